"""``BlockStackEnv``: a Panda and four cubes on a table (robosuite, delta OSC), the block-stacking study.

The sim is a robosuite ``Stack`` subclass with four equal cubes (4 cm, ids 0..3)
placed at seeded random positions at least :data:`MIN_SEPARATION` apart (centre
to centre, so the open fingers fit between them) with a random yaw. robosuite is
imported when an env is made, never by ``import steer_envs``.

Observation (flat ``float32``): ``robot0_eef_pos`` (3), ``robot0_gripper_qpos``
(2), then ``cube_i_pos`` (3) and ``cube_i_quat`` (4, xyzw) for i = 0..3: 33
numbers. robosuite's dict stays in ``env.unwrapped.robosuite_obs``. Action: the
adapter's 7-D delta OSC action (+1 closes the gripper).

Sensors (``info["sensors"]``):

- ``held_i``: latched like the adapter's ``held``: set once both finger pads
  have touched cube i for two control steps; it stays set while the cube is
  grasped or not yet resting (in the air, falling), for at most
  :data:`RELEASE_STEPS` steps after the grasp is lost; at most one cube is held
  (a new grasp releases the latch of any other cube).
- ``on_table_i`` / ``on_i_j``: cube i (not held) touches the table / cube j and
  rests on it (on j: centre above j's top half, xy offset below
  :data:`REST_XY_TOL`; a cube carries at most one cube, the best-centred).

Modes: ``free`` (no cube held: the next skill is a pick) and ``holding_i`` (the
next skill places cube i). Skills change the mode, the tower structure is the
world state a skill acts on: picks are ``free -> holding_i``, places
``holding_i -> free`` (:data:`SKILLS`, :func:`skill_transition`). A direct
``holding_i -> holding_j`` is not allowed.

``info["constraint_violation"]``: a mode change that is not allowed; a drop (the
latch of a held cube clears and the cube fell more than :data:`DROP_HEIGHT` since
it was last grasped, or does not rest on the table or the cube top it was
released over); a tower falling (a cube that rested on another stops doing so
without being held). ``perturb`` never reports one.

``info["success"]`` (reward 1, terminates): with ``goal_order`` (cube ids bottom
to top), the four cubes stand in that order on the table and none is held;
without a goal, any 4-high tower with none held.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Mapping, Sequence
from typing import Any, Unpack

import numpy as np

from steer_envs.core.interaction import InteractionKind
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import describe, integer, real_array
from steer_envs.envs.checks import check_options, check_seed
from steer_envs.envs.robosuite.adapter import GRASP_HOLD_STEPS, RobosuiteEnv, ViewOptions
from steer_envs.envs.robosuite.table import add_object_observables, table_arena

__all__ = [
    "CUBE_HALF",
    "DROP_HEIGHT",
    "MIN_SEPARATION",
    "NUM_CUBES",
    "PLACE_RANGE",
    "SKILLS",
    "BlockStackEnv",
    "blockstack_task",
    "skill_transition",
    "unwrap_blockstack",
]

NUM_CUBES = 4
#: half the edge of a cube (m).
CUBE_HALF = 0.02
#: the least distance between cube centres at reset (m); the open fingers need ~9 cm.
MIN_SEPARATION = 0.09
#: cubes start within +-PLACE_RANGE (m) of the table centre in x and y.
PLACE_RANGE = 0.12
#: success: each centre of the tower is this close (m) to its height in a perfect stack.
REST_Z_TOL = 0.008
#: resting on a cube: the xy offset of the centres is below this (m; beyond ~CUBE_HALF a cube tips).
REST_XY_TOL = 0.024
#: a released cube that fell more than this (m) was dropped, not placed.
DROP_HEIGHT = 0.015
#: the held latch clears at the latest this many control steps after the grasp is lost.
RELEASE_STEPS = 20
_COLOURS = ((0.85, 0.1, 0.1, 1.0), (0.1, 0.7, 0.1, 1.0), (0.1, 0.3, 0.9, 1.0), (0.95, 0.8, 0.1, 1.0))
_PLACEMENT_TRIES = 10_000
_SEAT = 0.001  # m: cubes start this far into the table, so their table contacts exist from the first reading

#: the skills: pick cube i, place cube i on the table or on cube j.
SKILLS: tuple[str, ...] = tuple(
    [f"pick_{i}" for i in range(NUM_CUBES)]
    + [f"place_{i}_on_table" for i in range(NUM_CUBES)]
    + [f"place_{i}_on_{j}" for i in range(NUM_CUBES) for j in range(NUM_CUBES) if i != j]
)


def _sensor_names() -> tuple[str, ...]:
    n = range(NUM_CUBES)
    return (
        tuple(f"held_{i}" for i in n)
        + tuple(f"on_table_{i}" for i in n)
        + tuple(f"on_{i}_{j}" for i in n for j in n if i != j)
    )


SENSORS = _sensor_names()


def skill_transition(skill: str) -> tuple[str, str]:
    """The mode change ``(from, to)`` a skill makes (``"pick_2"`` -> ``("free", "holding_2")``).

    >>> skill_transition("place_1_on_3")
    ('holding_1', 'free')
    """
    if not isinstance(skill, str) or skill not in SKILLS:
        raise ValueError(f"skill_transition: unknown `skill` {skill!r}; skills: {list(SKILLS)}")
    kind, cube = skill.split("_")[:2]
    return ("free", f"holding_{cube}") if kind == "pick" else (f"holding_{cube}", "free")


def _structures() -> list[tuple[int | None, dict[int, str | int | None]]]:
    """Every sensor-consistent world: (held cube or None, cube -> "table" / cube below / None)."""
    cubes = range(NUM_CUBES)
    out: list[tuple[int | None, dict[int, str | int | None]]] = []
    for below in itertools.product(("table", None, *cubes), repeat=NUM_CUBES):
        support: dict[int, str | int | None] = dict(enumerate(below))
        on_cubes = [s for s in below if isinstance(s, int)]
        if any(support[i] == i for i in cubes) or len(set(on_cubes)) != len(on_cubes):
            continue
        if any(_cycles(support, i) for i in cubes):
            continue
        out.append((None, support))
        out.extend((h, support) for h in cubes if support[h] is None)
    return out


def _cycles(support: Mapping[int, str | int | None], start: int) -> bool:
    seen, cube = {start}, support[start]
    while isinstance(cube, int):
        if cube in seen:
            return True
        seen.add(cube)
        cube = support[cube]
    return False


def _reading(held: int | None, support: Mapping[int, str | int | None]) -> dict[str, bool]:
    reading = dict.fromkeys(SENSORS, False)
    if held is not None:
        reading[f"held_{held}"] = True
    for i, s in support.items():
        if s == "table":
            reading[f"on_table_{i}"] = True
        elif s is not None:
            reading[f"on_{i}_{s}"] = True
    return reading


@functools.cache
def blockstack_task() -> TaskSpec:
    """The :class:`TaskSpec`: modes ``free``, ``holding_0..3``; every sensor-consistent reading labelled.

    >>> task = blockstack_task()
    >>> task.modes, task.is_allowed("free", "holding_2"), task.is_allowed("holding_0", "holding_1")
    (('free', 'holding_0', 'holding_1', 'holding_2', 'holding_3'), True, False)
    """
    modes = ("free", *(f"holding_{i}" for i in range(NUM_CUBES)))
    sensor_modes = {}
    for held, support in _structures():
        reading = _reading(held, support)
        sensor_modes[frozenset(k for k, v in reading.items() if v)] = "free" if held is None else f"holding_{held}"
    transitions = {t for i in range(NUM_CUBES) for t in (("free", f"holding_{i}"), (f"holding_{i}", "free"))}
    return TaskSpec(
        name="blockstack",
        modes=modes,
        sensors=SENSORS,
        sensor_modes=sensor_modes,
        transitions=frozenset(transitions),
        goal=("free",),
    )


def check_goal_order(goal_order: Any, owner: str) -> tuple[int, ...] | None:
    """``goal_order``: None or the 4 cube ids bottom to top (a permutation of 0..3)."""
    if goal_order is None:
        return None
    if isinstance(goal_order, (str, bytes)) or not isinstance(goal_order, Sequence):
        raise TypeError(f"{owner}: `goal_order` must be a sequence of cube ids or None, got {describe(goal_order)}")
    ids = tuple(integer(g, "goal_order", low=0, high=NUM_CUBES - 1, owner=owner) for g in goal_order)
    if sorted(ids) != list(range(NUM_CUBES)):
        raise ValueError(f"{owner}: `goal_order` must order each of the cubes 0..3 once, got {list(goal_order)}")
    return ids


def _load_cubes(env: Any) -> None:
    """The table arena (the robot at its edge) and the four cubes: ``env.cubes`` and ``env.model``."""
    from robosuite.models.objects import BoxObject
    from robosuite.models.tasks import ManipulationTask

    arena = table_arena(env)
    half = [CUBE_HALF] * 3
    env.cubes = [
        BoxObject(name=f"cube_{i}", size_min=half, size_max=half, rgba=list(_COLOURS[i])) for i in range(NUM_CUBES)
    ]
    env.model = ManipulationTask(
        mujoco_arena=arena,
        mujoco_robots=[robot.robot_model for robot in env.robots],
        mujoco_objects=env.cubes,
    )


def _place_cubes(env: Any) -> None:
    """Set each cube on the table at a sampled ``(x, y, yaw)`` (:meth:`sample_placements`)."""
    for cube, (x, y, yaw) in zip(env.cubes, env.sample_placements(), strict=True):
        pos = np.array([x, y, env.table_offset[2] + CUBE_HALF - _SEAT])
        quat = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])  # wxyz
        env.sim.data.set_joint_qpos(cube.joints[0], np.concatenate([pos, quat]))


def _cube_observables(env: Any, observables: Any) -> Any:
    """``observables`` with ``cube_<i>_pos`` and ``cube_<i>_quat`` (xyzw) of every cube added."""
    from robosuite.utils.transform_utils import convert_quat

    sensors = []
    for i, body in enumerate(env.cube_body_ids):

        def pos(obs_cache: Any, body: int = body) -> np.ndarray:
            return np.array(env.sim.data.body_xpos[body])

        def quat(obs_cache: Any, body: int = body) -> np.ndarray:
            return convert_quat(np.array(env.sim.data.body_xquat[body]), to="xyzw")

        sensors += [(f"cube_{i}_pos", pos), (f"cube_{i}_quat", quat)]
    return add_object_observables(env, observables, sensors)


def _tower_stacked(env: Any) -> bool:
    """A 4-high tower (in ``env.goal_order`` if set), centres stacked within the rest tolerances."""
    pos = np.array([env.sim.data.body_xpos[b] for b in env.cube_body_ids])
    orders = [env.goal_order] if env.goal_order else itertools.permutations(range(NUM_CUBES))
    base = env.table_offset[2] + CUBE_HALF
    for order in orders:
        p = pos[list(order)]
        heights = np.abs(p[:, 2] - (base + 2 * CUBE_HALF * np.arange(NUM_CUBES))) < REST_Z_TOL
        if heights.all() and np.all(np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1) < REST_XY_TOL):
            return True
    return False


@functools.cache
def _robosuite_class() -> type:
    """The robosuite env class (defined on first use: robosuite registers env classes by name)."""
    from robosuite.environments.manipulation.stack import Stack

    class SteerBlockStack(Stack):  # type: ignore[misc]
        """robosuite's Stack with four equal cubes, >= ``min_separation`` apart at reset, random yaw."""

        def __init__(self, *args: Any, min_separation: float = MIN_SEPARATION, **kwargs: Any) -> None:
            self.min_separation = min_separation
            self.goal_order: tuple[int, ...] | None = None
            self.cubes: list[Any] = []
            super().__init__(*args, **kwargs)

        def _load_model(self) -> None:
            super(Stack, self)._load_model()
            _load_cubes(self)

        def _setup_references(self) -> None:
            super(Stack, self)._setup_references()
            self.cube_body_ids = [self.sim.model.body_name2id(c.root_body) for c in self.cubes]

        def _reset_internal(self) -> None:
            super(Stack, self)._reset_internal()
            if not self.deterministic_reset:
                _place_cubes(self)

        def sample_placements(self) -> np.ndarray:
            """(4, 3): x, y, yaw of each cube, by rejection from ``self.rng`` (>= ``min_separation`` apart)."""
            for _ in range(_PLACEMENT_TRIES):
                xy = self.rng.uniform(-PLACE_RANGE, PLACE_RANGE, size=(NUM_CUBES, 2)) + self.table_offset[:2]
                gaps = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + np.eye(NUM_CUBES)
                if gaps.min() >= self.min_separation:
                    yaw = self.rng.uniform(0.0, 2 * np.pi, size=(NUM_CUBES, 1))
                    return np.concatenate([xy, yaw], axis=1)
            raise RuntimeError("SteerBlockStack: no cube placement found")  # pragma: no cover - 4 cubes always fit

        def _setup_observables(self) -> Any:
            return _cube_observables(self, super(Stack, self)._setup_observables())

        def reward(self, action: Any = None) -> float:
            return float(self._check_success())

        def _check_success(self) -> bool:
            """A 4-high tower (in ``goal_order`` if set), centres stacked within the rest tolerances."""
            return _tower_stacked(self)

        def visualize(self, vis_settings: Any) -> None:
            super(Stack, self).visualize(vis_settings=vis_settings)

    return SteerBlockStack


