"""``KitchenEnv``: a Panda, a microwave with a hinged door, a sink and a bowl (robosuite, delta OSC): ITPS §2.3.

The thesis's real toy kitchen, simulated: the microwave is gymnasium-robotics'
FrankaKitchen microwave converted for robosuite (:mod:`.kitchen_assets`,
scale :data:`~steer_envs.envs.robosuite.kitchen_scene.MICROWAVE_SCALE`, its opening facing the robot, the hinge on the
robot's left), the sink a fixed robosuite ``Bin``, the bowl a small MJCF of our
own (6 cm across: the open fingers close around it). robosuite is imported
when an env is made, never by ``import steer_envs``.

Observation (flat ``float32``, 17): ``robot0_eef_pos`` (3), ``robot0_eef_quat``
(4, xyzw), ``robot0_gripper_qpos`` (2), ``bowl_pos`` (3), ``bowl_quat`` (4),
``door_angle`` (1, rad, 0 shut, positive open). Action: the adapter's 7-D delta
OSC action (+1 closes the gripper).

Sensors (``info["sensors"]``):

- ``door_open``: the door is open more than :data:`DOOR_OPEN_ANGLE`.
- ``held``: latched like BlockStack's: set once both finger pads have touched
  the bowl for two control steps; it stays set while the bowl is grasped or
  not yet resting, for at most :data:`RELEASE_STEPS` steps after the grasp is lost.
- ``in_sink`` / ``in_microwave`` / ``on_table``: where the (not held) bowl's
  centre is: inside the sink's basin, inside the microwave's cavity, or low on
  the table (within :data:`ON_TABLE_HEIGHT` of the table top) elsewhere.
- ``washed``: latched: the bowl has rested in the sink this episode.

Modes: ``{door}_{place}[_washed]`` with door ``closed`` / ``open`` and place
``table``, ``sink``, ``microwave``, ``held`` (a bowl in the sink is washed),
plus ``lost`` (the bowl rests nowhere it may: off the table, tipped onto a
wall). The allowed mode changes are the skills' (:data:`SKILLS`,
:func:`skill_target`): ``open_door`` / ``close_door`` with the hand free,
``pick_bowl`` from the table, the sink or an open microwave, ``place_in_sink``,
``place_in_microwave`` only with the door open. Their tree is the env's
``TaskSpec`` (:func:`kitchen_task`).

``info["constraint_violation"]``: a mode change the skills do not make (e.g. a
bowl placed into the microwave while the door is closed, the door moved while
holding the bowl, a bowl pushed off the table); a drop (the held latch clears
and the bowl fell more than :data:`DROP_HEIGHT` since it was last grasped, or
rests nowhere). ``perturb`` never reports one.

Tasks (``task=``; ``info["success"]``, reward 1, terminates), hand free in each:

- ``"clean"`` (default, thesis Fig. 2.8): the bowl washed (it rested in the
  sink) and then in the microwave with the door shut. From the start (bowl on
  the table, door shut) it takes at least six skills, in two orders:
  open, pick, sink, pick, microwave, close or pick, sink, open, pick, microwave, close.
- ``"microwave"``: the bowl in the microwave, the door shut (the thesis's task 1).
- ``"sink"``: the bowl in the sink (the thesis's task 2).

Success needs the door shut (below :data:`DOOR_SHUT_ANGLE`) where the task
asks for a closed door; the ``door_open`` sensor only splits the modes.
"""

from __future__ import annotations

import functools
import itertools
from typing import Any, Unpack

import numpy as np

from steer_envs.core.interaction import InteractionKind
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import one_of, real_array, real_scalar
from steer_envs.envs.checks import check_options, check_seed
from steer_envs.envs.robosuite.adapter import GRASP_HOLD_STEPS, RobosuiteEnv, ViewOptions
from steer_envs.envs.robosuite.kitchen_assets import BOWL_HEIGHT
from steer_envs.envs.robosuite.kitchen_scene import (
    CAVITY_HIGH,
    CAVITY_LOW,
    SCENE_CAMERA,
    SINK_FLOOR_Z,
    SINK_SIZE,
    SINK_WALL,
    SINK_XY,
    TABLE_SIZE,
    TABLE_Z,
    kitchen_sim_class,
)

