"""The Kitchen scene: where the table, microwave, sink and bowl stand, and the robosuite env that builds it.

:class:`~steer_envs.envs.robosuite.kitchen.KitchenEnv` reads its sensors against
these positions; the skills (:mod:`steer_envs.control.kitchen`) and the expert aim
at them. robosuite is imported by :func:`kitchen_sim_class`, never by importing this module.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from steer_envs.envs.robosuite.kitchen_assets import BOWL_FILE, BOWL_HEIGHT, MICROWAVE_FILE, asset_dir
from steer_envs.envs.robosuite.table import add_object_observables, table_arena

#: the microwave's scale (width, depth, height; source units are FrankaKitchen's): its cavity is 31 x 25 x 35 cm,
#: tall enough for the hand and wrist above a bowl set in with the fingers pointing down.
MICROWAVE_SCALE = (0.75, 0.75, 1.2)
TABLE_SIZE = (0.8, 1.4, 0.05)
TABLE_Z = 0.8
#: x (m) of the microwave cavity's front plane (the door closes just in front of it).
CAVITY_FRONT_X = -0.02
_S, _SZ = MICROWAVE_SCALE[0], MICROWAVE_SCALE[2]
#: the microwave body's origin (bottom centre of the source frame) and its yaw (its front faces -x).
MICROWAVE_POS = (CAVITY_FRONT_X + 0.176 * _S, 0.02 + 0.345 * _S, TABLE_Z)
#: the cavity (world, m): x from the front plane back, y across, z from the floor up.
CAVITY_LOW = np.array([CAVITY_FRONT_X, MICROWAVE_POS[1] + 0.080 * _S - 0.207 * _S, TABLE_Z + 0.048 * _SZ])
CAVITY_HIGH = np.array([CAVITY_FRONT_X + 0.337 * _S, MICROWAVE_POS[1] + 0.080 * _S + 0.207 * _S, TABLE_Z + 0.336 * _SZ])
#: height (m) of the door's top edge (the door skills pass over it).
DOOR_TOP_Z = TABLE_Z + (0.192 + 0.185) * _SZ
#: the sink basin: centre (x, y) on the table, full size (x, y, z), wall thickness (m).
SINK_XY = (-0.05, -0.38)
SINK_SIZE = (0.2, 0.22, 0.07)
SINK_WALL = 0.01
#: height (m) of the sink basin's floor (the env's ``sink_floor_z``).
SINK_FLOOR_Z = TABLE_Z + SINK_WALL
#: the bowl's start on the table: x and y ranges (m) of its centre.
BOWL_START_BOX = ((-0.2, -0.12), (-0.17, -0.07))
#: a door that starts open (reset option ``door="open"``) starts at this angle (rad).
DOOR_START_OPEN = 1.3


def _look_at(pos: np.ndarray, target: np.ndarray) -> str:
    """MJCF ``xyaxes`` of a camera at ``pos`` looking at ``target`` (image up toward world +z)."""
    forward = (target - pos) / np.linalg.norm(target - pos)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    return " ".join(f"{v:.5f}" for v in (*right, *up))


#: the scene camera (RGB-D, the pixel methods' default): high on the robot's right, looking over the table.
SCENE_CAMERA = "kitchen_view"
_SCENE_CAMERA_POS = np.array([-0.6, -1.1, 1.8])
_SCENE_CAMERA_TARGET = np.array([-0.05, 0.0, 0.85])


def _kitchen_arena(env: Any) -> Any:
    """The table arena (the robot at its edge) with the scene camera."""
    import xml.etree.ElementTree as ET

    arena = table_arena(env)
    ET.SubElement(
        arena.worldbody,
        "camera",
        name=SCENE_CAMERA,
        mode="fixed",
        fovy="55",
        pos=" ".join(f"{v:.4f}" for v in _SCENE_CAMERA_POS),
        xyaxes=_look_at(_SCENE_CAMERA_POS, _SCENE_CAMERA_TARGET),
    )
    return arena


def _load_kitchen_model(env: Any, sink_class: type) -> None:
    """Place the robot, build the arena and set ``env.microwave``, ``env.sink``, ``env.bowl`` and ``env.model``."""
    from robosuite.models.objects import MujocoXMLObject
    from robosuite.models.tasks import ManipulationTask
    from robosuite.utils.mjcf_utils import array_to_string

    arena = _kitchen_arena(env)
    folder = asset_dir()
    env.microwave = MujocoXMLObject(
        str(folder / MICROWAVE_FILE),
        name="microwave",
        joints=None,
        duplicate_collision_geoms=False,
        scale=list(MICROWAVE_SCALE),
    )
    env.microwave.get_obj().set("pos", array_to_string(MICROWAVE_POS))
    env.microwave.get_obj().set("quat", "0.70710678 0 0 -0.70710678")  # front (-y) to -x
    env.sink = sink_class(
        "sink",
        bin_size=SINK_SIZE,
        wall_thickness=SINK_WALL,
        transparent_walls=False,
        use_texture=False,
        rgba=(0.55, 0.58, 0.62, 1.0),
    )
    env.sink.get_obj().set("pos", array_to_string([*SINK_XY, TABLE_Z + SINK_SIZE[2] / 2]))
    env.bowl = MujocoXMLObject(str(folder / BOWL_FILE), name="bowl", duplicate_collision_geoms=True)
    env.model = ManipulationTask(
        mujoco_arena=arena,
        mujoco_robots=[robot.robot_model for robot in env.robots],
        mujoco_objects=[env.microwave, env.sink, env.bowl],
    )


def _kitchen_references(env: Any) -> None:
    """The sim ids of the bowl, the door joint and body, and the handle site."""
    model = env.sim.model
    env.bowl_body_id = model.body_name2id(env.bowl.root_body)
    env.door_qpos = int(model.get_joint_qpos_addr("microwave_microwave"))
    env.door_qvel = int(model.get_joint_qvel_addr("microwave_microwave"))
    env.door_body_id = model.body_name2id("microwave_microdoorroot")
    env.handle_site_id = model.site_name2id("microwave_microhandle_site")


def _kitchen_observables(env: Any, observables: Any) -> Any:
    """``observables`` with the bowl's position and quaternion (xyzw) and the door angle added."""
    from robosuite.utils.transform_utils import convert_quat

    def bowl_pos(obs_cache: Any) -> np.ndarray:
        return np.array(env.sim.data.body_xpos[env.bowl_body_id])

    def bowl_quat(obs_cache: Any) -> np.ndarray:
        return convert_quat(np.array(env.sim.data.body_xquat[env.bowl_body_id]), to="xyzw")

    def door_angle(obs_cache: Any) -> np.ndarray:
        return np.array([-env.sim.data.qpos[env.door_qpos]])

    return add_object_observables(env, observables, ((fn.__name__, fn) for fn in (bowl_pos, bowl_quat, door_angle)))


