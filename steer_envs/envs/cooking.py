"""Cooking-v0: add chicken and broccoli to a pot (TLI generalization task, thesis appendix).

The spoon moves in ``[-8, 8]^2``. Regions (closed rectangles; the pot wins on
the edges it shares with the corridors)::

    y=8  +------+-----------+---------+-----------+------+
         |      |  yellow   |  dark   |   green   |      |
         |white | (chicken) |  (pot)  | (broccoli)|white |
    y=4  |      |           +---------+           |      |
         |      |           |  white  |           |      |
    y=1  +------+-----------+---------+-----------+------+
         |                white (start below)            |
    y=-8 +-----------------------------------------------+
        x=-8   -7          -2         2           7      8

=============  ==========================  ===============================
region         rectangle                   meaning (thesis mode AP)
=============  ==========================  ===============================
white          everything else             empty spoon (``w``)
yellow         ``[-7, -2] x [1, 8]``       transferring chicken (``y``)
green          ``[2, 7] x [1, 8]``         transferring broccoli (``g``)
dark           ``[-2, 2] x [4, 8]``        the pot (``d``)
=============  ==========================  ===============================

The pot borders white (through the gap below it), yellow and green; yellow and
green do not touch. Starts are uniform in ``[-1.5, 1.5] x [-6, -4]``.

Physics (task memory ``[spoon, chicken in pot, broccoli in pot]``):

* Entering yellow from white or from the pot loads chicken onto an empty
  spoon; entering green from white or the pot loads broccoli (so the thesis's
  ``w => y => d => g => d`` is realizable: leaving the pot into green picks up
  broccoli).
* Food stays on the spoon while it is in its corridor. Moving from the
  corridor into the pot adds that food to the pot (the spoon is empty again);
  leaving it anywhere else (into white) *spills* the food: a
  ``constraint_violation`` (invariance failure of ``y``/``g``). Violations
  never end the episode (TLI recovers by replanning).
* An empty spoon entering the pot (white -> pot) adds nothing.
* Success: both foods are in the pot. The memory freezes then (``done``
  absorbs).

Sensor APs (short lowercase names, distinct from the thesis's mode APs):

======  ===================================================
``hc``  the spoon holds chicken (it is in yellow, loaded)
``hb``  the spoon holds broccoli (it is in green, loaded)
``p``   the spoon is in the pot (dark region)
``ch``  chicken has been added to the pot
``br``  broccoli has been added to the pot
======  ===================================================

At most one of ``hc``, ``hb``, ``p`` is true. The thesis's mode APs are
boolean formulas over them (:data:`MODE_AP_FORMULAS`, Spot syntax):
``w = !hc & !hb & !p``, ``y = hc``, ``g = hb``, ``d = p`` (phi_c, phi_cc) and,
with memory, ``w1 = w & !ch & !br``, ``w2 = w & (ch | br)``,
``d1 = p & (ch xor br)``, ``d2 = p & ch & br`` (phi_cb, phi_bc).

Default task (:data:`COOKING_TASK`, "both foods, any order"): modes are the
spoon state ``w``/``y``/``g``/``d`` (as above) times the pot contents ``0``
(empty), ``c`` (chicken only), ``b`` (broccoli only), e.g. ``y0``, ``gc``,
``db``, plus the goal ``done`` (both foods in the pot, any spoon state). Its
transitions are every mode change a continuous motion can make (loading,
delivering, spilling, entering/leaving the pot); the plan chicken-first is
``w0 y0 dc wc gc done`` or, through the pot, ``w0 y0 dc gc done``.

Dynamics: ``x' = x + dt * u``, ``dt = 0.01``, ``|u| <= 10`` (as SoupScoop).

Description
    See above. The modes keep their short ids (``w0``, ``y0``, ``dc``, ...: ``info["mode_name"]``);
    ``task.labels`` (:data:`MODE_LABELS`) spell them out, e.g. ``w0`` = ``empty_spoon``, ``y0`` =
    ``carry_chicken``, ``dc`` = ``spoon_in_pot_chicken_done``, ``wc`` = ``empty_spoon_chicken_done``,
    ``gc`` = ``carry_broccoli_chicken_done``; either name is accepted wherever a mode is looked up.

Observation
    ``Box(float32)``: the agent's ``(x1, x2)`` in the workspace (``x1`` right, ``x2`` up, as plotted);
    with ``observe_sensors=True`` followed by the sensor APs ``hc``, ``hb``, ``p``, ``ch``, ``br`` as
    0/1. The pot contents (``ch``, ``br``) and the spoon's load are task memory: observe them this way.

Action
    ``Box(-10, 10, (2,), float32)``: a velocity, ``x' = x + 0.01 u`` with ``|u|`` clipped to 10;
    ``normalize_actions=True``: ``[-1, 1]^2``, scaled by 10.

Rewards
    ``reward_type="sparse"`` (default) or ``"dense"``, as in every 2D env
    (:class:`~steer_envs.envs.kinematic.Kinematic2DEnv`); the dense potential's stage = 2 x foods in the pot + 1 while
    holding a food still to deliver, sub-goal = the pot's entry from the held food's corridor while that food is not yet
    in the pot, else the nearest loading point of a food not yet in the pot.

Termination
    On success (both foods in the pot). Spills are reported, never terminal; truncation at 2000 steps
    (registered).

Registered ids
    ``steer_envs/Cooking-v0``, ``steer_envs/CookingDense-v0`` (for RL: ``reward_type="dense"``,
    ``observe_sensors=True``, ``normalize_actions=True``).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Unpack

import numpy as np

from steer_envs.core.cooking_aps import COOKING_MODE_FORMULAS, COOKING_SENSORS
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import one_of
from steer_envs.envs.kinematic import EnvOptions, Kinematic2DEnv, RectRegionsModel, TaskReading
from steer_envs.envs.kinematic_vector import vector_factory
from steer_envs.envs.render import REGION_PALETTE, Canvas

#: half-width of the square workspace ``[-8, 8]^2``.
WORKSPACE_HALF_WIDTH = 8.0
#: region labels returned by :meth:`CookingModel.regions`.
WHITE, YELLOW, GREEN, DARK = 0, 1, 2, 3
REGION_NAMES: tuple[str, ...] = ("white", "yellow", "green", "dark")
#: closed rectangles ``(x0, y0, x1, y1)`` of the coloured regions (later wins).
RECTS: MappingProxyType[str, tuple[float, float, float, float]] = MappingProxyType(
    {
        "yellow": (-7.0, 1.0, -2.0, 8.0),
        "green": (2.0, 1.0, 7.0, 8.0),
        "dark": (-2.0, 4.0, 2.0, 8.0),
    }
)
#: spoon contents (memory slot 0).
EMPTY, CHICKEN, BROCCOLI = 0, 1, 2
#: foods by name -> (region label, spoon content, memory slot of "in pot").
FOODS: MappingProxyType[str, tuple[int, int, int]] = MappingProxyType(
    {"chicken": (YELLOW, CHICKEN, 1), "broccoli": (GREEN, BROCCOLI, 2)}
)
#: per-transition attractors (0.5 inside the next region, where the expert crosses), thesis Fig. (b).
TRANSITION_ATTRACTORS: MappingProxyType[str, tuple[float, float]] = MappingProxyType(
    {
        "w->y": (-4.5, 1.5),
        "w->g": (4.5, 1.5),
        "y->d": (-1.5, 6.0),
        "g->d": (1.5, 6.0),
        "d->w": (0.0, 3.5),
        "d->y": (-2.5, 6.0),
        "d->g": (2.5, 6.0),
    }
)
#: start box ``(low, high)`` corners.
START_BOX = ((-1.5, -6.0), (1.5, -4.0))

#: the thesis's mode APs as Spot formulas over the sensor APs.
MODE_AP_FORMULAS = COOKING_MODE_FORMULAS

SENSORS = COOKING_SENSORS
_SPOON_LETTERS = ("w", "y", "g", "d")
_POT_SUFFIXES = ("0", "c", "b")
MODES: tuple[str, ...] = (*(s + p for p in _POT_SUFFIXES for s in _SPOON_LETTERS), "done")
_SPOON_LABELS = ("empty_spoon", "carry_chicken", "carry_broccoli", "spoon_in_pot")
_POT_LABELS = ("", "_chicken_done", "_broccoli_done")
#: descriptive labels of :data:`MODES` (aliases of the thesis-style names), e.g. ``y0`` = ``carry_chicken``,
#: ``gc`` = ``carry_broccoli_chicken_done`` (broccoli on the spoon, chicken already in the pot).
MODE_LABELS: tuple[str, ...] = (*(s + p for p in _POT_LABELS for s in _SPOON_LABELS), "done")
DONE = len(MODES) - 1


def _cooking_task() -> TaskSpec:
    spoon_aps = ((), ("hc",), ("hb",), ("p",))
    pot_aps = ((), ("ch",), ("br",))
    sensor_modes: dict[frozenset[str], str] = {}
    for j, suffix in enumerate(_POT_SUFFIXES):
        for i, letter in enumerate(_SPOON_LETTERS):
            sensor_modes[frozenset(spoon_aps[i] + pot_aps[j])] = letter + suffix
    for aps in spoon_aps:
        sensor_modes[frozenset((*aps, "ch", "br"))] = "done"
    after_chicken = {"0": "dc", "c": "dc", "b": "done"}
    after_broccoli = {"0": "db", "b": "db", "c": "done"}
    transitions: set[tuple[str, str]] = set()
    for s in _POT_SUFFIXES:
        w, y, g, d = (letter + s for letter in _SPOON_LETTERS)
        transitions |= {(w, y), (w, g), (y, w), (g, w)}  # load from white / spill into white
        transitions |= {(w, d), (d, w), (d, y), (d, g)}  # empty spoon into / out of the pot (loads)
        transitions |= {(y, after_chicken[s]), (g, after_broccoli[s])}  # deliver
    return TaskSpec(
        name="Cooking",
        modes=MODES,
        sensors=SENSORS,
        sensor_modes=sensor_modes,
        transitions=frozenset(transitions),
        initial="w0",
        goal=("done",),
        labels=MODE_LABELS,
    )


COOKING_TASK = _cooking_task()


class CookingModel(RectRegionsModel):
    """Batched task physics of Cooking; see the module docstring.

    Public geometry (float64 arrays):
        rects: region name -> ``(x0, y0, x1, y1)`` closed rectangle.
        attractors: transition ``"w->y"``, ``"y->d"``, ... -> ``(2,)`` goal of
            that transition's policy (0.5 inside the next region).
        start_low, start_high: corners of the uniform start box.

    Task memory (3 slots): ``[spoon (EMPTY/CHICKEN/BROCCOLI), chicken in pot,
    broccoli in pot]``.
    """

    memory_size = 3
    region_names = REGION_NAMES
    region_palette = REGION_PALETTE[[0, 1, 3, 4]]

    def __init__(self) -> None:
        self.task = COOKING_TASK
        self.set_geometry(WORKSPACE_HALF_WIDTH, RECTS, REGION_NAMES[1:], START_BOX)
        self.attractors = {k: np.asarray(v, dtype=np.float64) for k, v in TRANSITION_ATTRACTORS.items()}

    # ------------------------------------------------------------ geometry
    def in_rect(self, name: str, pos: np.ndarray) -> np.ndarray:
        """Whether points lie in region ``name``'s closed rectangle (overlaps ignored): ``(N, 2) -> (N,)``."""
        one_of(name, "name", tuple(self.rects), owner="Cooking.in_rect")
        p = np.asarray(pos, dtype=np.float64).reshape(-1, 2)
        x0, y0, x1, y1 = self.rects[name]
        return (p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)

    # ---------------------------------------------------------------- task
    def advance(self, memory: np.ndarray, prev_pos: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        prev_reg, new_reg = self.regions(prev_pos), self.regions(pos)
        spoon = memory[:, 0]
        done = (memory[:, 1] == 1) & (memory[:, 2] == 1)
        from_outside = (prev_reg == WHITE) | (prev_reg == DARK)
        new_memory = memory.copy()
        new_spoon = np.full_like(spoon, EMPTY)
        spill = np.zeros(len(spoon), dtype=bool)
        for region, content, slot in FOODS.values():
            held = spoon == content
            keep = held & (new_reg == region)
            delivered = held & (new_reg == DARK)
            spill |= held & ~keep & ~delivered
            load = (spoon == EMPTY) & from_outside & (new_reg == region)
            new_spoon[keep | load] = content
            new_memory[:, slot] |= delivered
        new_memory[:, 0] = new_spoon
        new_memory[done] = memory[done]  # the goal absorbs
        return new_memory, spill & ~done

    def read(self, memory: np.ndarray, pos: np.ndarray) -> TaskReading:
        spoon, ch, br = memory[:, 0], memory[:, 1] == 1, memory[:, 2] == 1
        hc, hb = spoon == CHICKEN, spoon == BROCCOLI
        p = self.regions(pos) == DARK
        letter = np.where(hc, 1, np.where(hb, 2, np.where(p, 3, 0)))
        suffix = np.where(ch, 1, np.where(br, 2, 0))
        done = ch & br
        mode = np.where(done, DONE, 4 * suffix + letter)
        return TaskReading(mode=mode.astype(np.int64), sensors=np.stack([hc, hb, p, ch, br], axis=1), success=done)

    num_stages = 4

    def progress(self, memory: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Stage = 2 x foods in the pot + 1 while holding a food still to deliver; sub-goal = the pot's
        entry from the held food's corridor (``"y->d"``, ``"g->d"``) or, with an empty spoon or one holding
        a food already in the pot, the nearest loading point (``"w->y"``, ``"d->y"``, ``"w->g"``,
        ``"d->g"``) of a food not yet in the pot. (Aiming a reloaded, useless food at the pot made a
        local optimum at the pot's edge: delivering it again moves the sub-goal farther away.)"""
        p = np.asarray(pos, dtype=np.float64).reshape(-1, 2)
        spoon, ch, br = memory[:, 0], memory[:, 1] == 1, memory[:, 2] == 1
        att = self.attractors

        def dist(name: str) -> np.ndarray:
            return np.linalg.norm(p - att[name], axis=1)

        load_chicken = np.where(ch, np.inf, np.minimum(dist("w->y"), dist("d->y")))
        load_broccoli = np.where(br, np.inf, np.minimum(dist("w->g"), dist("d->g")))
        new_chicken, new_broccoli = (spoon == CHICKEN) & ~ch, (spoon == BROCCOLI) & ~br
        distance = np.where(
            new_chicken,
            dist("y->d"),
            np.where(new_broccoli, dist("g->d"), np.minimum(load_chicken, load_broccoli)),
        )
        holding_new = new_chicken | new_broccoli
        stage = 2 * (ch.astype(np.int64) + br.astype(np.int64)) + holding_new.astype(np.int64)
        done = ch & br
        return np.where(done, self.num_stages, stage), np.where(done, 0.0, distance)

    def draw(self, canvas: Canvas) -> None:
        x0, y0, x1, y1 = self.rects["dark"]
        canvas.polyline(np.array([[x0, y1], [x0, y0], [x1, y0], [x1, y1]]), (40, 40, 40), thickness=2)
        for point in self.attractors.values():
            canvas.disc(point, max(2, canvas.width // 96), (255, 140, 0))


class CookingEnv(Kinematic2DEnv):
    """Cooking-v0 (TLI re-tasking: chicken and broccoli into the pot); see the module docstring.

    Args:
        dt, max_speed: integration step and speed limit (0.01, 10).
        render_mode, render_size, reward_type, observe_sensors, normalize_actions: the options of every 2D env
            (:class:`~steer_envs.envs.kinematic.EnvOptions`, see :class:`~steer_envs.envs.kinematic.Kinematic2DEnv`).

    Spills are reported, never terminal (``terminate_on_violation=False``).
    >>> import gymnasium as gym
    >>> import steer_envs
    >>> env = gym.make("steer_envs/Cooking-v0")
    >>> obs, info = env.reset(seed=0)
    >>> info["mode_name"], env.unwrapped.task.sensors
    ('w0', ('hc', 'hb', 'p', 'ch', 'br'))
    """

    def __init__(self, dt: float = 0.01, max_speed: float = 10.0, **options: Unpack[EnvOptions]) -> None:
        super().__init__(CookingModel(), dt=dt, max_speed=max_speed, terminate_on_violation=False, **options)
        self.model: CookingModel


make_vector_env = vector_factory(CookingEnv)

__all__ = [
    "COOKING_TASK",
    "FOODS",
    "MODES",
    "MODE_AP_FORMULAS",
    "MODE_LABELS",
    "RECTS",
    "REGION_NAMES",
    "SENSORS",
    "TRANSITION_ATTRACTORS",
    "CookingEnv",
    "CookingModel",
    "make_vector_env",
]
