"""The scripted expert of Kitchen: door and bowl skills on delta OSC, and a planner over the legal-sequence tree.

:class:`KitchenSkills` runs one skill at a time on the unwrapped
:class:`~steer_envs.envs.robosuite.kitchen.KitchenEnv` with the env's P-control
(:func:`~steer_envs.envs.robosuite.kitchen.pose_action`: position and full
orientation), reading the sim's ground truth (privileged):

- ``open_door`` / ``close_door``: over the handle with the fingers pointing
  down and opening across the bar, down, close on the bar, then swing the
  handle along its arc about the hinge (the wrist's yaw follows the door) to
  :data:`OPEN_GOAL` / shut, open, up.
- ``pick_bowl``: the fingers (pointing down, tilted toward +x by
  :data:`PITCH`) close around the bowl's wall; from the table or the sink from
  above, from the microwave straight in through the opening and back out.
- ``place_in_sink`` / ``place_in_microwave``: the held bowl's centre (the held
  offset re-read every step) over / in front of the target, down (in, then
  down) until it is just above the floor, open, back out and up.

Over the table and the sink the wrist takes the arm's natural yaw (the fingers
open across the line from the robot's base). In the microwave they open along
world y, across the opening: the hand goes in and comes out along x, so the
open fingers pass beside the bowl; at the natural yaw the finger behind the
bowl would drag a placed bowl back out.

:class:`KitchenPlanner` picks the next skill on a shortest legal sequence to
the task's goal (:func:`~steer_envs.envs.robosuite.kitchen.kitchen_task`); where
several exist (the cleaning task's two six-skill orders) a seeded draw chooses
one per episode. :class:`KitchenExpert` chains them and is the registry's expert
for ``steer_envs/Kitchen-v0``.
"""

from __future__ import annotations

from typing import Any

import networkx as nx
import numpy as np

from steer_envs.core.validation import integer, one_of
from steer_envs.envs.robosuite.kitchen import (
    DOOR_OPEN_ANGLE,
    DOOR_SHUT_ANGLE,
    SKILLS,
    KitchenEnv,
    legal_skills,
    pose_action,
    rotation,
    skill_target,
)
from steer_envs.envs.robosuite.kitchen_assets import BOWL_HEIGHT
from steer_envs.envs.robosuite.kitchen_scene import (
    CAVITY_FRONT_X,
    CAVITY_HIGH,
    CAVITY_LOW,
    DOOR_TOP_Z,
    SINK_XY,
    TABLE_Z,
)

__all__ = ["OPEN_GOAL", "PITCH", "KitchenExpert", "KitchenPlanner", "KitchenSkills"]

#: the fingertips' tilt toward +x (rad) in the microwave (0: straight down, the cavity is tall enough).
PITCH = 0.0
#: the door is swung open to this angle (rad).
OPEN_GOAL = 1.3
_CARRY_Z = TABLE_Z + 0.3  # m: the eef's travel height
_HANDLE_GRIP = 0.14  # m above the handle bar's centre: the pads close around the bar's top end
_OVER_DOOR_Z = DOOR_TOP_Z + 0.05  # m: the door skills come and go this high, over the door's top edge
_CLEAR = np.array([-0.2, 0.12, _OVER_DOOR_Z])  # where the door skills end: in front of the door, hand free
_STAGE_X = CAVITY_FRONT_X - 0.14  # m: the bowl waits here, in front of the microwave, before going in
_PLACE_IN_X = CAVITY_FRONT_X + 0.045  # m: a bowl placed in the microwave stands this far in
_SIDE_Y = -0.05  # m: the microwave's side of the table begins here ...
_AISLE_X = -0.22  # m: ... and carries across it pass this far back
_SWING = 0.3  # rad: the door target leads the door by this much while swinging it


def _check_env(env: Any, owner: str) -> KitchenEnv:
    if not isinstance(env, KitchenEnv):
        raise TypeError(f"{owner}: `env` must be a KitchenEnv, got {type(env).__name__}")
    return env