class BlockStackEnv(RobosuiteEnv):
    """Four-cube stacking with a Panda: cube poses observed, held cube and tower structure sensed.

    Args:
        goal_order: None (success = any 4-high tower) or the cube ids bottom to top
            (success = that tower); a reset option of the same name overrides it per episode.
        render_mode, camera, render_size, perturb_exact, fast_render: as for
            :class:`~steer_envs.envs.robosuite.adapter.RobosuiteEnv`.

    Reset options: ``state`` (eef start, as the adapter's), ``goal_order``.
    Observation, sensors, modes, violations and success: see the module docstring.
    Interactions: ``point`` (a world point, e.g. the cube or spot meant) and
    ``sketch`` (a 3D eef path in world coordinates, m); the adapter's pixel
    methods map them from camera frames. The rest of the API (``perturb``,
    rendering, cameras) is the adapter's.

    >>> BlockStackEnv.interaction_kinds
    ('point', 'sketch')
    """

    interaction_kinds: tuple[InteractionKind, ...] = ("point", "sketch")
    _OPTION_KEYS = frozenset({"state", "goal_order"})

    def __init__(
        self,
        goal_order: Sequence[int] | None = None,
        **view: Unpack[ViewOptions],
    ) -> None:
        owner = type(self).__name__
        self.default_goal = check_goal_order(goal_order, owner)
        self._check_view_args(view, owner)
        self.task_name = "blockstack"
        self.task = blockstack_task()
        self.obs_keys = (
            "robot0_eef_pos",
            "robot0_gripper_qpos",
            *(f"cube_{i}_{k}" for i in range(NUM_CUBES) for k in ("pos", "quat")),
        )
        self._build_sim(lambda **kwargs: _robosuite_class()(**kwargs), owner)
        rs = self.rs_env
        self._cube_masks, self._pad_geoms = self._cube_grasp_masks()
        model = rs.sim.model
        owner_of = {f"cube_{i}_g0": i for i in range(NUM_CUBES)} | {"table_collision": NUM_CUBES}
        self._geom_owner = np.array([owner_of.get(model.geom_id2name(g), -1) for g in range(model.ngeom)])
        self.table_z = float(rs.table_offset[2])
        self._reset_spaces()
        self._gripper = -1.0
        self._begin()

    # ----------------------------------------------------------------- state
    @property
    def goal_order(self) -> tuple[int, ...] | None:
        """The episode's goal tower (cube ids bottom to top), or None (any 4-high tower)."""
        order: tuple[int, ...] | None = self.rs_env.goal_order
        return order

    @property
    def cube_pos(self) -> np.ndarray:
        """(4, 3) cube centres (m, a copy)."""
        return np.array([self.robosuite_obs[f"cube_{i}_pos"] for i in range(NUM_CUBES)], dtype=np.float64)

    @property
    def cube_quat(self) -> np.ndarray:
        """(4, 4) cube orientations (xyzw, a copy)."""
        return np.array([self.robosuite_obs[f"cube_{i}_quat"] for i in range(NUM_CUBES)], dtype=np.float64)

    @property
    def object_pos(self) -> np.ndarray:
        """The held cube's centre, or cube 0's when none is held (the adapter's single-object view)."""
        held = self.held_cube
        return self.cube_pos[0 if held is None else held]

    @property
    def held_cube(self) -> int | None:
        """The cube the held latch is set for, or None."""
        return next((i for i in range(NUM_CUBES) if self._held_latch[i]), None)

    @property
    def supports(self) -> dict[int, str | int | None]:
        """The last sensed tower structure: cube -> ``"table"``, the cube it rests on, or None."""
        return dict(self._support)

    # --------------------------------------------------------------- sensors
    def _cube_grasp_masks(self) -> tuple[list[np.ndarray], tuple[tuple[np.ndarray, ...], ...]]:
        model = self.rs_env.sim.model
        names = [model.geom_id2name(g) for g in range(model.ngeom)]

        def mask(wanted: Any) -> np.ndarray:
            wanted = {wanted} if isinstance(wanted, str) else set(wanted)
            return np.array([n in wanted for n in names], dtype=bool)

        pads = tuple(
            (mask(g.important_geoms["left_fingerpad"]), mask(g.important_geoms["right_fingerpad"]))
            for g in self._robot.gripper.values()
        )
        return [mask(c.contact_geoms) for c in self.rs_env.cubes], pads

    def _grasped_cubes(self) -> list[bool]:
        """robosuite's ``_check_grasp`` for each cube, by geom ids (see the adapter's ``_grasped``)."""
        contact = self.rs_env.sim.data._data.contact
        g1, g2 = contact.geom1, contact.geom2
        if g1.size == 0:
            return [False] * NUM_CUBES
        out = []
        for cube in self._cube_masks:
            c1, c2 = cube[g1], cube[g2]
            out.append(any(all(bool(np.any((p[g1] & c2) | (c1 & p[g2]))) for p in pads) for pads in self._pad_geoms))
        return out

    def _touching(self) -> np.ndarray:
        """(5, 5) bool: which of the cubes (0..3) and the table (4) touch, from the sim's contacts."""
        contact = self.rs_env.sim.data._data.contact
        touch = np.zeros((NUM_CUBES + 1, NUM_CUBES + 1), dtype=bool)
        if contact.geom1.size:
            a, b = self._geom_owner[contact.geom1], self._geom_owner[contact.geom2]
            ok = (a >= 0) & (b >= 0)
            touch[a[ok], b[ok]] = True
            touch[b[ok], a[ok]] = True
        return touch

    def _raw_supports(self) -> dict[int, str | int | None]:
        """What each cube rests on (held or not): the table or the cube below that it touches.

        On a cube: touching it, centre at least 1.5 half-edges above its centre and
        less than :data:`REST_XY_TOL` off it (the best-centred one if several).
        On the table: touching it, centre below 1.5 half-edges above it. A tilted
        cube still resting counts (contacts, not poses, decide).
        """
        pos = self.cube_pos
        touch = self._touching()
        support: dict[int, str | int | None] = dict.fromkeys(range(NUM_CUBES))
        claims: dict[int, tuple[float, int]] = {}
        for i in range(NUM_CUBES):
            best: tuple[float, int] | None = None
            for j in range(NUM_CUBES):
                off = float(np.linalg.norm(pos[i, :2] - pos[j, :2]))
                above = pos[i, 2] - pos[j, 2] > 1.5 * CUBE_HALF
                if j != i and touch[i, j] and above and off < REST_XY_TOL and (best is None or off < best[0]):
                    best = (off, j)
            if best is not None:
                off, j = best
                if j not in claims or off < claims[j][0]:
                    claims[j] = (off, i)
            elif touch[i, NUM_CUBES] and pos[i, 2] - self.table_z < 1.5 * CUBE_HALF:
                support[i] = "table"
        for j, (_, i) in claims.items():
            support[i] = j
        return support

    def _under(self, i: int) -> str | int:
        """What cube i would land on if lowered straight down: the highest cube top below it, or the table."""
        pos = self.cube_pos
        below = [
            j
            for j in range(NUM_CUBES)
            if j != i and pos[j, 2] < pos[i, 2] and np.linalg.norm(pos[i, :2] - pos[j, :2]) < REST_XY_TOL
        ]
        return max(below, key=lambda j: pos[j, 2]) if below else "table"

    def _begin(self) -> None:
        self._held_latch = [False] * NUM_CUBES
        self._grasp_starts: list[float | None] = [None] * NUM_CUBES
        self._released = [0] * NUM_CUBES  # control steps since the grasp was lost, while latched
        self._grasp_z = [0.0] * NUM_CUBES  # the cube's height when last grasped
        self._release_over: list[str | int] = ["table"] * NUM_CUBES
        self._support: dict[int, str | int | None] = dict.fromkeys(range(NUM_CUBES))
        self._dropped = False
        self._gripper = -1.0
        self._sensors()
        self._dropped = False
        self._mode = self.task.mode_index(self.task.mode_of(self._reading()))

    def _sensors(self) -> dict[str, bool]:
        """Update the latches and the structure from the sim; ``_dropped``: a drop or a tower fell now."""
        now = float(self.rs_env.sim.data.time)
        grasped = self._grasped_cubes()
        raw = self._raw_supports()
        pos = self.cube_pos
        dropped = fell = False
        for i in range(NUM_CUBES):
            start = self._grasp_starts[i]
            self._grasp_starts[i] = (now if start is None else start) if grasped[i] else None
            start = self._grasp_starts[i]
            lasted = 0 if start is None else round((now - start) * self.control_freq) + 1
            if lasted >= GRASP_HOLD_STEPS and not self._held_latch[i]:
                for k in range(NUM_CUBES):  # one cube held at a time: a new grasp ends any other latch
                    if k != i and self._held_latch[k]:
                        dropped |= self._release(k, raw, pos)
                self._held_latch[i] = True
            if not self._held_latch[i]:
                continue
            if grasped[i]:
                self._released[i] = 0
                self._grasp_z[i] = float(pos[i, 2])
                self._release_over[i] = self._under(i)
            else:
                self._released[i] += 1
                if raw[i] is not None or self._released[i] > RELEASE_STEPS:
                    dropped |= self._release(i, raw, pos)
        support = {i: (None if self._held_latch[i] else raw[i]) for i in range(NUM_CUBES)}
        for k, before in self._support.items():
            if isinstance(before, int) and support[k] != before and not self._held_latch[k]:
                fell = True  # a cube that rested on another stopped doing so without being picked
        self._support = support
        self._dropped = dropped or fell
        self._success = bool(self.rs_env._check_success()) and self.held_cube is None
        return self._reading()

    def _release(self, i: int, raw: Mapping[int, str | int | None], pos: np.ndarray) -> bool:
        """Clear cube i's latch; True if it was dropped rather than placed."""
        self._held_latch[i] = False
        self._released[i] = 0
        fell = self._grasp_z[i] - float(pos[i, 2]) > DROP_HEIGHT
        return bool(fell or raw[i] is None or raw[i] != self._release_over[i])

    def _reading(self) -> dict[str, bool]:
        return _reading(self.held_cube, self._support)

    def _event_violation(self) -> bool:
        return self._dropped

    # ------------------------------------------------------------------- API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: cube placement (and the arm's init noise) drawn from ``seed``.

        ``options``: None or a dict with ``state`` (an eef start position, 3
        finite reals) and/or ``goal_order`` (this episode's goal tower; default
        the constructor's).
        """
        owner = f"{type(self).__name__}.reset"
        check_seed(seed, owner)
        opts = check_options(options, self._OPTION_KEYS, owner)
        goal = check_goal_order(opts.pop("goal_order"), owner) if "goal_order" in opts else self.default_goal
        if opts.get("state") is not None:
            real_array(opts["state"], "options['state']", shape=(3,), owner=owner)
        self.rs_env.goal_order = goal
        return super().reset(seed=seed, options=opts)


def unwrap_blockstack(env: Any, owner: str) -> BlockStackEnv:
    """``env`` unwrapped: a :class:`BlockStackEnv`, else a ``TypeError`` naming ``owner``."""
    base = getattr(env, "unwrapped", env)
    if not isinstance(base, BlockStackEnv):
        raise TypeError(f"{owner}: `env` must be a BlockStackEnv (or wrap one), got {type(env).__name__}")
    return base
