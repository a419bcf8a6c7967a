"""ColorTracing-v0: trace the coloured tiles Y, B, G, O, P into R; pushes into the dark region (TLI robot exp. 3).

The end-effector moves in ``[-8, 8]^2``. Six tiles lie in a row (closed
rectangles; on a shared edge the later tile wins), everything else is the
dark region D::

    y=1.5  +------+------+------+------+------+------+
           |  Y   |  B   |  G   |  O   |  P   |  R   |     D all around
    y=-1.5 +------+------+------+------+------+------+
          x=-6   -4     -2      0      2      4      6

Starts are uniform in ``[-5.8, -5.4] x [-1, 1]`` (the left end of yellow). The
task: move through yellow, blue, green, orange, pink (staying on the tiles) and
reach red.

**D modes.** D looks the same wherever it is entered (one sensor ``k``), but
entering it from each colour is its own mode (the thesis figure's D1..D4):
``dark1`` from yellow, ``dark2`` from blue, ``dark3`` from green, ``dark4``
from orange or pink. The figure is not in the thesis source; this assignment
is the one of :func:`steer_envs.ltl.specs.color_tracing` (the env keeps the
tile it left in its task memory, the automaton tells the D modes apart from
the sensor history).

**Transitions** (:data:`TRANSITIONS`): the demonstrated chain ``yellow ->
blue -> green -> orange -> pink -> red``, the exits ``tile -> its D mode`` and
the re-entries ``D mode -> tile`` of the replanning automaton ``automaton``
(:data:`REENTRY`; thesis (a): every D mode re-enters at yellow; (b): exits after
yellow re-enter at blue, a yellow exit at yellow; (c): a yellow exit continues at
blue, a blue exit at pink, other exits at the tile they left; ``None``, the
default: any of the three). ``constraint_violation`` flags every mode change
the policy makes that is not a chain step or an allowed re-entry: leaving a
tile into D (an invariance failure), stepping back to an earlier tile,
re-entering at a tile the automaton does not allow. Pushes (``perturb``) are
never violations.

**Success**: red is reached; the memory freezes then (mode ``red``).

Dynamics: ``x' = x + dt * u``, ``dt = 0.01``, ``|u| <= 10``.

Description
    See above. ``task.labels`` spell the D modes out (``dark1`` = ``dark_from_yellow``, ...,
    ``dark4`` = ``dark_from_orange_or_pink``); either name is accepted wherever a mode is looked up.

Observation
    ``Box(float32)``: the agent's ``(x1, x2)`` in the workspace (``x1`` right, ``x2`` up, as plotted);
    with ``observe_sensors=True`` followed by the sensor APs ``y``, ``b``, ``g``, ``o``, ``p``, ``r``
    (the tile under the end-effector) and ``k`` (the dark region) as 0/1.

Action
    ``Box(-10, 10, (2,), float32)``: a velocity, ``x' = x + 0.01 u`` with ``|u|`` clipped to 10;
    ``normalize_actions=True``: ``[-1, 1]^2``, scaled by 10.

Rewards
    ``reward_type="sparse"`` (default) or ``"dense"``, as in every 2D env
    (:class:`~steer_envs.envs.kinematic.Kinematic2DEnv`); the dense potential's stage = the index of the last tile
    visited (yellow 0 ... red 5), sub-goal = the next tile (distance to its rectangle).

Termination
    On success (red reached). Violations are reported, never terminal; truncation at 1000 steps
    (registered).

Registered ids
    ``steer_envs/ColorTracing-v0``, ``steer_envs/ColorTracingDense-v0`` (for RL: ``reward_type="dense"``,
    ``observe_sensors=True``, ``normalize_actions=True``).
"""

from __future__ import annotations

import itertools
from types import MappingProxyType
from typing import Unpack

import numpy as np

from steer_envs.core.task import TaskSpec
from steer_envs.envs.kinematic import EnvOptions, Kinematic2DEnv, RectRegionsModel, TaskReading
from steer_envs.envs.kinematic_vector import vector_factory
from steer_envs.envs.render import Canvas

