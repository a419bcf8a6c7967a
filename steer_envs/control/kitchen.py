"""Running Kitchen skill plans on the arm, and reading off which skill a plan performs (ITPS §2.3).

A Kitchen skill plan (:mod:`steer_envs.data.kitchen_plans`) is ``(H, 5)``:
waypoint ``k`` is the end-effector position (world frame, m), the wrist yaw
(rad, see below) and the gripper command (> 0 closed) after
``PLAN_STRIDE * (k + 1)`` control steps. The tracker
(:func:`execute_kitchen_plan`) interpolates the waypoints linearly at the
control rate, starting from the eef's current pose, and steers toward each
interpolated pose with the env's P-control
(:func:`~steer_envs.envs.robosuite.kitchen.pose_action` toward the position and
``rotation(yaw, 0)``: fingers pointing down). At a gripper switch it first
waits (at most :data:`SWITCH_SETTLE` extra steps) until the eef is on the
switching waypoint, then holds there :data:`SWITCH_HOLD` steps with the new
command, so the fingers close on the handle or bowl (and let a bowl go) where
the plan says, although the P-control lags a moving target. That is the
default, ``execution="open_loop"``. ``execution="closed_loop"``
(:mod:`steer_envs.control.plans`) tracks the same plan as the thesis's robots
did: after a waypoint's interpolation the tracker holds it until the eef is
within :data:`WAYPOINT_TOL` and :data:`WAYPOINT_YAW_TOL` (at most
:data:`WAYPOINT_PATIENCE` more steps); a grasp closes on the switching
waypoint for :data:`CLOSE_STEPS` and checks the hand holds what the plan
closes on (the bowl: both finger pads on it; the handle's bar: the fingers
stopped at least :data:`MIN_GRIP_GAP` apart); if not, it opens, rises
:data:`REAPPROACH_HEIGHT`, comes down on the object where it is now (the bowl:
:data:`BOWL_GRASP_HEIGHT` above its centre; the bar: on its axis at the plan's
height) and closes again, at most :data:`GRASP_RETRIES` times (only for a plan that
closes on the handle or the bowl by :func:`classify_kitchen_plan`'s rules); a
release opens and holds still until the env lets the bowl go (at most
:data:`RELEASE_SETTLE` steps).

Yaw: :func:`eef_yaw` (the expert's wrist yaw: the fingers' opening axis about
the vertical; :func:`~steer_envs.envs.robosuite.kitchen.rotation` of yaw ``y``
has ``eef_yaw == y``). A plan's yaw is continuous (unwrapped) but only defined
up to a multiple of pi (the fingers are symmetric: ``y`` and ``y + pi`` grip
alike); the tracker shifts the whole plan by the multiple of pi that puts its
first waypoint nearest the wrist's yaw now and then follows the plan's yaw
changes, turning the way the plan turns (a half turn of the wrist in a plan is
one in the arm, which keeps the last wrist joint within its limits as the
expert does). Turns are taken at most :data:`YAW_LEAD` rad ahead of the wrist.

:func:`classify_kitchen_plan` is the alignment test of the kitchen study: the
skill a plan would perform from a state, judged geometrically from the plan
alone. :class:`KitchenPlanOutcome` is what the world shows after execution
(the skill is read off the mode before and after with
:func:`~steer_envs.envs.robosuite.kitchen.skill_target`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.control.plans import PlanOutcome, PlanRun, check_execution, check_plan, first_index
from steer_envs.core.validation import integer
from steer_envs.envs.robosuite.kitchen import (
    DOOR_OPEN_ANGLE,
    SKILLS,
    pose_action,
    rotation,
    skill_target,
    unwrap_kitchen,
)
from steer_envs.envs.robosuite.kitchen_assets import BOWL_HEIGHT
from steer_envs.envs.robosuite.kitchen_scene import CAVITY_HIGH, CAVITY_LOW, SINK_SIZE, SINK_XY, TABLE_Z

__all__ = [
    "BOWL_GRASP_HEIGHT",
    "BOWL_XY_TOL",
    "BOWL_Z_RANGE",
    "CLOSE_STEPS",
    "GRASP_RETRIES",
    "HANDLE_ANGLE_TOL",
    "HANDLE_RADIUS_TOL",
    "HANDLE_Z_RANGE",
    "MAX_WAYPOINTS",
    "MIN_GRIP_GAP",
    "PLACE_Z_RANGE",
    "PLAN_DIM",
    "PLAN_STRIDE",
    "REAPPROACH_HEIGHT",
    "RELEASE_SETTLE",
    "SWING_MARGIN",
    "SWITCH_HOLD",
    "SWITCH_SETTLE",
    "SWITCH_TOL",
    "SWITCH_YAW_TOL",
    "WAYPOINT_PATIENCE",
    "WAYPOINT_TOL",
    "WAYPOINT_YAW_TOL",
    "YAW_LEAD",
    "KitchenPlanOutcome",
    "KitchenScene",
    "classify_kitchen_plan",
    "eef_yaw",
    "execute_kitchen_plan",
    "kitchen_scene",
]

#: control steps per plan waypoint (:mod:`steer_envs.data.kitchen_plans`, one layer up, builds plans with it).
PLAN_STRIDE = 9
#: a waypoint: eef x, y, z (m), the wrist yaw (rad) and the gripper command.
PLAN_DIM = 5
#: most waypoints of a plan (the tracker's loop is bounded by this many times the stride, plus the switch settles).
MAX_WAYPOINTS = 10_000
#: most extra control steps the tracker waits at a gripper switch for the eef to reach the switching waypoint.
SWITCH_SETTLE = 20
#: control steps the tracker holds the switching waypoint with the new gripper command (the fingers close / open).
SWITCH_HOLD = 6
#: the eef is "on" the switching waypoint within this distance (m) ...
SWITCH_TOL = 0.005
#: ... and within this yaw (rad).
SWITCH_YAW_TOL = 0.05
#: closed loop: the tracker moves on once the eef is within this distance (m) ...
WAYPOINT_TOL = 0.015
#: ... and this yaw (rad) of the waypoint ...
WAYPOINT_YAW_TOL = 0.1
#: ... or after this many extra control steps on it.
WAYPOINT_PATIENCE = 15
#: closed loop: control steps the fingers close before the grasp is checked (the expert's).
CLOSE_STEPS = 10
#: closed loop: most times a grasp that closed on nothing is tried again.
GRASP_RETRIES = 2
#: closed loop: a retry comes down onto the grasp point from this far (m) above it.
REAPPROACH_HEIGHT = 0.05
#: closed loop: a retry on the bowl closes this far (m) above its centre (the expert's grasp).
BOWL_GRASP_HEIGHT = 0.005
#: closed loop: the fingers closed on the handle's bar stay at least this far apart (m, both fingers' travel).
MIN_GRIP_GAP = 0.005
#: closed loop: most control steps the opened hand holds still for the env to let the bowl go (its latch clears).
RELEASE_SETTLE = 30
#: the tracker's yaw target leads the wrist by at most this much (rad), so a turn goes the plan's way.
YAW_LEAD = 0.5
#: a plan closes on the handle within this distance (m) of the circle the bar's axis moves on about the hinge, ...
HANDLE_RADIUS_TOL = 0.03
#: ... within this angle (rad) about the hinge of the bar (the door gives a little when the hand comes down) ...
HANDLE_ANGLE_TOL = 0.15
#: ... and within this height range (m) relative to the bar's centre (the bar is vertical).
HANDLE_Z_RANGE = (-0.15, 0.18)
#: a plan closes on the bowl within this xy distance (m) of its centre ...
BOWL_XY_TOL = 0.025
#: ... and within this height range (m) relative to it.
BOWL_Z_RANGE = (-0.02, 0.035)
#: the held bowl's centre where a plan opens, relative to its resting height in the sink / microwave (m).
PLACE_Z_RANGE = (-0.02, 0.04)
#: a door plan swings the door past :data:`~steer_envs.envs.robosuite.kitchen.DOOR_OPEN_ANGLE` by this much (rad).
SWING_MARGIN = 0.2


def eef_yaw(env: Any) -> float:
    """The wrist yaw (rad, in (-pi, pi]) of ``env``'s eef: the fingers' opening axis about the vertical.

    The expert's convention: :func:`~steer_envs.envs.robosuite.kitchen.rotation` of
    yaw ``y`` has yaw ``y``; yaw 0 opens the fingers along world y.
    """
    rot = unwrap_kitchen(env, "eef_yaw").eef_rotation
    return float(np.arctan2(-rot[0, 0], rot[1, 0]))


# ------------------------------------------------------------------------------ scenes
@dataclass(frozen=True)
class KitchenScene:
    """What :func:`classify_kitchen_plan` reads of a state (world frame, m; a copy of the env's values).

    Attributes:
        eef: ``(3,)`` the eef position.
        bowl: ``(3,)`` the bowl's centre.
        held: the bowl is held (the env's latch).
        door_angle: how far the door is open (rad, 0 shut).
        handle: ``(3,)`` the centre of the door handle's bar.
        hinge: ``(3,)`` a point on the door's (vertical) hinge axis.
    """

    eef: np.ndarray
    bowl: np.ndarray
    held: bool
    door_angle: float
    handle: np.ndarray
    hinge: np.ndarray


def kitchen_scene(env: Any) -> KitchenScene:
    """The :class:`KitchenScene` of ``env``'s current state (a KitchenEnv or a wrapper of one)."""
    base = unwrap_kitchen(env, "kitchen_scene")
    return KitchenScene(
        eef=base.state,
        bowl=base.bowl_pos,
        held=bool(base.held),
        door_angle=base.door_angle,
        handle=base.handle_pos,
        hinge=base.hinge_pos,
    )


def _heading(v: np.ndarray) -> float:
    return float(np.arctan2(v[1], v[0]))


# ------------------------------------------------------------------------ classification
def _door_angle_at(scene: KitchenScene, point: np.ndarray) -> float:
    """The door angle that turns the handle's bar about the hinge toward ``point`` (seen from above)."""
    turn = _heading(point - scene.hinge) - _heading(scene.handle - scene.hinge)
    # the door angle grows as the handle turns clockwise about the hinge
    return scene.door_angle - float((turn + np.pi) % (2 * np.pi) - np.pi)


def _on_handle(scene: KitchenScene, point: np.ndarray) -> bool:
    radial = np.linalg.norm((point - scene.hinge)[:2]) - np.linalg.norm((scene.handle - scene.hinge)[:2])
    height = point[2] - scene.handle[2]
    return bool(
        abs(radial) < HANDLE_RADIUS_TOL
        and abs(_door_angle_at(scene, point) - scene.door_angle) < HANDLE_ANGLE_TOL
        and HANDLE_Z_RANGE[0] <= height <= HANDLE_Z_RANGE[1]
    )


def _door_skill(scene: KitchenScene, arr: np.ndarray, k: int) -> str | None:
    """The door skill of a plan closing on the handle at waypoint ``k``: where its closed stretch leaves the door."""
    reopen = first_index(arr[k:, 4] <= 0)
    last = len(arr) - 1 if reopen is None else k + reopen - 1
    after = _door_angle_at(scene, arr[last, :3])
    if scene.door_angle <= DOOR_OPEN_ANGLE < after - SWING_MARGIN:
        return "open_door"
    if scene.door_angle > DOOR_OPEN_ANGLE > after + SWING_MARGIN:
        return "close_door"
    return None


def _on_bowl(scene: KitchenScene, point: np.ndarray) -> bool:
    rel = point - scene.bowl
    return bool(np.linalg.norm(rel[:2]) < BOWL_XY_TOL and BOWL_Z_RANGE[0] <= rel[2] <= BOWL_Z_RANGE[1])


def _place_of(centre: np.ndarray) -> str | None:
    """``place_in_sink`` / ``place_in_microwave`` when a bowl let go with its centre at ``centre`` lands there."""
    half = np.asarray(SINK_SIZE[:2]) / 2 - 0.01
    sink_rest = TABLE_Z + 0.01 + BOWL_HEIGHT / 2
    if np.all(np.abs(centre[:2] - np.asarray(SINK_XY)) <= half):
        low, high = PLACE_Z_RANGE
        return "place_in_sink" if low <= centre[2] - sink_rest <= high else None
    oven_rest = float(CAVITY_LOW[2]) + BOWL_HEIGHT / 2
    inside = np.all(centre[:2] >= CAVITY_LOW[:2]) and np.all(centre[:2] <= CAVITY_HIGH[:2])
    if inside and PLACE_Z_RANGE[0] <= centre[2] - oven_rest <= PLACE_Z_RANGE[1]:
        return "place_in_microwave"
    return None


def classify_kitchen_plan(env_or_state: Any, plan: Any) -> str | None:
    """The skill ``plan`` would perform from a state, judged from the plan alone; None if it does none.

    ``env_or_state``: a KitchenEnv (or a wrapper of one) or a :class:`KitchenScene`.
    Hand free: at the first closing waypoint (gripper > 0), on the door
    handle's bar (:data:`HANDLE_RADIUS_TOL`, :data:`HANDLE_ANGLE_TOL`,
    :data:`HANDLE_Z_RANGE`) it is a door skill: ``open_door`` when the last
    waypoint of the closed stretch has swung the handle about the hinge so the
    door ends open by more than :data:`SWING_MARGIN` beyond ``DOOR_OPEN_ANGLE``
    (from a door not open), ``close_door`` for the mirror case; on the bowl
    (:data:`BOWL_XY_TOL`, :data:`BOWL_Z_RANGE`) it is ``pick_bowl``. Holding
    the bowl: at the first opening waypoint, the held bowl's centre (the
    waypoint plus the held offset now) low in the sink's basin is
    ``place_in_sink``, low in the microwave's cavity ``place_in_microwave``
    (heights: :data:`PLACE_Z_RANGE`). Legality in the mode is not judged (a
    plan placing into a shut microwave still reads as that place).
    """
    owner = "classify_kitchen_plan"
    scene = env_or_state if isinstance(env_or_state, KitchenScene) else None
    if scene is None:
        try:
            scene = kitchen_scene(env_or_state)
        except TypeError:
            raise TypeError(
                f"{owner}: `env_or_state` must be a KitchenEnv (or wrap one) or a KitchenScene, "
                f"got {type(env_or_state).__name__}"
            ) from None
    arr = check_plan(plan, PLAN_DIM, MAX_WAYPOINTS, owner)
    if not scene.held:
        k = first_index(arr[:, 4] > 0)
        if k is None:
            return None
        point = arr[k, :3]
        if _on_handle(scene, point):
            return _door_skill(scene, arr, k)
        return "pick_bowl" if _on_bowl(scene, point) else None
    k = first_index(arr[:, 4] <= 0)
    if k is None:
        return None
    return _place_of(arr[k, :3] + (scene.bowl - scene.eef))


# ------------------------------------------------------------------------------ execution
@dataclass(frozen=True, kw_only=True)
class KitchenPlanOutcome(PlanOutcome):
    """What executing a plan did (:class:`~steer_envs.control.plans.PlanOutcome`) and the modes it ran between.

    ``executed`` is the skill leading from ``mode_before`` (the mode name at
    the start) to ``mode_after`` (after the last step), or None (no mode
    change, or one no skill makes).
    """

    mode_before: str
    mode_after: str


def _executed(before: str, after: str) -> str | None:
    if before == after:
        return None
    return next((s for s in SKILLS if skill_target(before, s) == after), None)


class _Tracker(PlanRun):
    """One plan run: the env, the wrist's unwrapped yaw, and the outcome so far (:class:`PlanRun`)."""

    def __init__(self, base: Any) -> None:
        super().__init__(base)
        self.yaw_now = eef_yaw(base)  # the wrist's yaw, unwrapped along the run

    def step(self, target: np.ndarray, yaw: float, g: float) -> None:
        """One control step toward ``target`` and ``yaw`` (led by at most :data:`YAW_LEAD`) with gripper ``g``."""
        lead = self.yaw_now + float(np.clip(yaw - self.yaw_now, -YAW_LEAD, YAW_LEAD))
        action, _ = pose_action(self.base, target, rotation(lead, 0.0), g)
        self.advance(action)
        now = eef_yaw(self.base)
        self.yaw_now += float((now - self.yaw_now + np.pi) % (2 * np.pi) - np.pi)

    def on(self, pos: np.ndarray, yaw: float, tol: float, yaw_tol: float) -> bool:
        """The eef is within ``tol`` (m) of ``pos`` and ``yaw_tol`` (rad) of ``yaw``."""
        return bool(np.linalg.norm(pos - self.base.state) < tol and abs(yaw - self.yaw_now) < yaw_tol)

    def settle(self, pos: np.ndarray, yaw: float, g: float, most: int) -> None:
        """Step toward the pose until on it (:data:`SWITCH_TOL`, :data:`SWITCH_YAW_TOL`), at most ``most`` steps."""
        for _ in range(most):
            if self.on(pos, yaw, SWITCH_TOL, SWITCH_YAW_TOL):
                return
            self.step(pos, yaw, g)

    def reach(self, pos: np.ndarray, yaw: float, g: float, most: int) -> None:
        """Step toward the pose until within :data:`WAYPOINT_TOL` / :data:`WAYPOINT_YAW_TOL`, at most ``most`` steps."""
        for _ in range(most):
            if self.on(pos, yaw, WAYPOINT_TOL, WAYPOINT_YAW_TOL):
                return
            self.step(pos, yaw, g)

    def switch(self, pos: np.ndarray, yaw: float, old: float, new: float) -> None:
        """Settle on the switching pose with the ``old`` command, then hold it :data:`SWITCH_HOLD` steps, ``new``."""
        self.settle(pos, yaw, old, SWITCH_SETTLE)
        for _ in range(SWITCH_HOLD):
            self.step(pos, yaw, new)


def _grip_target(base: Any, point: np.ndarray) -> str | None:
    """What a hand closing at ``point`` grasps by the classifier's rules: ``"handle"``, ``"bowl"`` or None."""
    scene = kitchen_scene(base)
    if _on_handle(scene, point):
        return "handle"
    return "bowl" if _on_bowl(scene, point) else None


def _object_pos(base: Any, target: str) -> np.ndarray:
    return np.asarray(base.handle_pos if target == "handle" else base.bowl_pos)


def _gripping(base: Any, target: str) -> bool:
    """The closed hand holds ``target``: both finger pads on the bowl (the env's grasp contacts), or, on the
    handle's bar, the fingers stopped apart by it (:data:`MIN_GRIP_GAP`)."""
    if target == "bowl":
        return bool(base._grasped())
    gap = float(np.sum(np.abs(base.robosuite_obs["robot0_gripper_qpos"])))
    return gap > MIN_GRIP_GAP


def _regrasp_point(base: Any, target: str, pos: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Where a retry closes: on the bowl, :data:`BOWL_GRASP_HEIGHT` above its centre now (the expert's grasp);
    on the handle's bar, on its axis now at the plan's height (moved with the bar since ``start``)."""
    now = _object_pos(base, target)
    if target == "bowl":
        return now + np.array([0.0, 0.0, BOWL_GRASP_HEIGHT])
    return np.array([now[0], now[1], pos[2] + now[2] - start[2]])


def _grasp(run: _Tracker, pos: np.ndarray, yaw: float) -> None:
    """Close on ``pos``; while the plan's object is not held, re-approach it where it is now and close again.

    The object is the one the closing waypoint reads as (:func:`classify_kitchen_plan`'s
    rules: the handle's bar or the bowl); a plan that closes on neither gets no retry. A
    retry opens, rises :data:`REAPPROACH_HEIGHT`, moves over the object's grasp point now
    (:func:`_regrasp_point`), comes down onto it and closes: at most :data:`GRASP_RETRIES` times.
    """
    base = run.base
    target = _grip_target(base, pos)
    start = None if target is None else _object_pos(base, target)
    point = pos
    up = np.array([0.0, 0.0, REAPPROACH_HEIGHT])
    for attempt in range(GRASP_RETRIES + 1):
        run.switch(point, yaw, -1.0, 1.0)
        for _ in range(CLOSE_STEPS - SWITCH_HOLD):
            run.step(point, yaw, 1.0)
        if target is None or start is None or _gripping(base, target) or attempt == GRASP_RETRIES:
            return
        run.regrasps += 1
        for _ in range(CLOSE_STEPS):
            run.step(point, yaw, -1.0)
        run.reach(point + up, yaw, -1.0, SWITCH_SETTLE)
        point = _regrasp_point(base, target, pos, start)
        run.reach(point + up, yaw, -1.0, SWITCH_SETTLE)


def _release(run: _Tracker, pos: np.ndarray, yaw: float) -> None:
    """Open on ``pos`` and hold still until the env lets the bowl go (it rests somewhere), bounded."""
    run.settle(pos, yaw, 1.0, SWITCH_SETTLE)
    for i in range(RELEASE_SETTLE):
        run.step(pos, yaw, -1.0)
        if i + 1 >= SWITCH_HOLD and not run.base.held:
            return


def _run(run: _Tracker, arr: np.ndarray, grip: np.ndarray, yaws: np.ndarray, stride: int, closed: bool) -> None:
    """Interpolate each waypoint over ``stride`` steps; switch the gripper on its waypoint (see the module docstring).

    ``closed``: then wait on each waypoint (bounded) and check grasps and releases.
    """
    base = run.base
    current = float(base._gripper)
    prev_pos, prev_yaw = base.state, run.yaw_now
    for k in range(len(arr)):
        pos, yaw, g = arr[k, :3], float(yaws[k]), float(grip[k])
        switching = g != current
        for i in range(1, stride + 1):
            f = i / stride
            run.step(prev_pos + f * (pos - prev_pos), prev_yaw + f * (yaw - prev_yaw), current if switching else g)
        if switching and closed and g > 0 and not base.held:
            _grasp(run, pos, yaw)
        elif switching and closed and g <= 0 and base.held:
            _release(run, pos, yaw)
        elif switching:  # settle on the switching waypoint with the old command, then switch and hold
            run.switch(pos, yaw, current, g)
        elif closed:
            run.reach(pos, yaw, g, WAYPOINT_PATIENCE)
        current = g
        prev_pos, prev_yaw = pos, yaw


def execute_kitchen_plan(
    env: Any, plan: Any, *, stride: int = PLAN_STRIDE, execution: str = "open_loop"
) -> KitchenPlanOutcome:
    """Run ``plan`` on the unwrapped env (see the module docstring); returns a :class:`KitchenPlanOutcome`.

    ``env``: a KitchenEnv or a wrapper of one (the unwrapped env is stepped, so
    no TimeLimit or success termination interrupts the plan). ``stride``:
    control steps per waypoint (closed loop: at least). A waypoint's gripper value > 0 closes the
    gripper, <= 0 opens it. ``execution``: ``"open_loop"`` or ``"closed_loop"``
    (:data:`~steer_envs.control.plans.EXECUTIONS`).
    """
    owner = "execute_kitchen_plan"
    base = unwrap_kitchen(env, owner)
    arr = check_plan(plan, PLAN_DIM, MAX_WAYPOINTS, owner)
    stride = integer(stride, "stride", low=1, high=1000, owner=owner)
    execution = check_execution(execution, owner)
    grip = np.where(arr[:, 4] > 0, 1.0, -1.0)
    before = base.task.modes[base._mode]
    run = _Tracker(base)
    yaws = arr[:, 3] + np.pi * np.round((run.yaw_now - arr[0, 3]) / np.pi)
    _run(run, arr, grip, yaws, stride, execution == "closed_loop")
    after = base.task.modes[base._mode]
    trail = np.stack(run.trail).astype(np.float64)
    obs = np.asarray(run.last_obs)
    return KitchenPlanOutcome(
        _executed(before, after),
        run.violation,
        run.steps,
        trail,
        obs,
        run.regrasps,
        mode_before=before,
        mode_after=after,
    )
