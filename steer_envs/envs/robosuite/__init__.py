"""robosuite tasks (Lift, Can, Square; BlockStack; ArmScoop; Kitchen) as steer-envs envs: an adapter + true modes.

Nothing here imports robosuite at import time: the adapter imports it when an
env is made (``gymnasium.make("steer_envs/Lift-v0")``).

>>> from steer_envs.envs.robosuite import TASK_NAMES
>>> TASK_NAMES
('lift', 'can', 'square')
"""

from steer_envs.envs.robosuite.tasks import TASK_NAMES, TASKS, RobosuiteTask, task_spec

__all__ = [
    "TASKS",
    "TASK_NAMES",
    "ArmScoopEnv",
    "BlockStackEnv",
    "KitchenEnv",
    "RobosuiteEnv",
    "RobosuiteTask",
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