def _yaw(rot: np.ndarray) -> float:
    """The yaw of an eef orientation made by :func:`rotation` (the fingers' opening axis about the vertical)."""
    return float(np.arctan2(-rot[0, 0], rot[1, 0]))


def _steer(env: KitchenEnv, yaw: float, pitch: float, turn: int) -> np.ndarray:
    """An orientation target toward ``rotation(yaw, pitch)``, turning the wrist at most 0.5 rad ahead of it.

    The fingers are symmetric, so ``yaw`` and ``yaw + pi`` grip alike; ``turn``
    (+1 / -1) says which way a turn of about a half circle goes. The door skills
    grip with ``yaw = pi - door angle`` and the bowl skills with ``yaw = 0``,
    and the expert turns between them so the last wrist joint stays inside its
    limits (turning the wrist to a larger yaw lowers that joint).
    """
    now = _yaw(env.eef_rotation)
    low = -np.pi / 2 if turn > 0 else -3 * np.pi / 2
    err = (yaw - now - low) % (2 * np.pi) + low
    return rotation(yaw=now + float(np.clip(err, -0.5, 0.5)), pitch=pitch)


def _aligned(env: KitchenEnv, yaw: float, pitch: float, tol: float = 0.08) -> bool:
    """The eef orientation is within ``tol`` (rad) of ``rotation(yaw, pitch)``."""
    rel = rotation(yaw=yaw, pitch=pitch) @ env.eef_rotation.T
    return bool(np.arccos(np.clip((np.trace(rel) - 1.0) / 2.0, -1.0, 1.0)) < tol)


def _radial(env: KitchenEnv, point: np.ndarray) -> float:
    """The yaw of the direction from the robot's base to ``point``: the arm's natural wrist yaw for a bowl skill."""
    d = np.asarray(point) - env.base_pos
    return float(np.arctan2(d[1], d[0]))


def _via(here: np.ndarray, there: np.ndarray) -> np.ndarray:
    """The next carry waypoint from ``here`` to ``there``: around the microwave's front corner, not through it.

    A carry that crosses the microwave's side of the table (y above
    :data:`_SIDE_Y`) goes back to x = :data:`_AISLE_X`, along y there, then on.
    """
    if abs(there[1] - here[1]) < 0.1 or max(here[1], there[1]) < _SIDE_Y:
        return there
    if here[0] > _AISLE_X + 0.02 and abs(here[1] - there[1]) >= 0.1:
        return np.array([_AISLE_X, here[1], there[2]])
    return np.array([_AISLE_X, there[1], there[2]])


