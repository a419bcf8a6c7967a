"""Diffusion Policy: config, presets, the conditional 1D U-Net and the DDIM-sampled policy.

>>> from steer_envs.baselines.diffusion import DiffusionConfig, DiffusionPolicy
>>> DiffusionPolicy(DiffusionConfig(obs_dim=7, action_dim=4, horizon=8, down_dims=(8, 16))).horizon
8
"""

from steer_envs.baselines.diffusion.configuration import PREDICTIONS, PRESETS, DiffusionConfig, PlanNetConfig
from steer_envs.baselines.diffusion.modeling import DiffusionPolicy
from steer_envs.baselines.diffusion.network import ConditionalUnet1D, DiffusionNet, ObsEncoder

__all__ = [
    "PREDICTIONS",
    "PRESETS",
    "ConditionalUnet1D",
    "DiffusionConfig",
    "DiffusionNet",
    "DiffusionPolicy",
    "ObsEncoder",
    "PlanNetConfig",
]