__all__ = [
    "BOWL_PLACES",
    "DOOR_OPEN_ANGLE",
    "DOOR_SHUT_ANGLE",
    "DROP_HEIGHT",
    "KITCHEN_TASKS",
    "ON_TABLE_HEIGHT",
    "RELEASE_STEPS",
    "R_DOWN",
    "SENSORS",
    "SKILLS",
    "KitchenEnv",
    "kitchen_task",
    "legal_skills",
    "mode_name",
    "pose_action",
    "push_toward",
    "rotation",
    "skill_centre",
    "skill_target",
    "unwrap_kitchen",
]

#: the door counts as open beyond this angle (rad) ...
DOOR_OPEN_ANGLE = 0.9
#: ... and as shut (a task's closed door) below this one.
DOOR_SHUT_ANGLE = 0.05
#: a bowl not held whose centre is within this height (m) above its resting height on the table is on the table.
ON_TABLE_HEIGHT = 0.03
#: a released bowl that fell more than this (m) was dropped, not placed.
DROP_HEIGHT = 0.05
#: the held latch clears at the latest this many control steps after the grasp is lost.
RELEASE_STEPS = 20
_REST_SPEED = 0.02  # m/s: a bowl slower than this rests

KITCHEN_TASKS = ("clean", "microwave", "sink")
#: where the bowl may start (reset option ``bowl``).
BOWL_PLACES = ("table", "sink", "microwave")
_DOORS = ("closed", "open")
SENSORS = ("door_open", "held", "on_table", "in_sink", "in_microwave", "washed")
_PLACES = ("table", "sink", "microwave", "held")
#: the skills; which one is legal depends on the mode (:func:`legal_skills`).
SKILLS = ("open_door", "close_door", "pick_bowl", "place_in_sink", "place_in_microwave")

#: the eef orientation with the fingers pointing straight down and opening along world y (yaw 0).
R_DOWN = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
_GAIN = 10.0
_ROT_GAIN = 2.0


def mode_name(door_open: bool, place: str, washed: bool) -> str:
    """The mode of a world: door, where the bowl is (``table``, ``sink``, ``microwave``, ``held``, ``lost``), washed.

    >>> mode_name(True, "held", True), mode_name(False, "sink", True), mode_name(False, "lost", False)
    ('open_held_washed', 'closed_sink', 'lost')
    """
    if place == "lost":
        return "lost"
    suffix = "_washed" if washed and place != "sink" else ""
    return f"{_DOORS[int(door_open)]}_{place}{suffix}"


def _worlds() -> list[tuple[bool, str, bool]]:
    """Every (door_open, place, washed) a sensor reading can show (a bowl in the sink is washed)."""
    out = []
    for door, place, washed in itertools.product((False, True), _PLACES, (False, True)):
        if place == "sink" and not washed:
            continue
        out.append((door, place, washed))
    return out


def unwrap_kitchen(env: Any, owner: str) -> KitchenEnv:
    """``env`` unwrapped: a :class:`KitchenEnv`, else a ``TypeError`` naming ``owner``."""
    base = getattr(env, "unwrapped", env)
    if not isinstance(base, KitchenEnv):
        raise TypeError(f"{owner}: `env` must be a KitchenEnv (or wrap one), got {type(env).__name__}")
    return base


def skill_centre(env: Any, skill: str) -> np.ndarray:
    """The centre of ``skill``'s target in ``env``'s current state (world, m): where a user clicks or pushes.

    ``env`` is a :class:`KitchenEnv` or wraps one; ``skill`` one of :data:`SKILLS`.
    """
    base = unwrap_kitchen(env, "skill_centre")
    if not isinstance(skill, str) or skill not in SKILLS:
        raise ValueError(f"skill_centre: `skill` must be one of {list(SKILLS)}, got {skill!r}")
    if skill in ("open_door", "close_door"):
        return base.handle_pos
    if skill == "pick_bowl":
        return base.bowl_pos
    if skill == "place_in_sink":
        return np.array([SINK_XY[0], SINK_XY[1], SINK_FLOOR_Z])
    mid = (CAVITY_LOW + CAVITY_HIGH) / 2
    return np.array([mid[0], mid[1], CAVITY_LOW[2]])


