"""Running BlockStack skill plans on the arm, and reading off which skill a plan performs (ITPS §2.3).

A skill plan (:mod:`steer_envs.data.blockstack_plans`) is ``(H, 4)``: eef
positions every ``PLAN_STRIDE`` control steps and the gripper command then. It
holds no orientation, so the tracker (:func:`execute_plan`) chooses the wrist
yaw from the plan and the scene before it moves, as the expert does: a plan
that closes the gripper on an empty hand turns the fingers square to the cube
it closes on; one that opens over another cube while holding one squares the
held cube to that cube; any other plan keeps the yaw. Each waypoint is then
tracked for ``stride`` control steps with the expert's P-control
(:func:`move_action`). At a gripper switch the tracker first waits (at most
:data:`SWITCH_SETTLE` extra steps) until the eef is on the switching
waypoint, so the fingers close on the cube and open with the cube on its
support although the P-control lags a moving target. That is the default,
``execution="open_loop"``. ``execution="closed_loop"``
(:mod:`steer_envs.control.plans`) tracks the same plan as the thesis's robots
did: after its ``stride`` steps a waypoint is held until the eef is within
:data:`WAYPOINT_TOL` of it (at most :data:`WAYPOINT_PATIENCE` more steps); a
grasp settles on the closing waypoint square to the cube, closes for
:data:`CLOSE_STEPS` and checks that both finger pads touch the cube the plan
closes on; if not, and the plan's closing waypoint was a grasp of that cube
(:func:`classify_plan`'s tolerances), it opens, comes down on the cube where
it is now from :data:`REAPPROACH_HEIGHT` above and closes again, at most
:data:`GRASP_RETRIES` times; a release that is a place by
:func:`classify_plan`'s rule puts the held cube :data:`PLACE_CLEARANCE` above
its support, centred on a tower top (the classifier's tolerances are looser
than the env's rest and drop tests), opens, and holds still until the env
lets the cube go (at most :data:`RELEASE_SETTLE` steps). A plan that is no
skill is run as it is: closed loop corrects execution, not the plan.

:func:`classify_plan` is the alignment test of the block-stacking study ("the
sample corresponds to the intended block"): the skill a plan would perform from
the env's state, read off the plan alone. :class:`PlanOutcome` is what the
world shows after execution.

The skill vocabulary and the control the scripted expert
(:mod:`steer_envs.data.experts.blockstack`, which re-exports them), this
tracker and the simulated user (:mod:`steer_envs.users.block_sketcher`) share
live here, in the control layer below both (``docs/architecture.md``, "Layers"):
:class:`Skill`, :func:`towers`, :func:`free_table_spot`,
:func:`goal_tower_skill` (the goal-tower planner's rule), :func:`move_action`
and :func:`quarter_turn`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.control.plans import PlanOutcome, PlanRun, check_execution, check_plan, first_index
from steer_envs.core.validation import integer, real_scalar
from steer_envs.envs.robosuite.blockstack import (
    CUBE_HALF,
    MIN_SEPARATION,
    NUM_CUBES,
    PLACE_RANGE,
    BlockStackEnv,
    unwrap_blockstack,
)

__all__ = [
    "CLASSIFY_XY_TOL",
    "CLOSE_STEPS",
    "GRASP_RETRIES",
    "GRASP_SETTLE",
    "GRASP_Z_TOL",
    "HOME_YAW",
    "MAX_WAYPOINTS",
    "OPEN_STEPS",
    "PLACE_CLEARANCE",
    "PLACE_Z_TOL",
    "PLAN_DIM",
    "PLAN_STRIDE",
    "REAPPROACH_HEIGHT",
    "RELEASE_SETTLE",
    "SQUARE_TOL",
    "SWITCH_SETTLE",
    "SWITCH_TOL",
    "TOWER_CLEARANCE",
    "WAYPOINT_PATIENCE",
    "WAYPOINT_TOL",
    "PlanOutcome",
    "Skill",
    "classify_plan",
    "execute_plan",
    "free_table_spot",
    "goal_tower_skill",
    "move_action",
    "plan_target",
    "quarter_turn",
    "towers",
    "wrap_quarter",
    "yaw_of",
]

#: control steps per plan waypoint (:mod:`steer_envs.data.blockstack_plans`, one layer up, builds plans with it).
PLAN_STRIDE = 3
#: a waypoint: eef x, y, z (m) and the gripper command.
PLAN_DIM = 4
#: most waypoints of a plan (the tracker's loop is bounded by this many times the stride, plus the switch settles).
MAX_WAYPOINTS = 10_000
#: the Panda's eef yaw at reset (rad; robosuite's init noise moves it by a few hundredths): yaw targets stay near it.
HOME_YAW = 0.0
#: most extra control steps the tracker waits at a gripper switch for the eef to reach the switching waypoint.
SWITCH_SETTLE = 12
#: the eef is "on" the switching waypoint within this distance (m).
SWITCH_TOL = 0.004
#: closed loop: the tracker moves on once the eef is within this distance (m) of the waypoint ...
WAYPOINT_TOL = 0.01
#: ... or after this many extra control steps on it.
WAYPOINT_PATIENCE = 15
#: closed loop: most control steps to settle on a switching waypoint (squared to the cube) before closing / opening.
GRASP_SETTLE = 40
#: closed loop: the wrist is square to the cube within this yaw (rad).
SQUARE_TOL = 0.05
#: closed loop: control steps the fingers close before the grasp is checked (the expert's) ...
CLOSE_STEPS = 10
#: ... and open before a retry or before the released cube may be checked (the expert's).
OPEN_STEPS = 8
#: closed loop: most times a grasp that closed on nothing is tried again.
GRASP_RETRIES = 2
#: closed loop: a retry comes down on the cube from this far (m) above its centre.
REAPPROACH_HEIGHT = 0.06
#: closed loop: a place lets the held cube go this far (m) above its rest (the expert's).
PLACE_CLEARANCE = 0.003
#: closed loop: most control steps the opened hand holds still for the env to let the cube go (its latch clears).
RELEASE_SETTLE = 30
#: a plan closes on / opens over a cube within this xy distance (m) of the waypoint (of the held cube's centre).
CLASSIFY_XY_TOL = 0.03
#: a closing waypoint grasps a cube when it is within this height (m) of the cube's centre.
GRASP_Z_TOL = 0.025
#: an opening waypoint places: the held cube's centre within this height (m) above its resting height.
PLACE_Z_TOL = 0.03
#: table spots stay this far (m) from cubes stacked on others: the hand, wider than the fingers, would hit them.
TOWER_CLEARANCE = 0.14
_GAIN = 10.0
_YAW_GAIN = 2.0
_YAW_CARRY = 0.5  # the expert turns a held cube at most this fast (action units)


# ------------------------------------------------------------------ skills and the world's structure
@dataclass(frozen=True)
class Skill:
    """One skill: ``kind`` ``"pick"`` or ``"place"``, the ``cube`` it moves, and for a place its target.

    ``onto``: the cube to place on, or None for the table at ``xy``.
    """

    kind: str
    cube: int
    onto: int | None = None
    xy: tuple[float, float] | None = None

    @property
    def name(self) -> str:
        """The skill's name in :data:`steer_envs.envs.robosuite.blockstack.SKILLS`."""
        if self.kind == "pick":
            return f"pick_{self.cube}"
        return f"place_{self.cube}_on_{'table' if self.onto is None else self.onto}"


