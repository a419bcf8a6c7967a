"""``ArmScoopEnv``: TLI's soup-scooping task on a Panda arm (robosuite, MuJoCo), in the thesis's (y, z, pitch).

Thesis appendix "Robot Experiment 1: Soup-Scooping": a spoon scoops beads from
one bowl and carries them to another; sensors ``r`` (the spoon is in the soup),
``s`` (beads on the spoon), ``t`` (the beads arrived above the target bowl) give
the modes ``a`` reach, ``b`` scoop, ``c`` transport, ``d`` done of
:data:`~steer_envs.envs.soup_scoop.SOUP_TASK` (same names, sensors and
transitions as ``SoupScoop-v0``). robosuite is imported when an env is made.

**Scene.** robosuite's table arena and a Panda; two bowls on the table along
the world ``y`` axis at ``x = BOWL_X`` (visual geoms: the spoon passes through
the soup, nothing collides but the arm and the table). The *spoon* is the
closed gripper: its tool point is the end-effector site, its *pitch* the
rotation of the hand about the world ``x`` axis from pointing straight down
(``pitch > 0`` tips the spoon toward the target bowl).

**State** (``env.unwrapped.state`` = the observation, float ``(3,)``): ``(y, z,
pitch)`` of the spoon, metres and radians, the thesis's 3D modulation
coordinates. ``x``, roll and yaw are held by the env's controller.

**Action**: a velocity ``(y', z', pitch')`` (m/s, m/s, rad/s), clipped to
:data:`MAX_VELOCITY`. As on the thesis's robot, the commanded velocity is
integrated into a target pose (kept within :data:`MAX_LAG` of the spoon) that
robosuite's operational-space controller tracks (delta ``OSC_POSE``, 20 Hz).

**The beads** (the "beads on spoon" sensor ``s``; task memory, as the thesis's
wrist camera saw it):

* the spoon picks beads up when it leaves the soup *upward* (through the soup
  surface, inside the bowl) with its pitch in the holding range
  ``[PITCH_LOW, PITCH_HIGH]``; leaving tipped further down (``pitch <
  PITCH_LOW``) lifts it out empty;
* the beads fall off when the pitch leaves the holding range (a *spill*), and
  go back into the soup when the spoon dips into it again;
* the beads are delivered (mode ``d``, ``info["success"]``, the episode ends)
  when the spoon with beads is above the target bowl (within
  :data:`TARGET_RADIUS` of its axis, :data:`TARGET_Z` in height).

``r`` is the spoon's tool point inside the soup (within :data:`BOWL_RADIUS` of
the soup bowl's axis, below the soup surface). Sensors follow the public
automaton's convention: ``d`` reads ``s & t``.

``info["constraint_violation"]``: a spill (beads lost from the spoon by the
policy's own motion); a push (``perturb``) never reports one.

**Pushes**: ``perturb(delta=...)`` / ``perturb(to=...)`` move the spoon's
``(y, z, pitch)`` (clipped to :data:`WORKSPACE`, the env's ``perturb_workspace``):
a few closed-loop OSC steps toward the pushed pose (the beads react on the way),
then the arm joints are set, within their limits, so the spoon is exactly
there. The arm takes nearly all of the box; a clipped pose it cannot take within
its joint limits (the tipped spoon at the box's far ``y`` corners, e.g.
``(-0.38, z, 1.2)``) is refused with a ``ValueError`` naming ``delta`` / ``to``
before anything moves. An unstable simulation raises
:class:`~steer_envs.envs.robosuite.stability.SimulationUnstableError` as in the
other arm envs.

>>> ArmScoopEnv.interaction_kinds
('nudge',)
>>> arm_scoop_task().labels
('reach', 'scoop', 'transport', 'done')
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Unpack

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from steer_envs.core.interaction import InteractionKind
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import real_array
from steer_envs.envs.checks import check_action, check_options, check_seed
from steer_envs.envs.robosuite.adapter import RobosuiteEnv, ViewOptions
from steer_envs.envs.robosuite.ik import IK_TOLERANCE, Residual
from steer_envs.envs.robosuite.table import table_arena
from steer_envs.envs.robosuite.workspace import Workspace
from steer_envs.envs.soup_scoop import SOUP_TASK

__all__ = [
    "BOWL_RADIUS",
    "BOWL_X",
    "MAX_LAG",
    "MAX_VELOCITY",
    "PITCH_HIGH",
    "PITCH_LOW",
    "SOUP_SURFACE",
    "SOUP_Y",
    "START_BOX",
    "TABLE_Z",
    "TARGET_RADIUS",
    "TARGET_Y",
    "TARGET_Z",
    "WORKSPACE",
    "ArmScoopEnv",
    "arm_scoop_task",
    "pitch_rotation",
]

#: height of the table top (m; robosuite's table arena at ``table_offset``).
TABLE_Z = 0.8
#: the bowls' axes lie at this world x (m), along the y axis.
BOWL_X = 0.0
#: y of the soup bowl's and of the target bowl's axis (m).
SOUP_Y = -0.15
TARGET_Y = 0.15
#: radius of the soup (the "in the soup" sensor's horizontal distance, m).
BOWL_RADIUS = 0.06
#: height of the soup surface (m).
SOUP_SURFACE = TABLE_Z + 0.08
#: "above the target": horizontal distance to the target bowl's axis (m) and the height band (m).
TARGET_RADIUS = 0.05
TARGET_Z = (TABLE_Z + 0.08, TABLE_Z + 0.18)
#: the spoon holds beads while its pitch is in ``[PITCH_LOW, PITCH_HIGH]`` (rad).
PITCH_LOW = -0.35
PITCH_HIGH = 0.6
#: the reachable state box ``(low, high)`` of ``(y, z, pitch)``; pushes and the target pose are clipped to it.
WORKSPACE = (np.array([-0.38, TABLE_Z + 0.04, -1.2]), np.array([0.35, TABLE_Z + 0.35, 1.2]))
#: reset states are uniform in this box ``(low, high)`` (beyond the soup bowl, above it, spoon about level).
START_BOX = (np.array([-0.32, TABLE_Z + 0.16, -0.2]), np.array([-0.24, TABLE_Z + 0.24, 0.2]))
#: the commanded velocity is clipped per axis to this (m/s, m/s, rad/s).
MAX_VELOCITY = np.array([0.25, 0.25, 2.5])
#: the integrated target pose stays within this of the spoon, per axis (no wind-up when the arm lags or is held).
MAX_LAG = np.array([0.02, 0.02, 0.2])
#: the hand's orientation at pitch 0: gripper pointing straight down (columns: the eef axes in the world).
HAND_DOWN = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: closed-loop OSC steps of a push before the joints are set exactly.
PUSH_STEPS = 8
_OSC_POS, _OSC_ROT = 0.05, 0.5  # robosuite's delta OSC output scale per unit action (m, rad)
_IK_ITERS = 200
#: extra start joints of the reachability check (radians added to the home joints): the far tipped poses need them.
_SEED_OFFSETS = (
    np.zeros(7),
    np.array([0.0, 0.3, 0.0, 0.5, 0.0, -0.5, 0.0]),
    np.array([0.0, 0.0, 0.0, 0.0, 1.2, 0.0, 0.0]),
    np.array([0.0, 0.0, 0.0, 0.0, -1.2, 0.0, 0.0]),
)
_SOUP_RGBA = "0.75 0.2 0.1 0.6"
_BOWL_RGBA = "0.85 0.85 0.8 1"


@functools.cache
def arm_scoop_task() -> TaskSpec:
    """The TaskSpec: ``SoupScoop-v0``'s modes, sensors and transitions under the name ``ArmScoop``."""
    return dataclasses.replace(SOUP_TASK, name="ArmScoop")


