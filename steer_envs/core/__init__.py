"""The shared vocabulary of steer-envs: tasks, interactions, metrics, policy contracts.

Numpy-only on purpose, so ``import steer_envs`` stays fast. The differentiable
alignment objectives need torch and live in :mod:`steer_envs.core.objectives`
(import it explicitly).
"""

from steer_envs.core.interaction import (
    Interaction,
    InteractionKind,
    Nudge,
    Point,
    Sketch,
    make_interaction,
    resample_path,
)
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
    "DiffusionPolicyLike",
    "Interaction",
    "InteractionKind",
    "MotionAlignment",
    "NoiseSchedulerLike",
    "Nudge",
    "Point",
    "Sketch",
    "TaskSpec",
    "TrajectoryPolicy",
    "VelocityPolicy",
    "aligned_success",
    "constraint_satisfaction",
    "make_interaction",
    "motion_alignment",
    "resample_path",
    "sketch_distances",
    "task_alignment",
]