def towers(env: BlockStackEnv) -> list[list[int]]:
    """The towers (cube ids bottom to top) standing on the table, from the env's last sensed structure."""
    support = env.supports
    above = {s: c for c, s in support.items() if isinstance(s, int)}
    out = []
    for c, s in support.items():
        if s == "table":
            tower = [c]
            while tower[-1] in above:
                tower.append(above[tower[-1]])
            out.append(tower)
    return out


def free_table_spot(env: BlockStackEnv, rng: np.random.Generator, *, exclude: int | None = None) -> np.ndarray:
    """A random table xy within the placement range, clear of every cube but ``exclude``.

    Clear: >= ``MIN_SEPARATION`` from each cube centre and >= :data:`TOWER_CLEARANCE`
    from cubes above the first level (if no such spot turns up, the first rule alone).
    """
    pos = env.cube_pos
    keep = [i for i in range(NUM_CUBES) if i != exclude]
    others = pos[keep, :2]
    high = pos[keep, 2] > env.table_z + 2.5 * CUBE_HALF  # a centre above 5 cm: the cube stands on another
    need = np.where(high, TOWER_CLEARANCE, MIN_SEPARATION)
    centre = np.asarray(env.rs_env.table_offset[:2], dtype=np.float64)
    for tries in range(2000):
        xy = centre + rng.uniform(-PLACE_RANGE, PLACE_RANGE, size=2)
        gaps = np.linalg.norm(others - xy, axis=1)
        if np.all(gaps >= (need if tries < 1000 else MIN_SEPARATION)):
            return xy
    raise RuntimeError("free_table_spot: no free spot on the table")  # pragma: no cover - 3 others always leave one


