"""The shared vocabulary of steer-envs: tasks, interactions, metrics, the env and policy contracts.

Numpy-only on purpose, so ``import steer_envs`` stays fast. The differentiable
alignment objectives need torch and live with the ITPS samplers in
:mod:`steer_envs.steering.objectives`.
"""

from steer_envs.core.env import (
    CONSTRAINT_VIOLATION,
    INFO_KEYS,
    INTERACTION_KINDS,
    IS_SUCCESS,
    MODE,
    MODE_NAME,
    PERTURBED,
    SENSORS,
    SUCCESS,
    HasInteractionKinds,
    HasTask,
    PerturbableEnv,
    SteerEnv,
    perturbable_env,
    steer_env,
    task_of,
)
from steer_envs.core.interaction import (
    Interaction,
    InteractionKind,
    Nudge,
    Point,
    Sketch,
    make_interaction,
    resample_path,
)
from steer_envs.core.lazy import lazy_exports
from steer_envs.core.metrics import (
    MotionAlignment,
    aligned_success,
    constraint_satisfaction,
    motion_alignment,
    sketch_distances,
    task_alignment,
)
from steer_envs.core.policy import DiffusionPolicyLike, NoiseSchedulerLike, TrajectoryPolicy, VelocityPolicy
from steer_envs.core.task import TaskSpec

__all__ = [
    "CONSTRAINT_VIOLATION",
    "INFO_KEYS",
    "INTERACTION_KINDS",
    "IS_SUCCESS",
    "MODE",
    "MODE_NAME",
    "PERTURBED",
    "SENSORS",
    "SUCCESS",
    "DiffusionPolicyLike",
    "HasInteractionKinds",
    "HasTask",
    "Interaction",
    "InteractionKind",
    "MotionAlignment",
    "NoiseSchedulerLike",
    "Nudge",
    "PerturbableEnv",
    "Point",
    "Sketch",
    "SteerEnv",
    "TaskSpec",
    "TrajectoryPolicy",
    "VelocityPolicy",
    "aligned_success",
    "constraint_satisfaction",
    "lazy_exports",
    "make_interaction",
    "motion_alignment",
    "perturbable_env",
    "resample_path",
    "sketch_distances",
    "steer_env",
    "task_alignment",
    "task_of",
]
