"""``RobosuiteEnv``: one robosuite task (Panda, delta OSC_POSE) as a steer-envs env.

robosuite is imported when an env is made, never by ``import steer_envs``; it is
the ``arm`` extra (``pip install "steer-envs[arm]"``), and making an arm env
without it raises :class:`~steer_envs.core.extras.MissingExtraError` (an
``ImportError``) that says so.
The sim is robosuite's own (``env.unwrapped.rs_env``); its observation dict
stays available under robosuite's names (``env.unwrapped.robosuite_obs``).

Observation (flat ``float32`` Box, keys in :attr:`RobosuiteEnv.obs_keys`):
``robot0_eef_pos`` (3), ``robot0_eef_quat`` (4, xyzw), ``robot0_gripper_qpos``
(2), then the task's object state (``<object>_pos`` (3), ``<object>_quat`` (4),
the object-to-gripper vector (3)): 19 numbers.
Action: 7 reals in [-1, 1] (clipped): delta eef position / axis-angle (scaled
by robosuite to +-0.05 m, +-0.5 rad per step) and the gripper (+1 closes).
Reward: 1 on success (robosuite's sparse reward; for the public-code Lift,
``variant="public_code"``, its own 0.40 m success), which also terminates the
episode; the step limit is the registry's TimeLimit (robosuite's own
``horizon`` is off: ``ignore_done=True``).

Pushes (``perturb``) stay inside the arm's workspace (``perturb_workspace``,
:mod:`steer_envs.envs.robosuite.workspace`): a target outside it, or one the arm
cannot take within its joint limits, is refused with a ``ValueError`` naming the
argument, before the sim moves. An unstable simulation (MuJoCo's NaN/Inf
warnings, after which MuJoCo resets the sim) raises
:class:`~steer_envs.envs.robosuite.stability.SimulationUnstableError` from
``step`` or ``perturb``, and the env refuses both until ``reset``.

Cameras: ``render`` gives RGB frames, :meth:`RobosuiteEnv.render_rgbd` RGB and a
metric depth map from any camera of the model; :meth:`RobosuiteEnv.world_to_pixel`
and :meth:`RobosuiteEnv.pixel_to_world` map between world points and pixels of
those frames (conventions in :mod:`steer_envs.envs.robosuite.camera`).
"""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Callable, Iterator
from types import ModuleType
from typing import Any, ClassVar, TypedDict, Unpack

import numpy as np
from gymnasium import spaces

from steer_envs.core.env import ClosableEnv
from steer_envs.core.extras import require
from steer_envs.core.interaction import InteractionKind
from steer_envs.core.validation import boolean, describe, integer, one_of, real_array, real_scalar
from steer_envs.envs.checks import check_action, check_options, check_render_mode, check_seed
from steer_envs.envs.robosuite import camera as cam
from steer_envs.envs.robosuite.gl_backend import ensure_gl_backend
from steer_envs.envs.robosuite.ik import IK_TOLERANCE, ArmIK, Residual
from steer_envs.envs.robosuite.stability import SimulationUnstableError, StepWatch
from steer_envs.envs.robosuite.tasks import FALL_SPEED, SQUARE_LOW_HEIGHT, TASK_NAMES, VARIANTS, task_spec
from steer_envs.envs.robosuite.workspace import Workspace, arm_workspace

__all__ = [
    "ARM_FEATURE",
    "GRASP_HOLD_STEPS",
    "PERTURB_MAX_STEPS",
    "PERTURB_TOLERANCE",
    "ROBOT_KEYS",
    "RobosuiteEnv",
    "ViewOptions",
    "require_robosuite",
]

#: what needs the ``arm`` extra (robosuite), as the missing-extra message names it.
ARM_FEATURE = "the robosuite arm envs (Lift, Can, Square, BlockStack, ArmScoop, Kitchen)"

#: robot observation keys, in observation order (the task's object keys follow).
ROBOT_KEYS = ("robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos")
#: ``perturb`` drives the arm with closed-loop OSC steps until the eef is this close to the target (m) ...
PERTURB_TOLERANCE = 0.005
#: ... or for at most this many control steps (0.05 s each).
PERTURB_MAX_STEPS = 40
_REST_MARGIN = 0.01  # m above the rest height that count as "in the air" (held latch, Lift's `lifted`)
#: the object is at rest below this speed (m/s); only such readings, untouched by the robot, set the rest height.
_REST_SPEED = 0.01
#: the held latch sets once a grasp has lasted this many control steps (a one-step touch of both pads
#: while the fingers close on an object resting on the table is no grasp); 1 sets it at the first touch.
GRASP_HOLD_STEPS = 2
_SNAP_ITERS = 100
_PLAN_ITERS = 200  # updates per start of the reachability check before a push
_RAISED = np.array([0.0, -0.2, 0.0, 1.1, 0.0, -1.4, 0.0])  # added to the home joints: a start with the elbow up
#: bound of every observation entry (positions in m lie within ~2 m of the origin; quats, gripper qpos within 1).
OBS_BOUND = 10.0