def goal_tower_skill(env: BlockStackEnv, order: tuple[int, ...], rng: np.random.Generator) -> Skill:
    """The next skill toward the tower ``order`` (bottom to top): clear blockers to the table, then stack.

    Holding the next cube of the tower while the partial tower's top is free: place
    it there; holding any other cube: to a free table spot (drawn from ``rng``).
    Free: pick off a wrong cube sitting on the partial tower (or on the base), else
    pick the next cube (or what sits on it). The rule of
    :class:`~steer_envs.data.experts.blockstack.GoalTowerPlanner`.
    """
    support = env.supports
    built = 1 if support[order[0]] == "table" else 0
    while built < NUM_CUBES and support[order[built]] == order[built - 1] and built > 0:
        built += 1
    held = env.held_cube
    top_of = {c: t[-1] for t in towers(env) for c in t}
    if held is not None:
        if built > 0 and held == order[built] and top_of.get(order[built - 1]) == order[built - 1]:
            return Skill("place", held, order[built - 1])
        xy = free_table_spot(env, rng, exclude=held)
        return Skill("place", held, None, (float(xy[0]), float(xy[1])))
    if built > 0 and top_of[order[built - 1]] != order[built - 1]:
        return Skill("pick", top_of[order[built - 1]])  # something wrong sits on the partial goal tower
    if built == 0:
        base = order[0]
        return Skill("pick", top_of[base]) if top_of.get(base, base) != base else Skill("pick", base)
    nxt = order[built]
    return Skill("pick", top_of.get(nxt, nxt))


# ------------------------------------------------------------------------------------ control
def yaw_of(quat_xyzw: np.ndarray) -> float:
    """The yaw (rad) of an xyzw quaternion."""
    x, y, z, w = (float(v) for v in quat_xyzw)
    return float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def wrap_quarter(angle: float) -> float:
    """``angle`` wrapped into [-pi/4, pi/4) (a square's yaw is defined mod 90 degrees)."""
    return float((angle + np.pi / 4) % (np.pi / 2) - np.pi / 4)


def _approach(quat_xyzw: np.ndarray) -> np.ndarray:
    """The gripper's approach axis (the eef frame's z axis) in the world."""
    x, y, z, w = (float(v) for v in quat_xyzw)
    return np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])