def _bowl_start(place: str, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """The bowl's start xy and resting height at ``place`` (``table``, ``sink``, ``microwave``), drawn from ``rng``."""
    if place == "table":
        (x0, x1), (y0, y1) = BOWL_START_BOX
        return np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)]), TABLE_Z
    if place == "sink":
        return np.asarray(SINK_XY) + rng.uniform(-0.02, 0.02, size=2), TABLE_Z + SINK_WALL
    mid = (CAVITY_LOW + CAVITY_HIGH) / 2
    xy = np.array([CAVITY_FRONT_X + 0.07, mid[1]]) + rng.uniform(-0.01, 0.01, size=2)
    return xy, float(CAVITY_LOW[2])


def _reset_kitchen(env: Any) -> None:
    """Set the door and the bowl (spot and yaw drawn from ``env.rng``) as ``env.start`` asks."""
    env.sim.data.qpos[env.door_qpos] = -DOOR_START_OPEN if env.start["door"] == "open" else 0.0
    env.sim.data.qvel[env.door_qvel] = 0.0
    xy, z = _bowl_start(env.start["bowl"], env.rng)
    yaw = env.rng.uniform(0.0, 2 * np.pi)
    pose = np.array([xy[0], xy[1], z + BOWL_HEIGHT / 2 - 0.0005, np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    env.sim.data.set_joint_qpos(env.bowl.joints[0], pose)
    env.sim.forward()


@functools.cache
def kitchen_sim_class() -> type:
    """The robosuite env class of the scene (defined on first use: robosuite registers env classes by name)."""
    from robosuite.environments.manipulation.lift import Lift
    from robosuite.models.objects import Bin

    class Sink(Bin):  # type: ignore[misc]
        """robosuite's Bin, fixed to the table (no free joint)."""

        def _get_geom_attrs(self) -> dict[str, Any]:
            attrs: dict[str, Any] = super()._get_geom_attrs()
            attrs["joints"] = None
            return attrs

    class SteerKitchen(Lift):  # type: ignore[misc]
        """A table with a microwave, a sink and a bowl; the bowl's start and the door's set by ``start``."""

        def __init__(self, *args: Any, **kwargs: Any) -> None:
            self.start: dict[str, str] = {"bowl": "table", "door": "closed"}
            super().__init__(*args, table_full_size=TABLE_SIZE, **kwargs)

        def _load_model(self) -> None:
            super(Lift, self)._load_model()
            _load_kitchen_model(self, Sink)

        def _setup_references(self) -> None:
            super(Lift, self)._setup_references()
            _kitchen_references(self)

        def _setup_observables(self) -> Any:
            return _kitchen_observables(self, super(Lift, self)._setup_observables())

        def _reset_internal(self) -> None:
            super(Lift, self)._reset_internal()
            _reset_kitchen(self)

        def reward(self, action: Any = None) -> float:
            return 0.0

        def _check_success(self) -> bool:
            return False  # judged by KitchenEnv (it needs the latched sensors)

        def visualize(self, vis_settings: Any) -> None:
            super(Lift, self).visualize(vis_settings=vis_settings)

    return SteerKitchen