WORKSPACE_HALF_WIDTH = 8.0
#: the tiles in the demonstrated order (red is the goal)
TILES: tuple[str, ...] = ("yellow", "blue", "green", "orange", "pink", "red")
DARK_MODES: tuple[str, ...] = ("dark1", "dark2", "dark3", "dark4")
MODES: tuple[str, ...] = (*TILES, *DARK_MODES)
MODE_LABELS: tuple[str, ...] = (
    *TILES,
    "dark_from_yellow",
    "dark_from_blue",
    "dark_from_green",
    "dark_from_orange_or_pink",
)
#: sensor APs: the tile under the end-effector, ``k`` the dark region
SENSORS: tuple[str, ...] = ("y", "b", "g", "o", "p", "r", "k")
#: region labels of :meth:`ColorTracingModel.regions`: 0 dark, ``i + 1`` tile ``i``
REGION_NAMES: tuple[str, ...] = ("dark", *TILES)
DARK, RED_REGION = 0, len(TILES)
RED = TILES.index("red")
TILE_WIDTH = 2.0
TILE_HALF_HEIGHT = 1.5
ROW_X0 = -6.0
#: closed rectangles ``(x0, y0, x1, y1)`` of the tiles
RECTS: MappingProxyType[str, tuple[float, float, float, float]] = MappingProxyType(
    {
        name: (ROW_X0 + TILE_WIDTH * i, -TILE_HALF_HEIGHT, ROW_X0 + TILE_WIDTH * (i + 1), TILE_HALF_HEIGHT)
        for i, name in enumerate(TILES)
    }
)
START_BOX = ((-5.8, -1.0), (-5.4, 1.0))
#: the D mode entered when leaving each tile (the figure's D1..D4; pink shares dark4 with orange)
EXIT_MODE: MappingProxyType[str, str] = MappingProxyType(
    {"yellow": "dark1", "blue": "dark2", "green": "dark3", "orange": "dark4", "pink": "dark4"}
)
#: the tile each D mode re-enters at under the thesis's automata (a), (b), (c)
REENTRY: MappingProxyType[str, MappingProxyType[str, str]] = MappingProxyType(
    {
        "a": MappingProxyType({"dark1": "yellow", "dark2": "yellow", "dark3": "yellow", "dark4": "yellow"}),
        "b": MappingProxyType({"dark1": "yellow", "dark2": "blue", "dark3": "blue", "dark4": "blue"}),
        "c": MappingProxyType({"dark1": "blue", "dark2": "pink", "dark3": "green", "dark4": "orange"}),
    }
)
AUTOMATA: tuple[str, ...] = tuple(REENTRY)
#: clearance from the row of tiles of the lane :func:`reentry_target` routes through
LANE_CLEARANCE = 1.0
#: how deep into the tile :func:`reentry_target` aims (from its outer edge)
REENTRY_DEPTH = 1.0

_CHAIN = frozenset(itertools.pairwise(TILES))
_EXITS = frozenset(EXIT_MODE.items())


def reentries(automaton: str | None) -> frozenset[tuple[str, str]]:
    """The ``(D mode, tile)`` re-entries automaton ``automaton`` allows (``None``: any of the three)."""
    if automaton is not None and (not isinstance(automaton, str) or automaton not in REENTRY):
        raise ValueError(f"automaton must be None or one of {list(AUTOMATA)}, got {automaton!r}")
    chosen = AUTOMATA if automaton is None else (automaton,)
    return frozenset(pair for a in chosen for pair in REENTRY[a].items())


def color_task(automaton: str | None = None) -> TaskSpec:
    """The TaskSpec of ColorTracing-v0 under ``automaton`` (``None``, ``"a"``, ``"b"``, ``"c"``).

    ``sensor_modes`` is empty on purpose: the dark reading ``{k}`` is D1..D4
    depending on the tile left, so no sensor reading alone labels a mode.
    """
    return TaskSpec(
        name="ColorTracing" if automaton is None else f"ColorTracing({automaton})",
        modes=MODES,
        sensors=SENSORS,
        sensor_modes={},
        transitions=_CHAIN | _EXITS | reentries(automaton),
        initial="yellow",
        goal=("red",),
        labels=MODE_LABELS,
    )


#: the task with the re-entries of any of the automata (the default env)
COLOR_TASK = color_task()
TRANSITIONS = COLOR_TASK.transitions


def _rect_distance(pos: np.ndarray, rects: np.ndarray) -> np.ndarray:
    """Distance of each row of ``pos (N, 2)`` to its rectangle ``rects (N, 4)`` (0 inside)."""
    dx = np.maximum.reduce([rects[:, 0] - pos[:, 0], np.zeros(len(pos)), pos[:, 0] - rects[:, 2]])
    dy = np.maximum.reduce([rects[:, 1] - pos[:, 1], np.zeros(len(pos)), pos[:, 1] - rects[:, 3]])
    return np.hypot(dx, dy)


