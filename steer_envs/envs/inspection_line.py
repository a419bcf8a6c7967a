"""InspectionLine-v0: carry an object to the inspection entry, slide it along the line, release it (TLI robot exp. 2).

The end-effector (holding the object) moves in ``[-8, 8]^2``. Regions (closed
rectangles, later wins)::

    track    [-5, 4] x [-0.5, 0.5]   the inspection line
    entry    [-5, -4] x [-0.5, 0.5]  its left end, where the object is put on the line
    release  [4, 7] x [-1.5, 1.5]    the release station, right of the line's end

Starts (the grasping region) are uniform in ``[-7, -5] x [-7, -5]``.

Physics (task memory ``[object on the line, released]``):

* reaching the entry puts the object on the line (sensor ``l``);
* the object stays on the line while the end-effector stays in the track; leaving
  the track anywhere but across its right end into the release station takes it
  off the line (an interrupted inspection: ``constraint_violation``);
* crossing from the track's last 0.5 into the release station with the object on
  the line releases it: the inspection is done, ``success``; the memory freezes;
* entering the release station with an uninspected object (sensor ``r`` without
  ``l``) is a ``constraint_violation`` (released uninspected), not a success.

Sensor APs ``l`` (the object is on the inspection line) and ``r`` (the
end-effector is at the release station). Modes (the thesis's two, plus the
goal): ``reach_entry`` (``!l``), ``inspect`` (``l & !r``), ``released`` (``l & r``).

Dynamics: ``x' = x + dt * u``, ``dt = 0.01``, ``|u| <= 10``.

Description
    See above; the mode names (``task.modes``) are descriptive already.

Observation
    ``Box(float32)``: the agent's ``(x1, x2)`` in the workspace (``x1`` right, ``x2`` up, as plotted);
    with ``observe_sensors=True`` followed by the sensor APs ``l``, ``r`` as 0/1.

Action
    ``Box(-10, 10, (2,), float32)``: a velocity, ``x' = x + 0.01 u`` with ``|u|`` clipped to 10;
    ``normalize_actions=True``: ``[-1, 1]^2``, scaled by 10.

Rewards
    ``reward_type="sparse"`` (default) or ``"dense"``, as in every 2D env
    (:class:`~steer_envs.envs.kinematic.Kinematic2DEnv`); the dense potential's stage = the mode (reach_entry 0, inspect
    1, released 2), sub-goal = the entry's centre ``(-4.5, 0)``, then ``(4.5, 0)`` just inside the release station.

Termination
    On success (released after the inspection). Violations are reported, never terminal; truncation at
    1000 steps (registered).

Registered ids
    ``steer_envs/InspectionLine-v0``, ``steer_envs/InspectionLineDense-v0`` (for RL: ``reward_type="dense"``,
    ``observe_sensors=True``, ``normalize_actions=True``).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Unpack

import numpy as np

from steer_envs.core.task import TaskSpec
from steer_envs.envs.kinematic import EnvOptions, Kinematic2DEnv, RectRegionsModel, TaskReading
from steer_envs.envs.kinematic_vector import vector_factory
from steer_envs.envs.render import REGION_PALETTE, Canvas

WORKSPACE_HALF_WIDTH = 8.0
WHITE, TRACK, ENTRY, RELEASE = 0, 1, 2, 3
REGION_NAMES: tuple[str, ...] = ("white", "track", "entry", "release")
RECTS: MappingProxyType[str, tuple[float, float, float, float]] = MappingProxyType(
    {
        "track": (-5.0, -0.5, 4.0, 0.5),
        "entry": (-5.0, -0.5, -4.0, 0.5),
        "release": (4.0, -1.5, 7.0, 1.5),
    }
)
#: the object is released only when it crosses into the station from this close to the track's end
END_ZONE = 0.5
START_BOX = ((-7.0, -7.0), (-5.0, -5.0))
SENSORS: tuple[str, ...] = ("l", "r")
MODES: tuple[str, ...] = ("reach_entry", "inspect", "released")
REACH, INSPECT, RELEASED = 0, 1, 2

INSPECTION_TASK = TaskSpec(
    name="InspectionLine",
    modes=MODES,
    sensors=SENSORS,
    sensor_modes={
        frozenset(): "reach_entry",
        frozenset({"r"}): "reach_entry",  # at the station with an uninspected object: still to be inspected
        frozenset({"l"}): "inspect",
        frozenset({"l", "r"}): "released",
    },
    transitions=frozenset({("reach_entry", "inspect"), ("inspect", "released"), ("inspect", "reach_entry")}),
    initial="reach_entry",
    goal=("released",),
)


class InspectionLineModel(RectRegionsModel):
    """Batched task physics of InspectionLine; see the module docstring.

    Public geometry: ``rects`` (region name -> ``(x0, y0, x1, y1)``), ``start_low`` / ``start_high``.
    Task memory (2 slots): ``[object on the line, released]``.
    """

    memory_size = 2
    region_names = REGION_NAMES
    region_palette = REGION_PALETTE[[0, 4, 5, 3]]

    def __init__(self) -> None:
        self.task = INSPECTION_TASK
        self.set_geometry(WORKSPACE_HALF_WIDTH, RECTS, REGION_NAMES[1:], START_BOX)

    def advance(self, memory: np.ndarray, prev_pos: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        prev_reg, reg = self.regions(prev_pos), self.regions(pos)
        on, released = memory[:, 0] == 1, memory[:, 1] == 1
        prev = np.asarray(prev_pos, dtype=np.float64).reshape(-1, 2)
        at_end = ((prev_reg == TRACK) | (prev_reg == ENTRY)) & (prev[:, 0] >= self.rects["track"][2] - END_ZONE)
        release = on & (reg == RELEASE) & at_end
        on_track = (reg == TRACK) | (reg == ENTRY)
        dropped = on & ~release & ~on_track
        new_on = (on & ~dropped) | (reg == ENTRY)
        uninspected = ~on & (reg == RELEASE) & (prev_reg != RELEASE)
        new_memory = np.stack([new_on, released | release], axis=1).astype(np.int64)
        new_memory[released] = memory[released]
        return new_memory, (dropped | uninspected) & ~released

    def read(self, memory: np.ndarray, pos: np.ndarray) -> TaskReading:
        on, released = memory[:, 0] == 1, memory[:, 1] == 1
        at_station = (self.regions(pos) == RELEASE) | released
        mode = np.where(released, RELEASED, np.where(on, INSPECT, REACH))
        return TaskReading(mode=mode.astype(np.int64), sensors=np.stack([on, at_station], axis=1), success=released)

    num_stages = 2
    #: sub-goals of the dense reward: the entry's centre, then just inside the release station.
    SUBGOALS = np.array([[-4.5, 0.0], [4.5, 0.0]])

    def progress(self, memory: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Stage = the mode (reach_entry 0, inspect 1, released 2); sub-goal = the entry, then the station."""
        mode = self.read(memory, pos).mode
        goal = self.SUBGOALS[np.minimum(mode, 1)]
        distance = np.linalg.norm(np.asarray(pos, dtype=np.float64).reshape(-1, 2) - goal, axis=1)
        return mode, np.where(mode == RELEASED, 0.0, distance)

    def draw(self, canvas: Canvas) -> None:
        x0, _, x1, _ = self.rects["track"]
        canvas.polyline(np.array([[x0, 0.0], [x1, 0.0]]), (40, 40, 40), thickness=1)


