"""Shared plumbing of the trajectory policies: the torch policy base, configs, presets, normalizers.

>>> from steer_envs.baselines.common import FeatureStats, Normalizer
>>> Normalizer("mean_std", FeatureStats(mean=[1.0], std=[2.0]), dim=1).normalize([[3.0]]).tolist()
[[1.0]]
"""

from steer_envs.baselines.common.configuration import PolicyConfig, Preset, TrainSettings
from steer_envs.baselines.common.normalize import NORMALIZATION_MODES, FeatureStats, Normalizer
from steer_envs.baselines.common.torch_policy import (
    CHECKPOINT_FORMAT,
    TorchPolicy,
    observation_history,
    read_checkpoint,
    write_checkpoint,
)

__all__ = [
    "CHECKPOINT_FORMAT",
    "NORMALIZATION_MODES",
    "FeatureStats",
    "Normalizer",
    "PolicyConfig",
    "Preset",
    "TorchPolicy",
    "TrainSettings",
    "observation_history",
    "read_checkpoint",
    "write_checkpoint",
]