def require_robosuite() -> ModuleType:
    """The ``robosuite`` module; without it an ``ImportError`` naming ``pip install "steer-envs[arm]"``.

    Every arm env calls it before it builds its sim, so ``gymnasium.make("steer_envs/Lift-v0")``
    without robosuite fails with that message rather than deep inside. It first picks an
    offscreen GL backend that works here when ``MUJOCO_GL`` is unset (:func:`ensure_gl_backend`).
    """
    if "robosuite" not in sys.modules:  # robosuite reads MUJOCO_GL once, at its import
        ensure_gl_backend()
    with _quiet_robosuite():
        return require("robosuite", "arm", ARM_FEATURE)


@contextlib.contextmanager
def _quiet_robosuite() -> Iterator[None]:
    """Silence robosuite's import-time and make-time warnings (missing macros, optional robot packages)."""
    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)
    try:
        yield
    finally:
        logging.disable(previous)
        logging.getLogger("robosuite_logs").setLevel(logging.ERROR)


class ViewOptions(TypedDict, total=False):
    """The rendering and perturbation options every robosuite env takes by keyword (their defaults in brackets).

    ``render_mode`` (None) or ``"rgb_array"``; ``camera`` the camera ``render``
    draws (the env's :attr:`~RobosuiteEnv.default_camera`); ``render_size``
    (256) its side in pixels; ``perturb_exact`` (True) set the joints after a
    push so the state is exactly the pushed one; ``fast_render`` (False) the
    offscreen renderer without robosuite's per-frame overhead.
    """

    render_mode: str | None
    camera: str
    render_size: int
    perturb_exact: bool
    fast_render: bool