class InspectionLineEnv(Kinematic2DEnv):
    """InspectionLine-v0 (TLI robot experiment 2, go to the entry -> follow the line -> release); see the module doc.

    Args:
        dt, max_speed: integration step and speed limit (0.01, 10).
        render_mode, render_size, reward_type, observe_sensors, normalize_actions: the options of every 2D env
            (:class:`~steer_envs.envs.kinematic.EnvOptions`, see :class:`~steer_envs.envs.kinematic.Kinematic2DEnv`).

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> env = gym.make("steer_envs/InspectionLine-v0")
    >>> obs, info = env.reset(seed=0)
    >>> info["mode_name"], info["sensors"]
    ('reach_entry', {'l': False, 'r': False})
    >>> env.unwrapped.perturb(to=[-4.5, 0.0])["mode_name"]  # put at the entry: the object is on the line
    'inspect'
    """

    def __init__(self, dt: float = 0.01, max_speed: float = 10.0, **options: Unpack[EnvOptions]) -> None:
        super().__init__(InspectionLineModel(), dt=dt, max_speed=max_speed, terminate_on_violation=False, **options)
        self.model: InspectionLineModel


make_vector_env = vector_factory(InspectionLineEnv)

__all__ = [
    "INSPECTION_TASK",
    "MODES",
    "RECTS",
    "SENSORS",
    "InspectionLineEnv",
    "InspectionLineModel",
    "make_vector_env",
]