def push_toward(env: KitchenEnv, point: np.ndarray, distance: float) -> dict[str, Any] | None:
    """Push the end effector straight toward ``point`` by ``distance`` m, less when nearer (``env.perturb``).

    OP's physical correction and the pushed starts of the Kitchen data share
    it. A push that would leave the arm's workspace (``env.perturb_workspace``:
    e.g. toward a point on or below the table's top) stops where the straight
    line leaves it (to 0.1 mm). Returns the push's ``info``, or ``None`` (no
    push) when the end effector is at ``point``.
    """
    start = env.state
    delta = np.asarray(point, dtype=np.float64) - start
    dist = float(np.linalg.norm(delta))
    if dist == 0:
        return None
    delta = delta * min(1.0, distance / dist)
    workspace = env.perturb_workspace
    if not workspace.contains(start + delta) and workspace.contains(start):
        inside, outside = 0.0, 1.0  # fractions of the push: the last known inside, the first known outside
        while (outside - inside) * float(np.linalg.norm(delta)) > 1e-4:
            mid = (inside + outside) / 2
            inside, outside = (mid, outside) if workspace.contains(start + mid * delta) else (inside, mid)
        delta = delta * inside
    return env.perturb(delta)


def skill_target(mode: str, skill: str) -> str | None:
    """The mode ``skill`` leads to from ``mode``, or None where the skill is not legal there.

    >>> skill_target("closed_held", "place_in_microwave") is None, skill_target("open_held", "place_in_microwave")
    (True, 'open_microwave')
    """
    if not isinstance(skill, str) or skill not in SKILLS:
        raise ValueError(f"skill_target: unknown `skill` {skill!r}; skills: {list(SKILLS)}")
    world = _WORLD_OF.get(mode) if isinstance(mode, str) else None
    if world is None:
        raise ValueError(f"skill_target: unknown `mode` {mode!r}; modes: {list(kitchen_task().modes)}")
    if mode == "lost":
        return None
    door, place, washed = world
    free = place != "held"
    if skill == "open_door":
        return mode_name(True, place, washed) if free and not door else None
    if skill == "close_door":
        return mode_name(False, place, washed) if free and door else None
    if skill == "pick_bowl":
        if place in ("table", "sink") or (place == "microwave" and door):
            return mode_name(door, "held", washed or place == "sink")
        return None
    if place != "held":
        return None
    if skill == "place_in_sink":
        return mode_name(door, "sink", True)
    return mode_name(door, "microwave", washed) if door else None


def legal_skills(mode: str) -> tuple[str, ...]:
    """The skills legal in ``mode`` (in :data:`SKILLS` order).

    >>> legal_skills("closed_table")
    ('open_door', 'pick_bowl')
    """
    return tuple(s for s in SKILLS if skill_target(mode, s) is not None)


_WORLD_OF: dict[str, tuple[bool, str, bool]] = {mode_name(*w): w for w in _worlds()}
_WORLD_OF["lost"] = (False, "lost", False)


def _reading(door: bool, place: str, washed: bool) -> frozenset[str]:
    true = {"door_open"} if door else set()
    if place == "held":
        true.add("held")
    elif place != "lost":
        true.add({"table": "on_table", "sink": "in_sink", "microwave": "in_microwave"}[place])
    if washed:
        true.add("washed")
    return frozenset(true)