def pitch_rotation(pitch: float) -> np.ndarray:
    """The hand's world orientation (3x3) at ``pitch``: :data:`HAND_DOWN` rotated about world x."""
    c, s = np.cos(pitch), np.sin(pitch)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]) @ HAND_DOWN


def _rotvec(rot: np.ndarray) -> np.ndarray:
    """Axis-angle vector of a rotation matrix (angle < pi)."""
    angle = float(np.arccos(np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0)))
    axis = np.array([rot[2, 1] - rot[1, 2], rot[0, 2] - rot[2, 0], rot[1, 0] - rot[0, 1]])
    if angle < 1e-9:
        return 0.5 * axis
    return axis * (angle / (2.0 * np.sin(angle)))


def _bowl_xml(name: str, y: float, soup: bool) -> Any:
    """A visual bowl (a ring of wall segments on a base; soup inside) at ``(BOWL_X, y)`` on the table."""
    import xml.etree.ElementTree as ET

    body = ET.Element("body", {"name": name, "pos": f"{BOWL_X} {y} {TABLE_Z}"})

    def geom(**attrs: str) -> None:
        ET.SubElement(body, "geom", {"contype": "0", "conaffinity": "0", "group": "1", **attrs})

    radius, height, n = BOWL_RADIUS + 0.01, SOUP_SURFACE - TABLE_Z + 0.01, 16
    geom(type="cylinder", size=f"{radius} 0.004", pos="0 0 0.004", rgba=_BOWL_RGBA)
    for k in range(n):
        a = 2 * np.pi * k / n
        geom(
            type="box", size=f"0.004 {radius * np.pi / n:.4f} {height / 2:.4f}",
            pos=f"{radius * np.cos(a):.4f} {radius * np.sin(a):.4f} {height / 2:.4f}", euler=f"0 0 {a:.4f}",
            rgba=_BOWL_RGBA,
        )  # fmt: skip
    if soup:
        depth = SOUP_SURFACE - TABLE_Z
        geom(type="cylinder", size=f"{BOWL_RADIUS} {depth / 2:.4f}", pos=f"0 0 {depth / 2:.4f}", rgba=_SOUP_RGBA)
    return body


