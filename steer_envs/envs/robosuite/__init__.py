"""robosuite tasks (Lift, Can, Square; BlockStack; ArmScoop; Kitchen) as steer-envs envs: an adapter + true modes.

Nothing here imports robosuite at import time: the adapter imports it when an
env is made (``gymnasium.make("steer_envs/Lift-v0")``). :class:`SimulationUnstableError`
is what the arm envs raise when MuJoCo finds their simulation unstable;
:class:`Workspace` is the region their pushes may reach (``env.unwrapped.perturb_workspace``).

>>> from steer_envs.envs.robosuite import TASK_NAMES
>>> TASK_NAMES
('lift', 'can', 'square')
"""

from steer_envs.envs.robosuite.stability import SimulationUnstableError
from steer_envs.envs.robosuite.tasks import TASK_NAMES, TASKS, RobosuiteTask, task_spec
from steer_envs.envs.robosuite.workspace import Workspace

__all__ = [
    "TASKS",
    "TASK_NAMES",
    "ArmScoopEnv",
    "BlockStackEnv",
    "KitchenEnv",
    "RobosuiteEnv",
    "RobosuiteTask",
    "SimulationUnstableError",
    "Workspace",
    "task_spec",
]


def __getattr__(name: str) -> object:
    if name == "RobosuiteEnv":
        from steer_envs.envs.robosuite.adapter import RobosuiteEnv

        return RobosuiteEnv
    if name == "BlockStackEnv":
        from steer_envs.envs.robosuite.blockstack import BlockStackEnv

        return BlockStackEnv
    if name == "ArmScoopEnv":
        from steer_envs.envs.robosuite.arm_scoop import ArmScoopEnv

        return ArmScoopEnv
    if name == "KitchenEnv":
        from steer_envs.envs.robosuite.kitchen import KitchenEnv

        return KitchenEnv
    raise AttributeError(name)