def _tile_at(points: np.ndarray) -> np.ndarray:
    """Region label (0 dark, ``i + 1`` tile ``i``) of points ``(..., 2)``."""
    x, y = points[..., 0], points[..., 1]
    inside = (np.abs(y) <= TILE_HALF_HEIGHT) & (x >= ROW_X0) & (x <= ROW_X0 + TILE_WIDTH * len(TILES))
    idx = np.clip(np.floor((x - ROW_X0) / TILE_WIDTH).astype(np.int64), 0, len(TILES) - 1)
    # on a shared edge the later tile wins (x exactly on a boundary floors into the right-hand tile already)
    return np.where(inside, idx + 1, DARK)


def _row_span(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the segments ``a -> b`` (rows of ``(N, 2)``) meet the row of tiles (a closed box).

    Returns ``(hits, x_low, x_high)``: whether each segment meets the box and
    the x-range of the part inside it (Liang-Barsky clipping, exact).
    """
    lo = np.array([ROW_X0, -TILE_HALF_HEIGHT])
    hi = np.array([ROW_X0 + TILE_WIDTH * len(TILES), TILE_HALF_HEIGHT])
    d = b - a
    t_in, t_out = np.zeros(len(a)), np.ones(len(a))
    hits = np.ones(len(a), dtype=bool)
    for k in range(2):
        flat = np.abs(d[:, k]) < 1e-12
        hits &= ~flat | ((a[:, k] >= lo[k]) & (a[:, k] <= hi[k]))
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = np.where(flat, -np.inf, (lo[k] - a[:, k]) / d[:, k])
            t2 = np.where(flat, np.inf, (hi[k] - a[:, k]) / d[:, k])
        t_in = np.maximum(t_in, np.minimum(t1, t2))
        t_out = np.minimum(t_out, np.maximum(t1, t2))
    hits &= t_in <= t_out
    xa, xb = a[:, 0] + t_in * d[:, 0], a[:, 0] + t_out * d[:, 0]
    return hits, np.minimum(xa, xb), np.maximum(xa, xb)


def reentry_target(pos: np.ndarray, tile: int | np.ndarray) -> np.ndarray:
    """Where to head from ``pos (N, 2)`` to enter tile(s) ``tile`` through the dark region only.

    The goal is ``REENTRY_DEPTH`` inside the tile's outer edge on the agent's
    side of the row. If the straight segment to it touches another tile, the
    route goes through a lane ``LANE_CLEARANCE`` beyond the row: first to the
    lane point over the tile, or (if that segment touches a tile too) straight
    away from the row to the lane. Returns the intermediate targets ``(N, 2)``.
    """
    p = np.asarray(pos, dtype=np.float64).reshape(-1, 2)
    t = np.broadcast_to(np.asarray(tile, dtype=np.int64), (len(p),))
    if np.any((t < 0) | (t >= len(TILES))):
        raise ValueError(f"tile must be tile indices in [0, {len(TILES)}), got {np.unique(t).tolist()}")
    side = np.where(p[:, 1] >= 0, 1.0, -1.0)
    x0 = ROW_X0 + TILE_WIDTH * t
    goal = np.stack([x0 + TILE_WIDTH / 2, side * (TILE_HALF_HEIGHT - REENTRY_DEPTH)], axis=1)
    lane_y = side * (TILE_HALF_HEIGHT + LANE_CLEARANCE)
    over = np.stack([goal[:, 0], lane_y], axis=1)
    away = np.stack([p[:, 0], lane_y], axis=1)

    def clear(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        hits, xl, xh = _row_span(a, b)
        return ~hits | ((xl > x0) & (xh < x0 + TILE_WIDTH))  # inside the tile only (not on a shared edge)

    return np.where(clear(p, goal)[:, None], goal, np.where(clear(p, over)[:, None], over, away))


class ColorTracingModel(RectRegionsModel):
    """Batched task physics of ColorTracing; see the module docstring.

    Task memory (2 slots): ``[last tile visited (index into TILES), red reached]``.
    """

    memory_size = 2
    region_names = REGION_NAMES
    #: dark, yellow, blue, green, orange, pink, red
    region_palette = np.array(
        [[70, 70, 80], [255, 221, 87], [90, 140, 230], [110, 190, 110], [255, 160, 70], [255, 160, 200],
         [215, 50, 50]],
        dtype=np.uint8,
    )  # fmt: skip
    num_stages = len(TILES) - 1

    def __init__(self, automaton: str | None = None) -> None:
        self.automaton = automaton
        self.task = color_task(automaton)
        self.set_geometry(WORKSPACE_HALF_WIDTH, RECTS, TILES, START_BOX)
        #: mode index of the D mode entered from each tile (red: never left, the memory freezes)
        self._exit = np.array([MODES.index(EXIT_MODE.get(t, "dark4")) for t in TILES], dtype=np.int64)
        valid = np.eye(len(MODES), dtype=bool)
        for a, b in _CHAIN | reentries(automaton):
            valid[MODES.index(a), MODES.index(b)] = True
        #: mode changes the policy may make itself (chain steps and allowed re-entries)
        self._valid = valid

    def regions(self, pos: np.ndarray) -> np.ndarray:
        return _tile_at(np.asarray(pos, dtype=np.float64).reshape(-1, 2))

    def reset_memory(self, pos: np.ndarray) -> np.ndarray:
        reg = self.regions(pos)
        last = np.where(reg == DARK, 0, reg - 1)  # a start in D counts as having left yellow
        return np.stack([last, reg == RED_REGION], axis=1).astype(np.int64)

    def _modes(self, last: np.ndarray, done: np.ndarray, reg: np.ndarray) -> np.ndarray:
        mode = np.where(reg == DARK, self._exit[last], reg - 1)
        return np.where(done, RED, mode).astype(np.int64)

    def advance(self, memory: np.ndarray, prev_pos: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        reg = self.regions(pos)
        last, done = memory[:, 0], memory[:, 1] == 1
        before = self._modes(last, done, self.regions(prev_pos))
        new_last = np.where(reg == DARK, last, reg - 1)
        new_done = done | (reg == RED_REGION)
        after = self._modes(new_last, new_done, reg)
        violation = ~self._valid[before, after] & ~done
        new_memory = np.stack([new_last, new_done], axis=1).astype(np.int64)
        new_memory[done] = memory[done]
        return new_memory, violation

    def read(self, memory: np.ndarray, pos: np.ndarray) -> TaskReading:
        reg = self.regions(pos)
        done = memory[:, 1] == 1
        mode = self._modes(memory[:, 0], done, reg)
        sensors = np.stack([reg == i + 1 for i in range(len(TILES))] + [reg == DARK], axis=1)
        return TaskReading(mode=mode, sensors=sensors, success=done)

    def progress(self, memory: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Stage = the last tile visited (red: 5); sub-goal = the next tile's rectangle."""
        p = np.asarray(pos, dtype=np.float64).reshape(-1, 2)
        last, done = memory[:, 0], memory[:, 1] == 1
        nxt = np.minimum(last + 1, len(TILES) - 1)
        distance = _rect_distance(p, self._rect_stack[nxt])
        return np.where(done, self.num_stages, last), np.where(done, 0.0, distance)

    def draw(self, canvas: Canvas) -> None:
        x0, x1 = ROW_X0, ROW_X0 + TILE_WIDTH * len(TILES)
        h = TILE_HALF_HEIGHT
        canvas.polyline(np.array([[x0, h], [x1, h], [x1, -h], [x0, -h], [x0, h]]), (20, 20, 20), thickness=1)


class ColorTracingEnv(Kinematic2DEnv):
    """ColorTracing-v0 (TLI robot experiment 3: trace Y, B, G, O, P into R); see the module doc.

    Args:
        dt, max_speed: integration step and speed limit (0.01, 10).
        render_mode, render_size, reward_type, observe_sensors, normalize_actions: the options of every 2D env
            (:class:`~steer_envs.envs.kinematic.EnvOptions`, see :class:`~steer_envs.envs.kinematic.Kinematic2DEnv`).
        automaton: the replanning automaton whose re-entries are valid (``"a"``, ``"b"``, ``"c"``;
            ``None``: any of them).

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> env = gym.make("steer_envs/ColorTracing-v0")
    >>> obs, info = env.reset(seed=0)
    >>> info["mode_name"], [ap for ap, on in info["sensors"].items() if on]
    ('yellow', ['y'])
    >>> env.unwrapped.perturb(to=[-3.0, 0.0])["mode_name"], env.unwrapped.perturb(to=[-3.0, 4.0])["mode_name"]
    ('blue', 'dark2')
    """

    def __init__(
        self, dt: float = 0.01, max_speed: float = 10.0, automaton: str | None = None, **options: Unpack[EnvOptions]
    ) -> None:
        if automaton is not None and not isinstance(automaton, str):
            raise TypeError(f"ColorTracingEnv: automaton must be None or a str, got {type(automaton).__name__}")
        super().__init__(
            ColorTracingModel(automaton), dt=dt, max_speed=max_speed, terminate_on_violation=False, **options
        )
        self.model: ColorTracingModel


make_vector_env = vector_factory(ColorTracingEnv)

__all__ = [
    "AUTOMATA",
    "COLOR_TASK",
    "EXIT_MODE",
    "MODES",
    "RECTS",
    "REENTRY",
    "SENSORS",
    "TILES",
    "ColorTracingEnv",
    "ColorTracingModel",
    "color_task",
    "make_vector_env",
    "reentries",
    "reentry_target",
]
