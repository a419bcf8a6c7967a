"""Running BlockStack skill plans open-loop, and reading off which skill a plan performs (ITPS §2.3).

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
support although the P-control lags a moving target.

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

from steer_envs.control.plans import PlanOutcome, check_plan, first_index
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
    "GRASP_Z_TOL",
    "HOME_YAW",
    "MAX_WAYPOINTS",
    "PLACE_Z_TOL",
    "PLAN_DIM",
    "PLAN_STRIDE",
    "SWITCH_SETTLE",
    "SWITCH_TOL",
    "TOWER_CLEARANCE",
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


def execute_plan(env: Any, plan: Any, *, stride: int = PLAN_STRIDE, home_yaw: float = HOME_YAW) -> PlanOutcome:
    """Run ``plan`` open-loop on the unwrapped env (see the module docstring); returns a :class:`PlanOutcome`.

    ``env``: a BlockStackEnv or a wrapper of one (the unwrapped env is stepped, so
    no TimeLimit or success termination interrupts the plan). ``stride``: control
    steps per waypoint. ``home_yaw``: the arm's start yaw (rad), near which yaw
    targets are chosen (the expert's rule). A waypoint's gripper value > 0
    closes the gripper, <= 0 opens it.
    """
    owner = "execute_plan"
    base = unwrap_blockstack(env, owner)
    arr = check_plan(plan, PLAN_DIM, MAX_WAYPOINTS, owner)
    stride = integer(stride, "stride", low=1, high=1000, owner=owner)
    home_yaw = real_scalar(home_yaw, "home_yaw", owner=owner)
    grip = np.where(arr[:, 3] > 0, 1.0, -1.0)
    held_before = base.held_cube
    # the wrist yaw: decided from the plan before moving, tracked until the gripper switches
    switch = first_index(grip != base._gripper)
    square = _squaring(base, arr, grip, held_before, switch)
    trail = [base.state]
    violation = False
    steps = 0
    last_obs = base._obs()

    def step(target: np.ndarray, g: float, turning: bool) -> None:
        nonlocal violation, steps, last_obs
        yaw_err = 0.0
        if turning and square is not None:
            eef_yaw = yaw_of(base.robosuite_obs["robot0_eef_quat"])
            quat = base.cube_quat
            if square[0] == "pick":
                yaw_err = quarter_turn(home_yaw, eef_yaw, yaw_of(quat[square[1]]))
            else:
                assert held_before is not None
                in_hand = yaw_of(quat[held_before]) - eef_yaw
                yaw_err = quarter_turn(home_yaw, eef_yaw, yaw_of(quat[square[1]]) - in_hand)
        action, _ = move_action(base, target, g, yaw_err)
        if turning and square is not None and square[0] == "place":
            action[5] = np.clip(action[5], -_YAW_CARRY, _YAW_CARRY)
        last_obs, _, _, _, info = base.step(action)
        violation |= bool(info["constraint_violation"])
        trail.append(base.state)
        steps += 1

    current = float(base._gripper)
    for k in range(len(arr)):
        target, g = arr[k, :3], float(grip[k])
        turning = switch is None or k <= switch
        if g != current:  # settle on the switching waypoint with the old command, then switch
            for _ in range(SWITCH_SETTLE):
                if np.linalg.norm(target - base.state) < SWITCH_TOL:
                    break
                step(target, current, turning)
            current = g
        for _ in range(stride):
            step(target, g, turning)
    trail_arr = np.stack(trail).astype(np.float64)
    return PlanOutcome(_executed(held_before, base), violation, steps, trail_arr, np.asarray(last_obs))