@functools.cache
def _robosuite_class() -> type:
    """robosuite's Lift without the cube, with the two bowls (defined on first use: robosuite registers classes)."""
    from robosuite.environments.manipulation.lift import Lift
    from robosuite.models.tasks import ManipulationTask

    class SteerArmScoop(Lift):  # type: ignore[misc]
        """A table, a Panda and two visual bowls; success is judged by :class:`ArmScoopEnv` (the beads)."""

        def _load_model(self) -> None:
            super(Lift, self)._load_model()
            arena = table_arena(self)
            arena.worldbody.append(_bowl_xml("soup_bowl", SOUP_Y, soup=True))
            arena.worldbody.append(_bowl_xml("target_bowl", TARGET_Y, soup=False))
            self.model = ManipulationTask(mujoco_arena=arena, mujoco_robots=[r.robot_model for r in self.robots])

        def _setup_references(self) -> None:
            super(Lift, self)._setup_references()

        def _setup_observables(self) -> Any:
            return super(Lift, self)._setup_observables()

        def _reset_internal(self) -> None:
            super(Lift, self)._reset_internal()

        def step(self, action: Any) -> Any:
            """robosuite's step; a 3-vector is ArmScoop's velocity ``(y', z', pitch')`` as a plain delta OSC command.

            So raw-sim timings on ArmScoop's actions (the smoke suite's) run
            the same physics without the env's target-pose tracking.
            """
            act = np.asarray(action, dtype=np.float64).reshape(-1)
            if act.size == 3:
                dt = 1.0 / self.control_freq
                act = np.array([0.0, act[0] * dt / _OSC_POS, act[1] * dt / _OSC_POS, act[2] * dt / _OSC_ROT, 0, 0, 1])
            return super().step(np.clip(act, -1.0, 1.0))

        def reward(self, action: Any = None) -> float:
            return 0.0

        def _check_success(self) -> bool:
            return False

        def visualize(self, vis_settings: Any) -> None:
            super(Lift, self).visualize(vis_settings=vis_settings)

    return SteerArmScoop