class RobosuiteEnv(ClosableEnv[np.ndarray, np.ndarray]):
    """A robosuite task (``"lift"``, ``"can"``, ``"square"``) with ground-truth modes and perturbations.

    Args:
        task: the task name, one of :data:`steer_envs.envs.robosuite.tasks.TASK_NAMES`.
        variant: which version of the task (:data:`steer_envs.envs.robosuite.tasks.VARIANTS`):
            ``"thesis"`` (default; robosuite's task as the thesis text describes it) or, for Lift,
            ``"public_code"`` (the public GLiDE fork's Lift: success at 0.40 m above the table,
            modes free / lifting / success; reward 1 and termination at that success).
        render_mode: ``"rgb_array"`` (an offscreen renderer is built) or None (no renderer).
            The arm envs are ``rgb_array``-only: ``"human"`` is refused here (a ``ValueError``);
            ``gymnasium.make(..., render_mode="human")`` wraps them in Gymnasium's ``HumanRendering``.
        camera: robosuite camera rendered by ``render`` and the default camera of the RGB-D and
            pixel methods (e.g. ``"agentview"``, ``"frontview"``; :attr:`camera_names` lists the model's).
        render_size: rendered frames are ``render_size x render_size`` pixels, an int in [16, 2048]
            (the library's convention).
        perturb_exact: after the OSC steps of ``perturb``, set the arm joints kinematically
            (damped least squares) so the eef lands on the target to 1e-7 m (the contract's exact
            ``perturb(to=x)``); False leaves the eef where the OSC steps brought it
            (within :data:`PERTURB_TOLERANCE`, unless blocked).

        fast_render: with ``render_mode="rgb_array"``, render without multisampling,
            reflections and skybox (robosuite's defaults are slow on a CPU renderer such as
            OSMesa); False keeps robosuite's look. It applies to ``render`` and
            :meth:`render_rgbd` alike (the depth buffer is rebuilt with the colour buffer).

    Frames are flipped to the image convention (row 0 at the top). The model is
    built with robosuite's seed 0, so every instance is the same model (Lift's
    cube size, drawn at construction, is the same everywhere) and a reset seed
    replays across instances.

    Pushes: :meth:`perturb` takes targets inside :attr:`perturb_workspace` only (a
    ``ValueError`` naming ``delta`` / ``to`` and the bounds otherwise) and sets the
    joints within their limits; a simulation MuJoCo found unstable raises
    :class:`~steer_envs.envs.robosuite.stability.SimulationUnstableError`.

    ``info``: ``mode`` / ``mode_name`` (ground truth, see :mod:`steer_envs.envs.robosuite.tasks`),
    ``sensors``, ``success`` (robosuite's ``_check_success``; ``is_success`` the same, for
    stable-baselines3), ``constraint_violation``
    (a mode change the task does not allow, e.g. the object dropped after being
    grasped), ``perturbed``.

    >>> RobosuiteEnv.interaction_kinds
    ('point', 'sketch', 'nudge')
    """

    #: also refused after close(): the RGB-D render
    closed_calls: ClassVar[tuple[str, ...]] = (*ClosableEnv.closed_calls, "render_rgbd")

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 20}  # noqa: RUF012 - Env's type
    interaction_kinds: tuple[InteractionKind, ...] = ("point", "sketch", "nudge")
    control_freq = 20
    #: success is the object this high above the table (m); None: robosuite's ``_check_success``
    _success_height: float | None = None
    #: the camera ``render`` draws when ``camera`` is not given
    default_camera = "agentview"
    _OPTION_KEYS = frozenset({"state"})

    def __init__(
        self,
        task: str = "lift",
        *,
        variant: str = "thesis",
        **view: Unpack[ViewOptions],
    ) -> None:
        owner = type(self).__name__
        self.task_name = one_of(task, "task", TASK_NAMES, owner=owner)
        #: the task's variant (``"thesis"``, or Lift's ``"public_code"``)
        self.variant = one_of(variant, "variant", tuple(VARIANTS[self.task_name]), owner=owner)
        self._check_view_args(view, owner)
        self.spec_task = VARIANTS[self.task_name][self.variant]
        self._success_height = self.spec_task.success_height
        self.task = task_spec(self.spec_task)
        self.obs_keys: tuple[str, ...] = ROBOT_KEYS + self.spec_task.object_keys

        def make(**kwargs: Any) -> Any:
            import robosuite as suite

            return suite.make(self.spec_task.env_name, **kwargs)

        self._build_sim(make, owner)
        rs = self.rs_env
        if self.task_name == "lift":
            self._object = rs.cube
        elif self.task_name == "can":
            self._object = rs.objects[rs.object_id]
        else:
            self._object = rs.nuts[rs.nut_id]
        self._object_geoms, self._pad_geoms = self._grasp_masks()
        self._robot_geoms = self._robot_mask()
        self._object_qvel = int(rs.sim.model.get_joint_qvel_addr(self._object.joints[0])[0])
        self._reset_spaces()
        self._held = False
        self._grasp_start: float | None = None  # sim time of the first reading of the current grasp
        self._rest_z = 0.0
        self._mode = 0
        self._gripper = -1.0
        self._success = False
        self._begin()

    def _reset_spaces(self) -> None:
        """Reset the sim for its first observation; the observation box of ``obs_keys`` and the 7-D action box."""
        self.robosuite_obs: dict[str, np.ndarray] = self.rs_env.reset()
        dim = sum(int(np.asarray(self.robosuite_obs[k]).size) for k in self.obs_keys)
        self.observation_space = spaces.Box(-OBS_BOUND, OBS_BOUND, shape=(dim,), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(7,), dtype=np.float32)

    def _check_view_args(self, view: ViewOptions, owner: str) -> None:
        """Validate and keep the :class:`ViewOptions` every robosuite env takes."""
        unknown = sorted(set(view) - set(ViewOptions.__annotations__))
        if unknown:
            raise TypeError(f"{owner}: unexpected keyword argument(s) {unknown}")
        self.render_mode = check_render_mode(view.get("render_mode"), self.metadata["render_modes"], owner)
        camera = view.get("camera", self.default_camera)
        if not isinstance(camera, str):
            raise TypeError(f"{owner}: `camera` must be a str, got {type(camera).__name__}")
        self.render_size = integer(view.get("render_size", 256), "render_size", low=16, high=2048, owner=owner)
        self.perturb_exact = boolean(view.get("perturb_exact", True), "perturb_exact", owner=owner)
        self.fast_render = boolean(view.get("fast_render", False), "fast_render", owner=owner)
        self.camera = camera

    def _build_sim(self, make: Callable[..., Any], owner: str) -> None:
        """``self.rs_env = make(**settings)`` with the Panda, delta OSC and our settings; cameras, robot handles.

        A fixed construction seed: robosuite draws parts of the model from its
        ``rng`` when it builds it (e.g. Lift's cube size), so every instance is
        the same model and episode seeds replay.
        """
        require_robosuite()
        with _quiet_robosuite():
            from robosuite.controllers import load_composite_controller_config

            cfg = load_composite_controller_config(controller="BASIC", robot="Panda")
            self.rs_env: Any = make(
                robots="Panda",
                controller_configs=cfg,
                control_freq=self.control_freq,
                has_renderer=False,
                has_offscreen_renderer=self.render_mode is not None,
                use_camera_obs=False,
                hard_reset=False,
                horizon=10**9,
                ignore_done=True,
                seed=0,
            )
        rs = self.rs_env
        #: the model's cameras (``render`` uses ``camera``; the RGB-D and pixel methods take any of these)
        self.camera_names: tuple[str, ...] = tuple(rs.sim.model.camera_names)
        try:
            self._camera(self.camera, owner)
        except ValueError:
            rs.close()  # the renderer, if one was built
            raise
        if self.render_mode is not None and self.fast_render:
            self._fast_render()
        self._robot = rs.robots[0]
        self._eef_site = int(self._robot.eef_site_id["right"])
        self._arm_qpos = np.asarray(self._robot._ref_joint_pos_indexes, dtype=int)
        self._arm_qvel = np.asarray(self._robot._ref_joint_vel_indexes, dtype=int)
        self._arm_joints = np.asarray(self._robot._ref_joint_indexes, dtype=int)
        self._ik = ArmIK(rs.sim.model._model, self._arm_joints, self._arm_qpos)
        self._workspace: Workspace | None = None
        self._unstable: str | None = None  # why the sim went unstable, until the next reset

    # ----------------------------------------------------------------- state
    @property
    def state(self) -> np.ndarray:
        """The end effector's position in the world frame (m, a float64 copy)."""
        return np.array(self.rs_env.sim.data.site_xpos[self._eef_site], dtype=np.float64)

    @property
    def perturb_workspace(self) -> Workspace:
        """Where :meth:`perturb` may take the end effector (world frame, m; :func:`~.workspace.arm_workspace`).

        Within the arm's reach of its shoulder, above the table's top, clear of
        the robot's own column; ``perturb_workspace.describe()`` states it.
        """
        if self._workspace is None:
            sim = self.rs_env.sim
            model, data = sim.model._model, sim.data._data
            base = np.array(data.xpos[model.body("robot0_base").id], dtype=np.float64)
            shoulder = np.array(data.xanchor[self._arm_joints[1]], dtype=np.float64)
            self._workspace = arm_workspace(base, shoulder, self._support_top())
        return self._workspace

    def _support_top(self) -> float:
        """Height (m) of the surface the objects rest on: the table's top (robosuite's bins: their floors' tops)."""
        import mujoco

        sim = self.rs_env.sim
        model, data = sim.model._model, sim.data._data
        best: tuple[float, float] | None = None  # (area, top) of the widest candidate box
        for g in range(model.ngeom):
            body = model.body(model.geom_bodyid[g]).name
            if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_BOX or not model.geom_contype[g]:
                continue
            if model.geom(g).name != "table_collision" and body not in ("bin1", "bin2"):
                continue
            size = model.geom_size[g]
            area, top = float(size[0] * size[1]), float(data.geom_xpos[g][2] + size[2])
            if best is None or area > best[0] or (area == best[0] and top > best[1]):
                best = (area, top)
        if best is None:  # pragma: no cover - every arm scene has a table or bins
            raise RuntimeError(f"{type(self).__name__}: no table in the scene to bound the pushes")
        return best[1]

    @property
    def object_pos(self) -> np.ndarray:
        """The task object's position (cube, can, nut centre; a copy)."""
        return np.array(self.robosuite_obs[f"{self.spec_task.object_prefix}_pos"], dtype=np.float64)

    def _obs(self) -> np.ndarray:
        return np.concatenate([np.ravel(self.robosuite_obs[k]) for k in self.obs_keys]).astype(np.float32)

    def _refresh(self) -> None:
        self.robosuite_obs = self.rs_env._get_observations(force_update=True)

    def _begin(self) -> None:
        self._held = False
        self._grasp_start = None
        self._rest_z = float(self.object_pos[2])
        self._gripper = -1.0
        self._mode = self.task.mode_index(self.task.mode_of(self._sensors()))

    # --------------------------------------------------------------- sensors
    def _grasp_masks(self) -> tuple[np.ndarray, tuple[tuple[np.ndarray, ...], ...]]:
        """Geom-id masks of the object's contact geoms and of each arm's finger-pad groups (see :meth:`_grasped`)."""
        model = self.rs_env.sim.model

        def mask(names: Any) -> np.ndarray:
            names = [names] if isinstance(names, str) else list(names)
            out = np.zeros(model.ngeom, dtype=bool)
            for i in range(model.ngeom):
                out[i] = model.geom_id2name(i) in names
            return out

        pads = tuple(
            (mask(g.important_geoms["left_fingerpad"]), mask(g.important_geoms["right_fingerpad"]))
            for g in self._robot.gripper.values()
        )
        return mask(self._object.contact_geoms), pads

    def _robot_mask(self) -> np.ndarray:
        """Geom-id mask of every contact geom of the arm and its grippers."""
        model = self.rs_env.sim.model
        names = set(self._robot.robot_model.contact_geoms)
        for gripper in self._robot.gripper.values():
            names.update(gripper.contact_geoms)
        return np.array([model.geom_id2name(i) in names for i in range(model.ngeom)], dtype=bool)

    def _robot_touches_object(self) -> bool:
        """Some geom of the arm or a gripper touches the task object."""
        contact = self.rs_env.sim.data._data.contact
        g1, g2 = contact.geom1, contact.geom2
        obj, robot = self._object_geoms, self._robot_geoms
        return bool(np.any((obj[g1] & robot[g2]) | (robot[g1] & obj[g2])))

    def _at_rest(self) -> bool:
        """The object is still and untouched by the robot: its height there is a rest height.

        A finger pressing the object into the table, or the bottom of the
        bounce when a freshly spawned object lands, is not one.
        """
        speed = np.linalg.norm(self.rs_env.sim.data.qvel[self._object_qvel : self._object_qvel + 3])
        return bool(speed < _REST_SPEED) and not self._robot_touches_object()

    def _grasped(self) -> bool:
        """robosuite's ``_check_grasp(gripper, object)``, by geom ids over the contact arrays.

        Grasped: for some arm, each finger-pad group touches one of the object's
        contact geoms. robosuite's own check looks every contact's geom names up
        in Python lists, several times per contact; the masks give the same
        answer without the names.
        """
        contact = self.rs_env.sim.data._data.contact
        g1, g2 = contact.geom1, contact.geom2
        if g1.size == 0:
            return False
        obj1, obj2 = self._object_geoms[g1], self._object_geoms[g2]
        return any(all(bool(np.any((pad[g1] & obj2) | (obj1 & pad[g2]))) for pad in pads) for pads in self._pad_geoms)

    def _sensors(self) -> dict[str, bool]:
        rs = self.rs_env
        pos = self.object_pos
        grasped = self._grasped()
        in_air = pos[2] > self._rest_z + _REST_MARGIN
        # control steps the grasp has lasted, from sim time (a second reading in the same step counts once)
        now = float(rs.sim.data.time)
        self._grasp_start = (now if self._grasp_start is None else self._grasp_start) if grasped else None
        lasted = 0 if self._grasp_start is None else round((now - self._grasp_start) * self.control_freq) + 1
        self._held = lasted >= GRASP_HOLD_STEPS or (self._held and (grasped or in_air))
        if not self._held and self._at_rest():
            self._rest_z = min(self._rest_z, float(pos[2]))
        self._success = bool(rs._check_success()) if self._success_height is None else self._above_table()
        sensors = {"held": self._held}
        if self.task_name == "lift" and self._success_height is not None:
            vz = float(rs.sim.data.qvel[self._object_qvel + 2])  # a free joint's linear velocity is in the world frame
            sensors["falling"] = vz < -FALL_SPEED
            sensors["at_height"] = self._success
        elif self.task_name == "lift":
            sensors["lifted"] = bool(in_air)
            sensors["at_height"] = self._success
        elif self.task_name == "can":
            obj_id = rs.object_to_id["can"]
            target = np.asarray(rs.target_bin_placements[obj_id])
            sensors["above_target"] = bool(np.all(np.abs(pos[:2] - target[:2]) <= np.asarray(rs.bin_size[:2]) / 4))
            sensors["in_target_bin"] = not bool(rs.not_in_bin(pos, obj_id))
        else:
            peg = np.asarray(rs.sim.data.body_xpos[rs.peg1_body_id])
            sensors["above_peg"] = bool(np.linalg.norm(pos[:2] - peg[:2]) <= 0.03)
            sensors["low"] = bool(pos[2] < self._rest_z + SQUARE_LOW_HEIGHT)
            sensors["on_peg"] = self._success
        return sensors

    def _above_table(self) -> bool:
        """The object's body is more than the variant's success height above the table top (robosuite's rule)."""
        rs = self.rs_env
        body = rs.sim.model.body_name2id(self._object.root_body)
        assert self._success_height is not None
        return bool(rs.sim.data.body_xpos[body][2] > rs.table_offset[2] + self._success_height)

    def _event_violation(self) -> bool:
        """A violation the last sensor reading found besides a forbidden mode change (none here; BlockStack: a drop)."""
        return False

    def _info(self, *, perturbed: bool = False) -> dict[str, Any]:
        sensors = self._sensors()
        name = self.task.mode_of(sensors)
        mode = self.task.mode_index(name)
        bad_change = mode != self._mode and not self.task.is_allowed(self._mode, mode)
        violation = not perturbed and (bad_change or self._event_violation())
        self._mode = mode
        return {
            "mode": mode,
            "mode_name": name,
            "sensors": sensors,
            "success": self._success,
            "is_success": self._success,  # stable-baselines3's name (Monitor, ep_success_buffer)
            "constraint_violation": bool(violation),
            "perturbed": perturbed,
        }

    # ------------------------------------------------------------------- API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: robosuite's placement (and the arm's init noise) drawn from ``seed``.

        ``seed``: None (continue the stream) or an int >= 0; robosuite's samplers
        draw from ``rs_env.rng``, whose state is replaced in place (the samplers
        share the Generator). ``options``: None or a dict with ``state`` (an eef
        start position, 3 finite reals inside :attr:`perturb_workspace`, reached as
        by ``perturb(to=...)``).
        """
        owner = f"{type(self).__name__}.reset"
        seed = check_seed(seed, owner)
        options = check_options(options, self._OPTION_KEYS, owner)
        start = options.get("state")
        if start is not None:
            start = real_array(start, "options['state']", shape=(3,), owner=owner)
            self.perturb_workspace.check(start, "options['state']", owner)
        super().reset(seed=seed)  # after every check: a refused reset leaves the episode as it was
        if seed is not None:
            self.rs_env.rng.bit_generator.state = np.random.default_rng(seed).bit_generator.state
        self._unstable = None
        self.robosuite_obs = self.rs_env.reset()
        self._gripper = -1.0
        if start is not None:
            self._push(start, "options['state']", owner)
        self._begin()
        return self._obs(), self._info()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One 20 Hz control step of the 7-D delta OSC action (clipped to [-1, 1])."""
        owner = f"{type(self).__name__}.step"
        act = np.clip(check_action(action, self.action_space, owner), -1.0, 1.0)
        self._check_stable(owner)
        self._gripper = float(act[6])
        self.robosuite_obs, reward, _, _ = self._sim_step(act, owner)
        info = self._info()
        if self._success_height is not None:  # robosuite's sparse reward is its own success's
            reward = float(info["success"])
        return self._obs(), float(reward), info["success"], False, info

    def _sim_step(self, action: np.ndarray, owner: str) -> Any:
        """robosuite's step of ``action``, checked: a simulation MuJoCo found unstable raises (see the module)."""
        watch = StepWatch.start(self.rs_env.sim.data._data)
        out = self.rs_env.step(action)
        problem = watch.problem()
        if problem is not None:
            self._unstable = problem
            raise SimulationUnstableError(f"{owner}: {problem}; the episode cannot go on: call reset()")
        return out

    def _check_stable(self, owner: str) -> None:
        """Refuse to go on after the simulation went unstable, until ``reset``."""
        if self._unstable is not None:
            raise SimulationUnstableError(
                f"{owner}: the simulation became unstable earlier ({self._unstable}); call reset() first"
            )

    def perturb(self, delta: np.ndarray | None = None, *, to: np.ndarray | None = None) -> dict[str, Any]:
        """Move the end effector by ``delta`` (or ``to`` a position, 3 finite reals, m): a push from outside.

        The target must lie in :attr:`perturb_workspace` and be reachable within the
        arm's joint limits; otherwise a ``ValueError`` naming ``delta`` / ``to`` is
        raised and nothing moves. Closed-loop OSC steps (the gripper command held)
        drive the eef toward the target until it is within
        :data:`PERTURB_TOLERANCE` or for :data:`PERTURB_MAX_STEPS` steps; with
        ``perturb_exact`` the arm joints are then set (within their limits) so the
        eef is on the target (a held object follows on the next steps). Sim time
        advances by the OSC steps; they are not env steps (no TimeLimit count).
        Returns the new ``info`` (``perturbed=True``).
        """
        owner = f"{type(self).__name__}.perturb"
        if (delta is None) == (to is None):
            raise ValueError(f"{owner}: pass exactly one of `delta` (displacement) or `to` (target position)")
        if to is None:
            name, target = "delta", self.state + real_array(delta, "delta", shape=(3,), owner=owner)
        else:
            name, target = "to", real_array(to, "to", shape=(3,), owner=owner)
        self._check_stable(owner)
        self.perturb_workspace.check(target, name, owner)
        return self._push(target, name, owner)

    def _push(self, target: np.ndarray, name: str, owner: str) -> dict[str, Any]:
        """:meth:`perturb` to ``target`` (in the workspace), refused before any step if the arm cannot reach it."""
        plan = self._ik.plan(
            self.rs_env.sim.data._data, self._position_residual(target), self._ik_seeds(target), iters=_PLAN_ITERS
        )
        if plan is None:
            raise ValueError(
                f"{owner}: `{name}` takes the arm to {np.round(target, 4).tolist()}, which it cannot reach within "
                f"its joint limits (workspace: {self.perturb_workspace.describe()})"
            )
        for _ in range(PERTURB_MAX_STEPS):
            d = target - self.state
            if np.linalg.norm(d) <= PERTURB_TOLERANCE:
                break
            act = np.zeros(7)
            act[:3] = np.clip(d * 10.0, -1.0, 1.0)
            act[6] = self._gripper
            self._sim_step(act, owner)
        if self.perturb_exact:
            self._snap(target, plan)
        self._refresh()
        return self._info(perturbed=True)

    def _position_residual(self, target: np.ndarray) -> Residual:
        """The eef's position error to ``target`` and its Jacobian over the arm joints (for :class:`ArmIK`)."""
        import mujoco

        model = self.rs_env.sim.model._model
        jacp = np.zeros((3, model.nv))

        def residual(data: Any) -> tuple[np.ndarray, np.ndarray]:
            mujoco.mj_jacSite(model, data, jacp, None, self._eef_site)
            return target - data.site_xpos[self._eef_site], jacp[:, self._arm_qvel]

        return residual

    def _ik_seeds(self, target: np.ndarray) -> list[np.ndarray]:
        """Start joints of the reachability check besides the current ones: the home pose, turned toward ``target``."""
        home = np.array(self._robot.init_qpos, dtype=np.float64)
        base = self.perturb_workspace.centre
        assert base is not None
        turned = home.copy()
        turned[0] = np.arctan2(target[1] - base[1], target[0] - base[0])
        raised = turned + _RAISED  # the elbow up: targets close beside the robot's own column
        return [turned, home, raised]

    def _snap(self, target: np.ndarray, plan: np.ndarray) -> None:
        """Damped least-squares IK on the arm joints (kinematic, within their limits) until the eef is on ``target``.

        From the joints the OSC steps left; where that solve stalls (at a joint
        limit), the joints ``plan`` found before the push.
        """
        import mujoco

        sim = self.rs_env.sim
        model, data = sim.model._model, sim.data._data
        if self._ik.solve(data, self._position_residual(target), iters=_SNAP_ITERS) >= IK_TOLERANCE:
            data.qpos[self._arm_qpos] = plan
        data.qvel[self._arm_qvel] = 0.0
        mujoco.mj_forward(model, data)

    # ------------------------------------------------------------- rendering
    def _fast_render(self) -> None:
        """No multisampling (the offscreen buffers rebuilt), no reflections, no skybox: cheap CPU frames."""
        import mujoco

        sim = self.rs_env.sim
        ctx = sim._render_context_offscreen
        sim.model.vis.quality.offsamples = 0
        ctx.gl_ctx.make_current()
        ctx.con.free()
        ctx._set_mujoco_context_and_buffers()
        ctx.scn.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        ctx.scn.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = 0

    def _make_context_current(self) -> None:
        """Bind this env's own offscreen GL context (another env's renderer, made or closed since, may hold it)."""
        ctx = getattr(self.rs_env.sim, "_render_context_offscreen", None)
        if ctx is not None:
            ctx.gl_ctx.make_current()

    def render(self) -> np.ndarray | None:
        """An RGB frame (``render_size x render_size x 3``, uint8) from ``camera`` with ``render_mode="rgb_array"``."""
        if self.render_mode is None:
            return None
        self._make_context_current()
        frame = self.rs_env.sim.render(camera_name=self.camera, width=self.render_size, height=self.render_size)
        return np.ascontiguousarray(frame[::-1])

    def _camera(self, camera: Any, owner: str) -> str:
        """``camera`` (None: the env's ``camera``) checked against the model's cameras."""
        name = self.camera if camera is None else camera
        if not isinstance(name, str):
            raise TypeError(f"{owner}: `camera` must be a str or None, got {describe(name)}")
        if name not in self.camera_names:
            raise ValueError(f"{owner}: unknown `camera` {name!r}; cameras: {list(self.camera_names)}")
        return name

    def render_rgbd(self, camera: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """An RGB frame (uint8, ``(H, W, 3)``) and its depth map (float32 metres, ``(H, W)``) from ``camera``.

        ``camera``: any camera of the model (:attr:`camera_names`; None: the
        env's ``camera``). Both are ``render_size x render_size`` in image
        convention (row 0 at the top, like ``render``); depth is the distance
        along the camera's optical axis, converted from MuJoCo's normalised
        depth buffer (robosuite's ``get_real_depth_map``). Needs
        ``render_mode="rgb_array"`` (the offscreen renderer).
        """
        owner = f"{type(self).__name__}.render_rgbd"
        name = self._camera(camera, owner)
        self._need_renderer(owner)
        from robosuite.utils.camera_utils import get_real_depth_map

        sim = self.rs_env.sim
        self._make_context_current()
        rgb, depth = sim.render(camera_name=name, width=self.render_size, height=self.render_size, depth=True)
        metres = get_real_depth_map(sim, depth[::-1])
        return np.ascontiguousarray(rgb[::-1]), np.ascontiguousarray(metres, dtype=np.float32)

    def _need_renderer(self, owner: str) -> None:
        if self.render_mode is None:
            raise ValueError(
                f"{owner} needs an offscreen renderer: make the env with render_mode='rgb_array' "
                "(this one has render_mode=None)"
            )

    def camera_matrix(self, camera: str | None = None) -> np.ndarray:
        """The 4x4 world-to-image matrix of ``camera`` for a ``render_size`` frame (robosuite's, at the current state).

        It maps a world point ``p`` to ``(x z, y z, z, 1)``; see
        :mod:`steer_envs.envs.robosuite.camera` for the pixel conventions.
        """
        name = self._camera(camera, f"{type(self).__name__}.camera_matrix")
        from robosuite.utils.camera_utils import get_camera_transform_matrix

        size = self.render_size
        return np.asarray(get_camera_transform_matrix(self.rs_env.sim, name, size, size), dtype=np.float64)

    def world_to_pixel(self, point: Any, *, camera: str | None = None) -> np.ndarray:
        """``(u, v, depth)`` of a world point (3 finite reals, m) in a frame of ``camera``.

        Column ``u`` and row ``v`` in image convention (integers are pixel
        centres; the point lies in pixel ``(round(v), round(u))`` when inside the
        frame), ``depth`` its distance along the optical axis (m). Points outside
        the frame are not clipped. No renderer needed.
        """
        owner = f"{type(self).__name__}.world_to_pixel"
        p = real_array(point, "point", shape=(3,), owner=owner)
        return cam.world_to_pixel(p, self.camera_matrix(self._camera(camera, owner)))

    def pixel_to_world(
        self, u: float, v: float, *, camera: str | None = None, depth: float | None = None
    ) -> np.ndarray:
        """The world point (3,) seen at column ``u``, row ``v`` of a ``render_size`` frame of ``camera``.

        ``u``, ``v``: reals in ``[0, render_size)``, image convention (row 0 at
        the top; integers are pixel centres). ``depth``: the point's distance
        along the optical axis (m, finite, > 0); None reads it from a fresh
        depth render at the nearest pixel (needs ``render_mode="rgb_array"``),
        so the point is the first surface the pixel sees.
        """
        owner = f"{type(self).__name__}.pixel_to_world"
        size = self.render_size
        u = real_scalar(u, "u", low=0.0, high=size, high_inclusive=False, owner=owner)
        v = real_scalar(v, "v", low=0.0, high=size, high_inclusive=False, owner=owner)
        name = self._camera(camera, owner)
        if depth is None:
            self._need_renderer(owner)
            row, col = cam.nearest_pixel(u, v, size)
            z = float(self.render_rgbd(name)[1][row, col])
        else:
            z = real_scalar(depth, "depth", low=0.0, low_inclusive=False, owner=owner)
        return cam.pixel_to_world(u, v, z, self.camera_matrix(name))

    def close(self) -> None:
        """Close robosuite's env (its renderer)."""
        rs = getattr(self, "rs_env", None)
        if rs is not None:
            rs.close()
            self.rs_env = None