def _rz(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class KitchenSkills:
    """Closed-loop skills; call :meth:`start` with a skill name, then :meth:`act` until :attr:`done`.

    :meth:`succeeded` says whether the world shows the finished skill's outcome
    (door open / shut, bowl held, bowl in the sink / microwave).
    """

    phase_limit = 160  # control steps one phase may take before the skill gives up
    close_steps = 10
    open_steps = 8

    def __init__(self, env: KitchenEnv) -> None:
        self.env = _check_env(env, type(self).__name__)
        self.skill: str | None = None
        self.source = "table"  # where a pick takes the bowl from
        self.phase = "done"
        self.count = 0
        self.steps = 0
        self._grip0 = np.zeros(3)  # the handle grasp point, door shut (relative to the hinge)
        self._out_z = 0.0

    @property
    def done(self) -> bool:
        """The current skill has finished (or failed, or none was started)."""
        return self.phase in ("done", "failed")

    def start(self, skill: str) -> None:
        """Begin ``skill`` (one of :data:`~steer_envs.envs.robosuite.kitchen.SKILLS`), legal or not in the mode."""
        self.skill = one_of(skill, "skill", SKILLS, owner="KitchenSkills.start")
        self.source = self.env.place
        self.phase, self.count, self.steps = "up", 0, 0

    def _next(self, phase: str) -> None:
        self.phase, self.count = phase, 0

    def _hold(self, gripper: float) -> np.ndarray:
        return np.array([0, 0, 0, 0, 0, 0, gripper], dtype=np.float32)

    def act(self) -> np.ndarray:
        """The action of the current phase (a zero move with the gripper as it was once done)."""
        env = self.env
        if self.skill is None or self.done:
            return self._hold(env._gripper)
        self.steps += 1
        self.count += 1
        if self.count > self.phase_limit:
            self._next("failed")
            return self._hold(env._gripper)
        if self.skill in ("open_door", "close_door"):
            return self._door()
        if self.skill == "pick_bowl":
            return self._pick()
        return self._place()

    # ------------------------------------------------------------------ the door
    def _door(self) -> np.ndarray:
        env = self.env
        angle = env.door_angle
        handle, eef = env.handle_pos, env.state
        opening = self.skill == "open_door"
        rot = _steer(env, np.pi - angle, 0.0, +1)
        if self.phase == "up":
            action, d = pose_action(env, np.array([eef[0], eef[1], max(eef[2], _OVER_DOOR_Z)]), rot, -1)
            if abs(d[2]) < 0.02:
                self._next("over")
        elif self.phase == "over":
            action, d = pose_action(env, np.array([handle[0], handle[1], _OVER_DOOR_Z]), rot, -1)
            if np.linalg.norm(d) < 0.01 and _aligned(env, np.pi - angle, 0.0):
                self._next("down")
        elif self.phase == "down":
            action, d = pose_action(env, handle + np.array([0.0, 0.0, _HANDLE_GRIP]), rot, -1, speed=0.5)
            if np.linalg.norm(d) < 0.005 or (self.count > 40 and np.linalg.norm(d) < 0.012):
                self._next("close")
        elif self.phase == "close":
            action, _ = pose_action(env, handle + np.array([0.0, 0.0, _HANDLE_GRIP]), rot, 1)
            if self.count >= self.close_steps:
                self._grip0 = _rz(angle) @ (eef - env.hinge_pos)
                self._next("swing")
        elif self.phase == "swing":
            goal = OPEN_GOAL if opening else -0.05
            want = min(angle + _SWING, goal) if opening else max(angle - _SWING, goal)
            target = env.hinge_pos + _rz(-want) @ self._grip0
            action, _ = pose_action(env, target, _steer(env, np.pi - want, 0.0, +1), 1, speed=0.6)
            if (opening and angle >= OPEN_GOAL - 0.05) or (not opening and angle < DOOR_SHUT_ANGLE / 2):
                self._next("release")
        elif self.phase == "release":
            action, _ = pose_action(env, eef, rot, -1)
            if self.count >= self.open_steps:
                self._next("retreat")
        elif self.phase == "retreat":
            action, d = pose_action(env, np.array([eef[0], eef[1], _OVER_DOOR_Z]), rot, -1)
            if abs(d[2]) < 0.02:
                self._next("clear")
        else:  # clear: back in front of the door
            action, d = pose_action(env, _CLEAR, rot, -1)
            if np.linalg.norm(d) < 0.03:
                self._next("done")
        return action

    # ------------------------------------------------------------------ the bowl
    def _pick(self) -> np.ndarray:
        env = self.env
        eef, bowl = env.state, env.bowl_pos
        grasp = bowl + np.array([0.0, 0.0, 0.005])
        inside = self.source == "microwave"
        pitch = PITCH if inside and self.phase in ("front", "down", "close", "out") else 0.0
        yaw = 0.0 if inside else _radial(env, grasp)
        rot = _steer(env, yaw, pitch, -1)
        if self.phase == "up":
            action, d = pose_action(env, np.array([eef[0], eef[1], max(eef[2], _CARRY_Z)]), rot, -1)
            if abs(d[2]) < 0.02:
                self._next("over")
        elif self.phase == "over":
            pre = np.array([_STAGE_X, grasp[1], _CARRY_Z]) if inside else grasp + np.array([0.0, 0.0, 0.1])
            action, d = pose_action(env, pre, rot, -1)
            if np.linalg.norm(d) < 0.01 and _aligned(env, yaw, 0.0):
                self._next("front" if inside else "down")
        elif self.phase == "front":  # the microwave: down in front of the opening, the fingertips tilted in
            action, d = pose_action(env, np.array([_STAGE_X, grasp[1], grasp[2]]), rot, -1)
            if np.linalg.norm(d) < 0.01 and _aligned(env, yaw, PITCH):
                self._next("down")
        elif self.phase == "down":
            action, d = pose_action(env, grasp, rot, -1, speed=0.5)
            if np.linalg.norm(d) < 0.006 or (self.count > 40 and np.linalg.norm(d) < 0.015):
                self._next("close")
        elif self.phase == "close":
            action, _ = pose_action(env, eef, rot, 1)
            if self.count >= self.close_steps:
                self._out_z = eef[2] + 0.02
                self._next("lift" if not inside else "out")
        elif self.phase == "out":  # back out of the microwave, a little raised
            action, d = pose_action(env, np.array([_STAGE_X, eef[1], self._out_z]), rot, 1, speed=0.5)
            if abs(d[0]) < 0.015:
                self._next("lift")
        else:  # lift
            action, d = pose_action(env, np.array([eef[0], eef[1], _CARRY_Z]), rot, 1)
            if abs(d[2]) < 0.02:
                self._next("done")
        return action

    def _place(self) -> np.ndarray:
        env = self.env
        eef, bowl = env.state, env.bowl_pos
        offset = bowl - eef  # the held bowl's centre relative to the eef, now
        into_sink = self.skill == "place_in_sink"
        if into_sink:
            goal = np.array([SINK_XY[0], SINK_XY[1], env.sink_floor_z + BOWL_HEIGHT / 2 + 0.006])
        else:
            mid_y = float((CAVITY_LOW[1] + CAVITY_HIGH[1]) / 2)
            goal = np.array([_PLACE_IN_X, mid_y, CAVITY_LOW[2] + BOWL_HEIGHT / 2 + 0.006])
        pitch = 0.0 if into_sink or self.phase in ("up", "over", "retreat") else PITCH
        yaw = _radial(env, goal) if into_sink else 0.0
        rot = _steer(env, yaw, pitch, -1)
        level = goal[2] + 0.012  # the bowl slides into the microwave this high

        def toward(centre: np.ndarray, gripper: float = 1, speed: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
            """The action moving the bowl's centre toward ``centre``, and the bowl's remaining offset from it."""
            act, _ = pose_action(env, centre - offset, rot, gripper, speed=speed)
            return act, centre - bowl

        if self.phase == "up":
            action, d = pose_action(env, np.array([eef[0], eef[1], max(eef[2], _CARRY_Z)]), rot, 1)
            if abs(d[2]) < 0.02:
                self._next("over")
        elif self.phase == "over":
            x = goal[0] if into_sink else _STAGE_X
            dest = np.array([x, goal[1], _CARRY_Z])
            action, d = toward(_via(bowl, dest), speed=0.6)
            if np.linalg.norm((dest - bowl)[:2]) < 0.01:
                self._next("down" if into_sink else "tilt")
        elif self.phase == "tilt":  # the microwave: tilt the fingertips toward it before going down
            action, d = toward(np.array([_STAGE_X, goal[1], _CARRY_Z]), speed=0.3)
            if _aligned(env, yaw, PITCH):
                self._next("front")
        elif self.phase == "front":  # the microwave: down in front of the opening, the bowl just above the floor
            action, d = toward(np.array([_STAGE_X, goal[1], level]), speed=0.6)
            if np.linalg.norm(d) < 0.008:
                self._next("in")
        elif self.phase == "in":
            action, d = toward(np.array([goal[0], goal[1], level]), speed=0.4)
            if np.linalg.norm(d[:2]) < 0.008:
                self._next("down")
        elif self.phase == "down":
            action, d = toward(goal, speed=0.3 if bowl[2] - goal[2] < 0.04 else 0.8)
            if bowl[2] - goal[2] < 0.004 or self.count > 80:
                self._next("open")
        elif self.phase == "open":
            action, _ = pose_action(env, eef, rot, -1)
            if self.count >= self.open_steps:
                self._out_z = eef[2] + 0.01
                self._next("retreat" if into_sink else "out")
        elif self.phase == "out":
            action, d = pose_action(env, np.array([_STAGE_X, eef[1], self._out_z]), rot, -1, speed=0.5)
            if abs(d[0]) < 0.015:
                self._next("retreat")
        else:  # retreat
            action, d = pose_action(env, np.array([eef[0] - 0.03, eef[1], _CARRY_Z]), rot, -1)
            if abs(d[2]) < 0.02:
                self._next("done")
        return action

    def succeeded(self) -> bool:
        """Whether the world shows the finished skill's outcome."""
        if self.skill is None or self.phase != "done":
            return False
        env = self.env
        if self.skill == "open_door":
            return env.door_angle > DOOR_OPEN_ANGLE and not env.held
        if self.skill == "close_door":
            return env.door_angle < DOOR_SHUT_ANGLE and not env.held
        if self.skill == "pick_bowl":
            return env.held
        return env.place == ("sink" if self.skill == "place_in_sink" else "microwave")


class KitchenPlanner:
    """The next skill on a shortest legal skill sequence from the env's mode to its task's goal (seeded).

    The sequence is drawn once (uniformly among the shortest ones) and followed;
    when the mode leaves it, a new one is drawn from there.
    """

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(integer(seed, "seed", low=0, owner="KitchenPlanner"))
        self.plan: list[str] = []  # modes, the current one first

    def next_skill(self, env: KitchenEnv) -> str | None:
        """The skill toward the goal from ``env``'s current mode; None at a goal or where no legal sequence leads."""
        env = _check_env(env, "KitchenPlanner.next_skill")
        task = env.task
        mode = task.modes[env._mode]
        if mode in task.goal:
            return None
        if not self.plan or self.plan[0] != mode:
            paths: list[list[str]] = []
            for goal in task.goal:
                try:
                    paths.extend(nx.all_shortest_paths(task.graph(), mode, goal))
                except nx.NetworkXNoPath:
                    continue
            if not paths:
                return None
            shortest = min(len(p) for p in paths)
            paths = sorted(p for p in paths if len(p) == shortest)
            self.plan = list(paths[int(self.rng.integers(len(paths)))])
        nxt = self.plan[1]
        self.plan = self.plan[1:]
        return next(s for s in legal_skills(mode) if skill_target(mode, s) == nxt)


class KitchenExpert:
    """The registry's scripted expert: the planner's skills run one after another.

    Args:
        env: the unwrapped :class:`KitchenEnv`.
        seed: seeds the planner (which of equally short sequences); the same seed replays.

    ``history`` lists ``(skill, succeeded, steps, violated)`` of every finished skill
    (``violated``: some step of it reported ``constraint_violation``).
    """

    def __init__(self, env: KitchenEnv, *, seed: int = 0) -> None:
        self.env = _check_env(env, "KitchenExpert")
        self.seed = integer(seed, "seed", low=0, owner="KitchenExpert")
        self.skills = KitchenSkills(env)
        self.planner = KitchenPlanner(self.seed)
        self.history: list[tuple[str, bool, int, bool]] = []
        self._violated = False

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Start over (the planner reseeded) after ``env.reset``."""
        self.skills = KitchenSkills(self.env)
        self.planner = KitchenPlanner(self.seed)
        self.history = []
        self._violated = False

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for the current sim state; a finished skill is logged and the next one planned."""
        sk = self.skills
        self._violated |= bool(info.get("constraint_violation", False))
        if sk.skill is not None and sk.done:
            self.history.append((sk.skill, sk.succeeded(), sk.steps, self._violated))
            sk.skill = None
        if sk.skill is None:
            self._violated = False
            nxt = self.planner.next_skill(self.env)
            if nxt is None:
                return sk.act()
            sk.start(nxt)
        return sk.act()