class ArmScoopEnv(RobosuiteEnv):
    """Soup scooping with a Panda in ``(y, z, pitch)``: velocity actions, bead sensors, pushes (see the module).

    Args:
        render_mode, camera, render_size, fast_render: as for
            :class:`~steer_envs.envs.robosuite.adapter.RobosuiteEnv`.
        perturb_exact: set the joints after a push's OSC steps so the spoon is exactly on the
            pushed state (the contract's exact ``perturb(to=x)``).

    Reset options: ``state`` (a start ``(y, z, pitch)``, 3 finite reals; default drawn
    from :data:`START_BOX`). Interactions: ``nudge`` (``perturb``).
    """

    interaction_kinds: tuple[InteractionKind, ...] = ("nudge",)
    _OPTION_KEYS = frozenset({"state"})
    default_camera = "frontview"
    #: control period (s): one env step.
    dt = 1.0 / RobosuiteEnv.control_freq

    def __init__(self, **view: Unpack[ViewOptions]) -> None:
        owner = type(self).__name__
        self._check_view_args(view, owner)
        self.task_name = "arm_scoop"
        self.task = arm_scoop_task()
        self.obs_keys = ()
        self._build_sim(lambda **kwargs: _robosuite_class()(**kwargs), owner)
        self.robosuite_obs = self.rs_env.reset()
        self.observation_space = spaces.Box(-10.0, 10.0, shape=(3,), dtype=np.float32)
        high = MAX_VELOCITY.astype(np.float32)
        self.action_space = spaces.Box(-high, high, dtype=np.float32)
        #: the speed bound of the velocity norm a DS policy should respect (the per-axis bounds' norm).
        self.max_speed = float(np.linalg.norm(MAX_VELOCITY))
        self._gripper = 1.0
        self._reference = np.zeros(3)
        self._begin()

    # ----------------------------------------------------------------- state
    @property
    def eef_pos(self) -> np.ndarray:
        """The tool point's world position (m, a copy)."""
        return np.array(self.rs_env.sim.data.site_xpos[self._eef_site], dtype=np.float64)

    def _hand(self) -> np.ndarray:
        return np.asarray(self.rs_env.sim.data.site_xmat[self._eef_site], dtype=np.float64).reshape(3, 3)

    @property
    def pitch(self) -> float:
        """The spoon's pitch (rad): the hand's rotation about world x from pointing down."""
        rel = self._hand() @ HAND_DOWN.T
        return float(np.arctan2(rel[2, 1], rel[1, 1]))

    @property
    def state(self) -> np.ndarray:
        """``(y, z, pitch)`` of the spoon (m, m, rad; a float64 copy)."""
        p = self.eef_pos
        return np.array([p[1], p[2], self.pitch])

    @property
    def object_pos(self) -> np.ndarray:
        """The soup bowl's centre on the table (the adapter's single-object view)."""
        return np.array([BOWL_X, SOUP_Y, TABLE_Z])

    @property
    def beads_on_spoon(self) -> bool:
        """The ``s`` sensor: beads are on the spoon (task memory)."""
        return self._beads

    @property
    def perturb_workspace(self) -> Workspace:
        """The ``(y, z, pitch)`` box pushes and reset states are clipped to (:data:`WORKSPACE`)."""
        return Workspace(WORKSPACE[0].copy(), WORKSPACE[1].copy(), axes=("y", "z", "pitch"))

    def _obs(self) -> np.ndarray:
        return self.state.astype(np.float32)

    # --------------------------------------------------------------- sensors
    def _in_soup(self) -> bool:
        p = self.eef_pos
        return bool(np.hypot(p[0] - BOWL_X, p[1] - SOUP_Y) <= BOWL_RADIUS and p[2] <= SOUP_SURFACE)

    def _above_target(self) -> bool:
        p = self.eef_pos
        return bool(np.hypot(p[0] - BOWL_X, p[1] - TARGET_Y) <= TARGET_RADIUS and TARGET_Z[0] <= p[2] <= TARGET_Z[1])

    def _begin(self) -> None:
        self._beads = False
        self._delivered = False
        self._spilled = False
        self._was_in_soup = self._in_soup()
        self._reference = self.state
        self._success = False
        self._mode = self.task.mode_index(self.task.mode_of(self._sensors()))

    def _update_beads(self) -> None:
        """Advance the bead memory to the current pose; ``_spilled``: the beads fell off at this reading."""
        self._spilled = False
        in_soup = self._in_soup()
        if self._delivered:
            self._was_in_soup = in_soup
            return
        pitch = self.pitch
        holding = PITCH_LOW <= pitch <= PITCH_HIGH
        if self._beads:
            if in_soup or not holding:
                self._beads = False
                self._spilled = True
        elif self._was_in_soup and not in_soup and holding:
            p = self.eef_pos
            self._beads = bool(p[2] > SOUP_SURFACE and np.hypot(p[0] - BOWL_X, p[1] - SOUP_Y) <= BOWL_RADIUS)
        if self._beads and self._above_target():
            self._delivered = True
        self._was_in_soup = in_soup

    def _sensors(self) -> dict[str, bool]:
        self._success = self._delivered
        return {"r": self._in_soup() and not self._beads, "s": self._beads, "t": self._delivered}

    def _event_violation(self) -> bool:
        return self._spilled

    # --------------------------------------------------------------- control
    def _osc_action(self, target: np.ndarray) -> np.ndarray:
        """The 7-D delta OSC action driving the hand toward ``target`` = (y, z, pitch), x and roll/yaw held."""
        act = np.zeros(7)
        goal = np.array([BOWL_X, target[0], target[1]])
        act[:3] = np.clip((goal - self.eef_pos) / _OSC_POS, -1.0, 1.0)
        act[3:6] = np.clip(_rotvec(pitch_rotation(target[2]) @ self._hand().T) / _OSC_ROT, -1.0, 1.0)
        act[6] = self._gripper
        return act

    def _clip_state(self, x: np.ndarray) -> np.ndarray:
        return np.clip(x, WORKSPACE[0], WORKSPACE[1])

    def _pose_residual(self, target: np.ndarray) -> Residual:
        """The hand's pose error to ``target`` = (y, z, pitch) (position, axis-angle) and its Jacobian over the arm."""
        import mujoco

        model = self.rs_env.sim.model._model
        goal_pos = np.array([BOWL_X, target[0], target[1]])
        goal_rot = pitch_rotation(target[2])
        jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))

        def residual(data: Any) -> tuple[np.ndarray, np.ndarray]:
            hand = np.asarray(data.site_xmat[self._eef_site], dtype=np.float64).reshape(3, 3)
            err = np.concatenate([goal_pos - data.site_xpos[self._eef_site], _rotvec(goal_rot @ hand.T)])
            mujoco.mj_jacSite(model, data, jacp, jacr, self._eef_site)
            return err, np.vstack([jacp, jacr])[:, self._arm_qvel]

        return residual

    def _plan(self, target: np.ndarray, name: str, owner: str) -> np.ndarray:
        """Arm joints putting the spoon at ``target`` within the joint limits; else a ``ValueError`` naming ``name``."""
        home = np.array(self._robot.init_qpos, dtype=np.float64)
        seeds = [home + offset for offset in _SEED_OFFSETS]
        plan = self._ik.plan(self.rs_env.sim.data._data, self._pose_residual(target), seeds, iters=_IK_ITERS)
        if plan is None:
            raise ValueError(
                f"{owner}: `{name}` takes the spoon to (y, z, pitch) = {np.round(target, 4).tolist()}, a pose the arm "
                f"cannot take within its joint limits (workspace: {self.perturb_workspace.describe()})"
            )
        return plan

    def _snap_pose(self, target: np.ndarray, plan: np.ndarray) -> None:
        """Damped least-squares IK on the arm joints (within their limits) until the hand is at ``target``.

        From the current joints; where that solve stalls (at a joint limit), the joints ``plan`` found beforehand.
        """
        import mujoco

        sim = self.rs_env.sim
        model, data = sim.model._model, sim.data._data
        if self._ik.solve(data, self._pose_residual(target), iters=_IK_ITERS, tol=1e-10) >= IK_TOLERANCE:
            data.qpos[self._arm_qpos] = plan
        data.qvel[self._arm_qvel] = 0.0
        mujoco.mj_forward(model, data)

    # ------------------------------------------------------------------- API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode with empty spoon at ``options["state"]`` or a start drawn from ``seed``."""
        owner = f"{type(self).__name__}.reset"
        seed = check_seed(seed, owner)
        opts = check_options(options, self._OPTION_KEYS, owner)
        start = opts.get("state")
        if start is not None:
            start = self._clip_state(real_array(start, "options['state']", shape=(3,), owner=owner))
        gym.Env.reset(self, seed=seed)  # after every check: a refused reset leaves the episode as it was
        if start is None:
            start = self.np_random.uniform(START_BOX[0], START_BOX[1])
        if seed is not None:
            self.rs_env.rng.bit_generator.state = np.random.default_rng(seed).bit_generator.state
        self._unstable = None
        self.robosuite_obs = self.rs_env.reset()
        self._gripper = 1.0
        self._snap_pose(start, self._plan(start, "options['state']", owner))
        self._refresh()
        self._begin()
        return self._obs(), self._info()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One 20 Hz step: integrate the velocity ``(y', z', pitch')`` into the target pose and track it."""
        owner = f"{type(self).__name__}.step"
        v = np.clip(check_action(action, self.action_space, owner), -MAX_VELOCITY, MAX_VELOCITY)
        self._check_stable(owner)
        state = self.state
        ref = self._clip_state(self._reference + self.dt * v.astype(np.float64))
        self._reference = np.clip(ref, state - MAX_LAG, state + MAX_LAG)
        self.robosuite_obs, _, _, _ = self._sim_step(self._osc_action(self._reference), owner)
        self._update_beads()
        info = self._info()
        return self._obs(), float(info["success"]), info["success"], False, info

    def perturb(self, delta: np.ndarray | None = None, *, to: np.ndarray | None = None) -> dict[str, Any]:
        """Push the spoon by ``delta`` (or ``to`` a state), 3 finite reals ``(y, z, pitch)``; see the module."""
        owner = f"{type(self).__name__}.perturb"
        if (delta is None) == (to is None):
            raise ValueError(f"{owner}: pass exactly one of `delta` (displacement) or `to` (target state)")
        if to is None:
            name, target = "delta", self.state + real_array(delta, "delta", shape=(3,), owner=owner)
        else:
            name, target = "to", real_array(to, "to", shape=(3,), owner=owner)
        self._check_stable(owner)
        target = self._clip_state(target)
        plan = self._plan(target, name, owner)
        for _ in range(PUSH_STEPS):
            if np.all(np.abs(target - self.state) <= np.array([0.003, 0.003, 0.02])):
                break
            self._sim_step(self._osc_action(target), owner)
            self._update_beads()
        if self.perturb_exact:
            self._snap_pose(target, plan)
        self._refresh()
        self._update_beads()
        self._reference = self.state
        return self._info(perturbed=True)