@functools.cache
def kitchen_task(task: str = "clean") -> TaskSpec:
    """The :class:`TaskSpec`: the skills' mode tree, the goal of ``task`` (one of :data:`KITCHEN_TASKS`).

    >>> spec = kitchen_task()
    >>> spec.initial, spec.goal, len(spec.shortest_plan("closed_table")) - 1
    ('closed_table', ('closed_microwave_washed',), 6)
    """
    one_of(task, "task", KITCHEN_TASKS, owner="kitchen_task")
    sensor_modes: dict[frozenset[str], str] = {}
    for door, place, washed in _worlds():
        sensor_modes[_reading(door, place, washed)] = mode_name(door, place, washed)
    for door, washed in itertools.product((False, True), (False, True)):
        sensor_modes[_reading(door, "lost", washed)] = "lost"
    modes = (*dict.fromkeys(mode_name(*w) for w in _worlds()), "lost")
    transitions = {(m, t) for m in modes for s in SKILLS if (t := skill_target(m, s)) is not None}
    goals = {
        "clean": ("closed_microwave_washed",),
        "microwave": ("closed_microwave", "closed_microwave_washed"),
        "sink": ("closed_sink", "open_sink"),
    }[task]
    return TaskSpec(
        name=f"kitchen-{task}",
        modes=modes,
        sensors=SENSORS,
        sensor_modes=sensor_modes,
        transitions=frozenset(transitions),
        initial="closed_table",
        goal=goals,
    )


# ------------------------------------------------------------------------------ control
def rotation(yaw: float = 0.0, pitch: float = 0.0) -> np.ndarray:
    """The eef orientation (3x3) ``R_DOWN`` pitched by ``pitch`` (rad, fingertips toward +x) then yawed by ``yaw``."""
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, -sp], [0.0, 1.0, 0.0], [sp, 0.0, cp]])  # about y by -pitch
    return rz @ ry @ R_DOWN


def _rotvec(rot: np.ndarray) -> np.ndarray:
    """The axis-angle vector of a rotation matrix."""
    angle = float(np.arccos(np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0)))
    axis = np.array([rot[2, 1] - rot[1, 2], rot[0, 2] - rot[2, 0], rot[1, 0] - rot[0, 1]])
    if angle < 1e-6:
        return 0.5 * axis
    if angle > np.pi - 1e-3:  # a half turn: the axis from the symmetric part
        k = int(np.argmax(np.diag(rot)))
        v = (rot[:, k] + np.eye(3)[k]) / np.sqrt(2.0 * (1.0 + rot[k, k]))
        return v * angle
    return axis * (angle / (2.0 * np.sin(angle)))


