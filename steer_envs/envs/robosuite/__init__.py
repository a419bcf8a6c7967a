"""robosuite tasks (Lift, Can, Square; BlockStack) as steer-envs envs: one adapter + the tasks' ground-truth modes.

Nothing here imports robosuite at import time: the adapter imports it when an
env is made (``gymnasium.make("steer_envs/Lift-v0")``).

>>> from steer_envs.envs.robosuite import TASK_NAMES
>>> TASK_NAMES
('lift', 'can', 'square')
"""

from steer_envs.envs.robosuite.tasks import TASK_NAMES, TASKS, RobosuiteTask, task_spec

__all__ = ["TASKS", "TASK_NAMES", "BlockStackEnv", "RobosuiteEnv", "RobosuiteTask", "task_spec"]


def __getattr__(name: str) -> object:
    if name == "RobosuiteEnv":
        from steer_envs.envs.robosuite.adapter import RobosuiteEnv

        return RobosuiteEnv
    if name == "BlockStackEnv":
        from steer_envs.envs.robosuite.blockstack import BlockStackEnv

        return BlockStackEnv
    raise AttributeError(name)