def move_action(
    env: BlockStackEnv, target: np.ndarray, gripper: float, yaw_error: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """The P-control delta-OSC action toward eef position ``target`` and the position error ``d``.

    Gain 10, clipped to [-1, 1]; the fingers are kept pointing straight down and
    the wrist turns about the vertical by ``yaw_error`` (rad, gain 2); ``gripper``
    is the command (-1 open, +1 closed). The expert's skills and the plan tracker share it.
    """
    d = target - env.state
    action = np.zeros(7, dtype=np.float32)
    action[:3] = np.clip(d * _GAIN, -1.0, 1.0)
    # keep the fingers pointing straight down (the arm's orientation drifts over a long episode) ...
    tilt = np.cross(_approach(env.robosuite_obs["robot0_eef_quat"]), [0.0, 0.0, -1.0])
    action[3:5] = np.clip(tilt[:2] * _YAW_GAIN, -1.0, 1.0)
    # ... and turn about the vertical by `yaw_error`
    action[5] = np.clip(yaw_error * _YAW_GAIN, -1.0, 1.0)
    action[6] = gripper
    return action, d


def quarter_turn(home_yaw: float, eef_yaw: float, yaw: float) -> float:
    """The eef yaw change to a yaw equal to ``yaw`` modulo 90 degrees, the one nearest ``home_yaw``.

    Always turning the shortest way would wind the wrist up over many skills
    until a joint limit stops the arm; the target nearest the start yaw keeps it within 45 degrees.
    """
    target = home_yaw + wrap_quarter(yaw - home_yaw)
    return float((target - eef_yaw + np.pi) % (2 * np.pi) - np.pi)


# ------------------------------------------------------------------------------- plans
def _closing_cube(env: BlockStackEnv, point: np.ndarray) -> int:
    """The cube a plan closes on at ``point``: the nearest (3-D) of those within the xy tolerance, else xy-nearest."""
    pos = env.cube_pos
    xy = np.linalg.norm(pos[:, :2] - point[:2], axis=1)
    near = np.flatnonzero(xy < CLASSIFY_XY_TOL)
    if near.size == 0:
        return int(np.argmin(xy))
    return int(near[np.argmin(np.linalg.norm(pos[near] - point, axis=1))])


def _over_tower(env: BlockStackEnv, centre: np.ndarray, held: int) -> int | None:
    """The tower top (not ``held``) nearest ``centre`` in xy, if within :data:`CLASSIFY_XY_TOL`."""
    pos = env.cube_pos
    tops = [t[-1] for t in towers(env) if held not in t]
    over = [j for j in tops if np.linalg.norm(pos[j, :2] - centre[:2]) < CLASSIFY_XY_TOL]
    return min(over, key=lambda c: float(np.linalg.norm(pos[c, :2] - centre[:2]))) if over else None


def _held_centre(env: BlockStackEnv, plan: np.ndarray, k: int, held: int) -> np.ndarray:
    """The held cube's centre at waypoint ``k``: the waypoint plus the held cube's offset now."""
    return np.asarray(plan[k, :3] + (env.cube_pos[held] - env.state))


def _opening_centre(env: BlockStackEnv, plan: np.ndarray, held: int) -> np.ndarray | None:
    """The held cube's centre at the first opening waypoint, or None."""
    k = first_index(plan[:, 3] <= 0)
    return None if k is None else _held_centre(env, plan, k, held)


def _read_plan(env: Any, plan: Any, owner: str) -> tuple[BlockStackEnv, np.ndarray, int | None, int | None]:
    """The BlockStack under ``env``, the checked plan, the held cube and the plan's gripper switch.

    The switch is the first waypoint that closes the gripper (hand empty) or
    opens it (holding a cube); None if the plan never switches.
    """
    base = unwrap_blockstack(env, owner)
    arr = check_plan(plan, PLAN_DIM, MAX_WAYPOINTS, owner)
    held = base.held_cube
    k = first_index(arr[:, 3] > 0 if held is None else arr[:, 3] <= 0)
    return base, arr, held, k


def classify_plan(env: Any, plan: Any) -> str | None:
    """The skill ``plan`` would perform from ``env``'s current state, read off the plan; None if none.

    Hand empty: ``pick_i`` for the cube nearest the first closing waypoint
    (within :data:`CLASSIFY_XY_TOL` in xy and :data:`GRASP_Z_TOL` of its centre's
    height). Holding cube i: at the first opening waypoint, ``place_i_on_j`` when
    the held cube is over the top cube j of a tower, else ``place_i_on_table``
    when it is low near the table. ``env``: a BlockStackEnv or a wrapper of one.
    """
    base, arr, held, k = _read_plan(env, plan, "classify_plan")
    if k is None:
        return None
    if held is None:
        wp = arr[k, :3]
        cube = _closing_cube(base, wp)
        pos = base.cube_pos[cube]
        near = np.linalg.norm(pos[:2] - wp[:2]) < CLASSIFY_XY_TOL and abs(wp[2] - pos[2]) < GRASP_Z_TOL
        return f"pick_{cube}" if near else None
    centre = _held_centre(base, arr, k, held)
    onto = _over_tower(base, centre, held)
    rest = base.table_z + CUBE_HALF if onto is None else base.cube_pos[onto, 2] + 2 * CUBE_HALF
    if not -CUBE_HALF < centre[2] - rest < PLACE_Z_TOL:
        return None
    return f"place_{held}_on_{'table' if onto is None else onto}"


def plan_target(env: Any, plan: Any) -> str:
    """The skill ``plan`` *heads for* from ``env``'s state, whether or not it could perform it.

    The thesis's reading of alignment ("the sample corresponds to the intended
    block"): :func:`classify_plan` without its height checks, and with the
    plan's last waypoint standing in when the gripper never switches. Hand
    empty: ``pick_i`` for the cube the first closing waypoint (else the last)
    closes on, as :func:`classify_plan` reads it (of a tower's cubes, the
    nearest in 3-D). Holding cube i: the held cube's centre at the first opening
    waypoint (else the last) over a tower top j gives ``place_i_on_j``,
    anywhere else ``place_i_on_table``.
    """
    base, arr, held, k = _read_plan(env, plan, "plan_target")
    k = -1 if k is None else k
    if held is None:
        return f"pick_{_closing_cube(base, arr[k, :3])}"
    onto = _over_tower(base, _held_centre(base, arr, k, held), held)
    return f"place_{held}_on_{'table' if onto is None else onto}"


def _executed(before_held: int | None, env: BlockStackEnv) -> str | None:
    """The skill the world shows happened since a state where ``before_held`` was held."""
    held = env.held_cube
    if before_held is None:
        return None if held is None else f"pick_{held}"
    if held is not None:
        return None
    rest = env.supports[before_held]
    return None if rest is None else f"place_{before_held}_on_{rest}"


def _squaring(
    base: Any, arr: np.ndarray, grip: np.ndarray, held_before: int | None, switch: int | None
) -> tuple[str, int] | None:
    """What the wrist squares to before the gripper switches: ``("pick", cube)``, ``("place", cube)`` or None.

    A plan that closes on an empty hand squares the fingers to the cube it closes on; one that opens over
    another cube while holding one squares the held cube to that cube; any other plan keeps the yaw.
    """
    if held_before is None and switch is not None and grip[switch] > 0:
        return ("pick", _closing_cube(base, arr[switch, :3]))
    if held_before is not None and switch is not None and grip[switch] < 0:
        centre = _opening_centre(base, arr, held_before)
        onto = None if centre is None else _over_tower(base, centre, held_before)
        return None if onto is None else ("place", onto)
    return None


class _Tracker(PlanRun):
    """One plan run: the env, the wrist's squaring target, and the outcome so far (:class:`PlanRun`)."""

    base: BlockStackEnv

    def __init__(
        self, base: BlockStackEnv, square: tuple[str, int] | None, held_before: int | None, home: float
    ) -> None:
        super().__init__(base)
        self.square, self.held_before, self.home_yaw = square, held_before, home

    def yaw_error(self, turning: bool) -> float:
        """The wrist's yaw change still to go (0 when not squaring)."""
        if not turning or self.square is None:
            return 0.0
        base = self.base
        eef_yaw = yaw_of(base.robosuite_obs["robot0_eef_quat"])
        quat = base.cube_quat
        if self.square[0] == "pick":
            return quarter_turn(self.home_yaw, eef_yaw, yaw_of(quat[self.square[1]]))
        assert self.held_before is not None
        in_hand = yaw_of(quat[self.held_before]) - eef_yaw
        return quarter_turn(self.home_yaw, eef_yaw, yaw_of(quat[self.square[1]]) - in_hand)

    def step(self, target: np.ndarray, g: float, turning: bool) -> None:
        """One control step toward ``target`` with gripper command ``g`` (turning the wrist when ``turning``)."""
        action, _ = move_action(self.base, target, g, self.yaw_error(turning))
        if turning and self.square is not None and self.square[0] == "place":
            action[5] = np.clip(action[5], -_YAW_CARRY, _YAW_CARRY)
        self.advance(action)

    def settle(self, target: np.ndarray, g: float, turning: bool, most: int, *, square: bool = False) -> None:
        """Step toward ``target`` until on it (:data:`SWITCH_TOL`; square with ``square``), at most ``most`` steps."""
        for _ in range(most):
            on = np.linalg.norm(target - self.base.state) < SWITCH_TOL
            if on and (not square or abs(self.yaw_error(turning)) < SQUARE_TOL):
                return
            self.step(target, g, turning)

    def outcome(self) -> PlanOutcome:
        """What the run did: the skill the world shows since the start, the violation, steps and trail."""
        trail = np.stack(self.trail).astype(np.float64)
        executed = _executed(self.held_before, self.base)
        return PlanOutcome(executed, self.violation, self.steps, trail, np.asarray(self.last_obs), self.regrasps)


def _open_loop(run: _Tracker, arr: np.ndarray, grip: np.ndarray, switch: int | None, stride: int) -> None:
    """Each waypoint for ``stride`` steps; at a gripper switch first at most :data:`SWITCH_SETTLE` steps to reach it."""
    current = float(run.base._gripper)
    for k in range(len(arr)):
        target, g = arr[k, :3], float(grip[k])
        turning = switch is None or k <= switch
        if g != current:  # settle on the switching waypoint with the old command, then switch
            run.settle(target, current, turning, SWITCH_SETTLE)
            current = g
        for _ in range(stride):
            run.step(target, g, turning)


def _grasping(base: BlockStackEnv, cube: int) -> bool:
    """Both finger pads touch ``cube`` now (the contacts the env's held latch is set from)."""
    return bool(base._grasped_cubes()[cube])


def _grasp(run: _Tracker, target: np.ndarray, turning: bool) -> None:
    """Close on the cube at ``target``; while no contact grasp shows, re-approach it and close again.

    The plan's cube is the one its closing waypoint reads as (:func:`classify_plan`'s rule).
    A retry opens, rises :data:`REAPPROACH_HEIGHT` above the cube where it is now, comes down
    onto its centre and closes: at most :data:`GRASP_RETRIES` times, and only when the plan's
    closing waypoint was a grasp of that cube (within the classifier's tolerances).
    """
    base = run.base
    cube = _closing_cube(base, target)
    rel = target - base.cube_pos[cube]
    is_grasp = np.linalg.norm(rel[:2]) < CLASSIFY_XY_TOL and abs(rel[2]) < GRASP_Z_TOL
    point = target
    for attempt in range(GRASP_RETRIES + 1):
        run.settle(point, -1.0, turning, GRASP_SETTLE, square=True)
        for _ in range(CLOSE_STEPS):
            run.step(point, 1.0, turning)
        if _grasping(base, cube) or not is_grasp or attempt == GRASP_RETRIES:
            return
        run.regrasps += 1
        for _ in range(OPEN_STEPS):
            run.step(point, -1.0, turning)
        above = base.cube_pos[cube] + np.array([0.0, 0.0, REAPPROACH_HEIGHT])
        _reach(run, above, -1.0, turning, GRASP_SETTLE)
        point = base.cube_pos[cube]


def _reach(run: _Tracker, target: np.ndarray, g: float, turning: bool, most: int) -> None:
    """Step toward ``target`` until within :data:`WAYPOINT_TOL`, at most ``most`` steps."""
    for _ in range(most):
        if np.linalg.norm(target - run.base.state) < WAYPOINT_TOL:
            return
        run.step(target, g, turning)


def _place_point(base: BlockStackEnv, target: np.ndarray, held: int) -> np.ndarray | None:
    """Where the eef puts ``held`` down when the plan opens at ``target``, or None if that is no place.

    A place by :func:`classify_plan`'s rule (the held cube's centre over a tower
    top, or low over the table): the held cube centred on the top (or where it
    is, over the table) and :data:`PLACE_CLEARANCE` above its rest, using the
    held offset measured now. The classifier's tolerances are looser than the
    env's rest and drop tests; this puts a valid place within them.
    """
    offset = base.cube_pos[held] - base.state
    centre = target + offset
    onto = _over_tower(base, centre, held)
    rest = base.table_z + CUBE_HALF if onto is None else base.cube_pos[onto, 2] + 2 * CUBE_HALF
    if not -CUBE_HALF < centre[2] - rest < PLACE_Z_TOL:
        return None
    xy = centre[:2] if onto is None else base.cube_pos[onto, :2]
    return np.array([xy[0], xy[1], rest + PLACE_CLEARANCE]) - offset


def _release(run: _Tracker, target: np.ndarray, turning: bool) -> None:
    """Put the held cube down where the plan opens (:func:`_place_point`), open, and hold still until
    the env lets the cube go (it rests on a support), bounded."""
    base = run.base
    held = base.held_cube
    assert held is not None
    for _ in range(GRASP_SETTLE):
        point = _place_point(base, target, held)
        point = target if point is None else point
        if np.linalg.norm(point - base.state) < SWITCH_TOL and abs(run.yaw_error(turning)) < SQUARE_TOL:
            break
        run.step(point, 1.0, turning)
        target = point
    for i in range(RELEASE_SETTLE):
        run.step(target, -1.0, turning)
        if i + 1 >= OPEN_STEPS and base.held_cube is None:
            return


def _closed_loop(run: _Tracker, arr: np.ndarray, grip: np.ndarray, switch: int | None, stride: int) -> None:
    """Each waypoint for ``stride`` steps and then until the eef is on it (bounded); checked grasps and releases."""
    current = float(run.base._gripper)
    for k in range(len(arr)):
        target, g = arr[k, :3], float(grip[k])
        turning = switch is None or k <= switch
        if g != current:
            if g > 0 and run.base.held_cube is None:
                _grasp(run, target, turning)
            elif g <= 0 and run.base.held_cube is not None:
                _release(run, target, turning)
            else:
                run.settle(target, current, turning, SWITCH_SETTLE)
            current = g
        for _ in range(stride):
            run.step(target, g, turning)
        _reach(run, target, g, turning, WAYPOINT_PATIENCE)


def execute_plan(
    env: Any, plan: Any, *, stride: int = PLAN_STRIDE, home_yaw: float = HOME_YAW, execution: str = "open_loop"
) -> PlanOutcome:
    """Run ``plan`` on the unwrapped env (see the module docstring); returns a :class:`PlanOutcome`.

    ``env``: a BlockStackEnv or a wrapper of one (the unwrapped env is stepped, so
    no TimeLimit or success termination interrupts the plan). ``stride``: control
    steps per waypoint (closed loop: at least). ``home_yaw``: the arm's start yaw (rad), near which yaw
    targets are chosen (the expert's rule). A waypoint's gripper value > 0
    closes the gripper, <= 0 opens it. ``execution``: ``"open_loop"`` or ``"closed_loop"``
    (:data:`~steer_envs.control.plans.EXECUTIONS`).
    """
    owner = "execute_plan"
    base = unwrap_blockstack(env, owner)
    arr = check_plan(plan, PLAN_DIM, MAX_WAYPOINTS, owner)
    stride = integer(stride, "stride", low=1, high=1000, owner=owner)
    home_yaw = real_scalar(home_yaw, "home_yaw", owner=owner)
    execution = check_execution(execution, owner)
    grip = np.where(arr[:, 3] > 0, 1.0, -1.0)
    held_before = base.held_cube
    # the wrist yaw: decided from the plan before moving, tracked until the gripper switches
    switch = first_index(grip != base._gripper)
    run = _Tracker(base, _squaring(base, arr, grip, held_before, switch), held_before, home_yaw)
    (_open_loop if execution == "open_loop" else _closed_loop)(run, arr, grip, switch, stride)
    return run.outcome()