def pose_action(
    env: KitchenEnv, target: np.ndarray, rot: np.ndarray, gripper: float, *, speed: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """The P-control delta-OSC action toward eef position ``target`` and orientation ``rot``; and the position error.

    Gain 10 on position (clipped to ``+-speed``), 2 on orientation (axis-angle,
    clipped to [-1, 1]); ``gripper`` is the command (-1 open, +1 closed).
    """
    speed = real_scalar(speed, "speed", low=0.0, low_inclusive=False, high=1.0, owner="pose_action")
    d = np.asarray(target, dtype=np.float64) - env.state
    action = np.zeros(7, dtype=np.float32)
    action[:3] = np.clip(d * _GAIN, -speed, speed)
    action[3:6] = np.clip(_rotvec(rot @ env.eef_rotation.T) * _ROT_GAIN, -1.0, 1.0)
    action[6] = gripper
    return action, d


class KitchenEnv(RobosuiteEnv):
    """Kitchen rearrangement with a Panda: a microwave with a door, a sink and a bowl (see the module docstring).

    Args:
        task: ``"clean"`` (default), ``"microwave"`` or ``"sink"``: what ``success`` asks (:data:`KITCHEN_TASKS`).
        render_mode, render_size, perturb_exact, fast_render: as for
            :class:`~steer_envs.envs.robosuite.adapter.RobosuiteEnv`.
        camera: the camera ``render`` and the pixel methods use (default the scene camera
            :data:`~steer_envs.envs.robosuite.kitchen_scene.SCENE_CAMERA`, high on the robot's right).

    Reset options: ``state`` (eef start, as the adapter's), ``bowl`` (where the bowl
    starts: ``"table"`` (default, a seeded spot), ``"sink"``, ``"microwave"``),
    ``door`` (``"closed"`` (default) or ``"open"``).
    Interactions: ``point`` (a world point, e.g. from :meth:`pixel_to_world` on a click
    in the scene camera), ``sketch`` (a 3D eef path, m) and ``nudge`` (``perturb``).

    >>> KitchenEnv.interaction_kinds
    ('point', 'sketch', 'nudge')
    """

    interaction_kinds: tuple[InteractionKind, ...] = ("point", "sketch", "nudge")
    _OPTION_KEYS = frozenset({"state", "bowl", "door"})
    default_camera = SCENE_CAMERA

    def __init__(
        self,
        task: str = "clean",
        **view: Unpack[ViewOptions],
    ) -> None:
        owner = type(self).__name__
        self.kitchen_task = one_of(task, "task", KITCHEN_TASKS, owner=owner)
        self._check_view_args(view, owner)
        self.task_name = "kitchen"
        self.task = kitchen_task(self.kitchen_task)
        self.obs_keys = (
            "robot0_eef_pos",
            "robot0_eef_quat",
            "robot0_gripper_qpos",
            "bowl_pos",
            "bowl_quat",
            "door_angle",
        )
        self._build_sim(lambda **kwargs: kitchen_sim_class()(**kwargs), owner)
        rs = self.rs_env
        self._object = rs.bowl
        self._object_geoms, self._pad_geoms = self._grasp_masks()
        self._robot_geoms = self._robot_mask()
        self._object_qvel = int(rs.sim.model.get_joint_qvel_addr(rs.bowl.joints[0])[0])
        self.table_z = TABLE_Z
        self._base_body = int(rs.sim.model.body_name2id("robot0_base"))
        self._reset_spaces()
        self._gripper = -1.0
        self._begin()

    # ----------------------------------------------------------------- state
    @property
    def object_pos(self) -> np.ndarray:
        """The bowl's centre (m, a copy)."""
        return np.array(self.rs_env.sim.data.body_xpos[self.rs_env.bowl_body_id], dtype=np.float64)

    @property
    def bowl_pos(self) -> np.ndarray:
        """The bowl's centre (m, a copy)."""
        return self.object_pos

    @property
    def door_angle(self) -> float:
        """How far the microwave door is open (rad; 0 shut, up to ~2.09)."""
        return float(-self.rs_env.sim.data.qpos[self.rs_env.door_qpos])

    @property
    def handle_pos(self) -> np.ndarray:
        """The centre of the door handle's bar (m, a copy)."""
        return np.array(self.rs_env.sim.data.site_xpos[self.rs_env.handle_site_id], dtype=np.float64)

    @property
    def hinge_pos(self) -> np.ndarray:
        """A point on the door's hinge axis (vertical; the door body's origin, m, a copy)."""
        return np.array(self.rs_env.sim.data.body_xpos[self.rs_env.door_body_id], dtype=np.float64)

    @property
    def base_pos(self) -> np.ndarray:
        """The robot base's position (m, a copy)."""
        return np.array(self.rs_env.sim.data.body_xpos[self._base_body], dtype=np.float64)

    @property
    def eef_rotation(self) -> np.ndarray:
        """The eef orientation (3x3 world rotation matrix, a copy)."""
        return np.array(self.rs_env.sim.data.site_xmat[self._eef_site], dtype=np.float64).reshape(3, 3)

    @property
    def held(self) -> bool:
        """The held latch (see the module docstring)."""
        return self._held

    @property
    def place(self) -> str:
        """Where the bowl is by the last sensor reading: ``held``, ``table``, ``sink``, ``microwave`` or ``lost``."""
        return self._place

    @property
    def sink_floor_z(self) -> float:
        """Height (m) of the sink basin's floor (:data:`~steer_envs.envs.robosuite.kitchen_scene.SINK_FLOOR_Z`)."""
        return SINK_FLOOR_Z

    # --------------------------------------------------------------- sensors
    def _location(self, pos: np.ndarray) -> str:
        """Where a bowl centre at ``pos`` is, if not held: ``microwave``, ``sink``, ``table`` or ``lost``."""
        if np.all(pos >= CAVITY_LOW) and np.all(pos <= CAVITY_HIGH):
            return "microwave"
        half = np.asarray(SINK_SIZE[:2]) / 2 - SINK_WALL
        if np.all(np.abs(pos[:2] - np.asarray(SINK_XY)) <= half) and pos[2] < TABLE_Z + SINK_SIZE[2] + BOWL_HEIGHT:
            return "sink"
        on_top = np.all(np.abs(pos[:2]) <= np.asarray(TABLE_SIZE[:2]) / 2)
        if on_top and TABLE_Z < pos[2] < TABLE_Z + BOWL_HEIGHT / 2 + ON_TABLE_HEIGHT:
            return "table"
        return "lost"

    def _at_rest(self) -> bool:
        speed = np.linalg.norm(self.rs_env.sim.data.qvel[self._object_qvel : self._object_qvel + 3])
        return bool(speed < _REST_SPEED) and not self._robot_touches_object()

    def _begin(self) -> None:
        self._held = False
        self._grasp_start: float | None = None
        self._release_time: float | None = None
        self._grasp_z = float(self.object_pos[2])
        self._washed = False
        self._dropped = False
        self._place = self._location(self.object_pos)
        self._gripper = -1.0
        sensors = self._sensors()
        self._dropped = False
        self._mode = self.task.mode_index(self.task.mode_of(sensors))

    def _sensors(self) -> dict[str, bool]:
        """Update the latches from the sim; ``_dropped``: the latch cleared on a drop now."""
        rs = self.rs_env
        now = float(rs.sim.data.time)
        pos = self.object_pos
        grasped = self._grasped()
        self._grasp_start = (now if self._grasp_start is None else self._grasp_start) if grasped else None
        lasted = 0 if self._grasp_start is None else round((now - self._grasp_start) * self.control_freq) + 1
        dropped = False
        if lasted >= GRASP_HOLD_STEPS:
            self._held = True
        if self._held:
            if grasped:
                self._release_time = None
                self._grasp_z = float(pos[2])
            else:
                if self._release_time is None:
                    self._release_time = now
                since = round((now - self._release_time) * self.control_freq)
                where = self._location(pos)
                if (where != "lost" and self._at_rest()) or since > RELEASE_STEPS:
                    self._held = False
                    self._release_time = None
                    dropped = where == "lost" or self._grasp_z - float(pos[2]) > DROP_HEIGHT
        self._dropped = dropped
        self._place = "held" if self._held else self._location(pos)
        if self._place == "sink" and self._at_rest():
            self._washed = True
        door_open = self.door_angle > DOOR_OPEN_ANGLE
        mode = mode_name(door_open, self._place, self._washed or self._place == "sink")
        shut = self.door_angle < DOOR_SHUT_ANGLE
        needs_shut = self.kitchen_task != "sink"
        self._success = mode in self.task.goal and (shut or not needs_shut)
        return {
            "door_open": bool(door_open),
            "held": self._place == "held",
            "on_table": self._place == "table",
            "in_sink": self._place == "sink",
            "in_microwave": self._place == "microwave",
            "washed": bool(self._washed or self._place == "sink"),
        }

    def _event_violation(self) -> bool:
        return self._dropped

    # ------------------------------------------------------------------- API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: the bowl's spot and yaw (and the arm's init noise) drawn from ``seed``.

        ``options``: None or a dict with ``state`` (an eef start position, 3 finite
        reals), ``bowl`` (one of :data:`BOWL_PLACES`) and/or ``door`` (``"closed"`` / ``"open"``).
        """
        owner = f"{type(self).__name__}.reset"
        check_seed(seed, owner)
        opts = check_options(options, self._OPTION_KEYS, owner)
        start = {
            "bowl": one_of(opts.pop("bowl", "table"), "options['bowl']", BOWL_PLACES, owner=owner),
            "door": one_of(opts.pop("door", "closed"), "options['door']", _DOORS, owner=owner),
        }
        if opts.get("state") is not None:
            real_array(opts["state"], "options['state']", shape=(3,), owner=owner)
        self.rs_env.start = start
        return super().reset(seed=seed, options=opts)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One 20 Hz control step of the 7-D delta OSC action; reward 1 on success (which terminates)."""
        obs, _, terminated, truncated, info = super().step(action)
        return obs, float(info["success"]), terminated, truncated, info
