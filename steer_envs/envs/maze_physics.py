"""The Maze2D physics: D4RL's point mass in MuJoCo, tracking a waypoint with D4RL's PD law.

A sphere of radius :data:`~steer_envs.envs.maze_grid.AGENT_RADIUS` on two slide joints,
timestep 0.01 s, Euler, frictionless contacts, no gravity; walls are boxes of
half-size 0.5 on the cell grid. The PD law is a MuJoCo affine actuator, so it is
re-evaluated at every physics step.
"""

from __future__ import annotations

import mujoco
import numpy as np

from steer_envs.envs.maze_grid import AGENT_RADIUS, MazeGrid

#: D4RL maze2d physics step (s).
TIMESTEP = 0.01
#: PD law ``u = clip(KP (wp - pos) - KD vel, -U_MAX, U_MAX)``, force = GEAR * u.
KP, KD, U_MAX, GEAR = 10.0, 1.0, 1.0, 100.0


def maze_mjcf(grid: MazeGrid, name: str = "maze2d") -> str:
    """MJCF of the D4RL point mass in ``grid`` (walls as boxes, PD actuators on ``ctrl = waypoint``).

    The affine actuator ``force = 1000 ctrl - 1000 qpos - 100 qvel`` clamped
    to +-100 is exactly ``100 * clip(10 (wp - pos) - vel, -1, 1)``.
    """
    gain, kv = GEAR * KP, GEAR * KD
    walls = "\n".join(
        f'    <geom name="wall_{r}_{c}" type="box" pos="{r} {c} 0" size="0.5 0.5 0.2" rgba=".7 .5 .3 1"/>'
        for r, c in np.argwhere(grid.walls)
    )
    actuators = "\n".join(
        f'    <general name="pd_{axis}" joint="{axis}" gainprm="{gain}" biastype="affine" '
        f'biasprm="0 {-gain} {-kv}" forcelimited="true" forcerange="{-GEAR * U_MAX} {GEAR * U_MAX}"/>'
        for axis in ("x", "y")
    )
    return f"""<mujoco model="{name}">
  <compiler inertiafromgeom="true" angle="radian"/>
  <option timestep="{TIMESTEP}" gravity="0 0 0" iterations="20" integrator="Euler"/>
  <default>
    <joint damping="1" limited="false"/>
    <geom friction=".5 .1 .1" density="1000" margin="0.002" condim="1" contype="2" conaffinity="1"/>
  </default>
  <worldbody>
    <body name="agent" pos="0 0 0">
      <geom name="agent" type="sphere" size="{AGENT_RADIUS}" contype="1" conaffinity="1" rgba="0.2 0.3 0.9 1"/>
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
    </body>
{walls}
  </worldbody>
  <actuator>
{actuators}
  </actuator>
</mujoco>
"""


class MazePhysics:
    """The MuJoCo model and data of one maze; steps the PD-tracked point mass."""

    def __init__(self, grid: MazeGrid, name: str = "maze2d") -> None:
        self.grid = grid
        self.model = mujoco.MjModel.from_xml_string(maze_mjcf(grid, name))
        self.data = mujoco.MjData(self.model)
        self.agent_geom = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, "agent")

    @property
    def pos(self) -> np.ndarray:
        return self.data.qpos[:2].copy()

    @property
    def vel(self) -> np.ndarray:
        return self.data.qvel[:2].copy()

    def set_state(self, pos: np.ndarray, vel: np.ndarray | None = None) -> None:
        """Place the agent (velocity zero unless given) and recompute derived quantities."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:2] = pos
        self.data.qvel[:2] = 0.0 if vel is None else vel
        mujoco.mj_forward(self.model, self.data)

    def in_contact(self) -> bool:
        """Whether the agent geom has a MuJoCo contact with a wall geom now."""
        n = self.data.ncon
        if n == 0:
            return False
        geoms = self.data.contact.geom[:n]
        return bool(np.any(geoms == self.agent_geom))

    def step(self, waypoint: np.ndarray, n: int = 1) -> bool:
        """``n`` physics steps tracking ``waypoint``; True if the agent touched a wall in any of them."""
        self.data.ctrl[:2] = waypoint
        touched = False
        for _ in range(n):
            mujoco.mj_step(self.model, self.data)
            touched = touched or self.in_contact()
        return touched

    def control(self) -> np.ndarray:
        """The normalized control ``u`` (in [-1, 1]) applied in the last step."""
        return self.data.actuator_force[:2] / GEAR
