"""Shared plumbing of the trajectory policies: the torch policy base, configs, presets, normalizers, checkpoints.

Every checkpoint loader of :mod:`steer_envs.baselines` raises
:class:`CheckpointError` (a ``ValueError``, also in :mod:`steer_envs.io`)
naming the file and what is wrong with it.

>>> from steer_envs.baselines.common import FeatureStats, Normalizer
>>> Normalizer("mean_std", FeatureStats(mean=[1.0], std=[2.0]), dim=1).normalize([[3.0]]).tolist()
[[1.0]]
"""

from steer_envs.baselines.common.checkpoint import (
    MAX_CHECKPOINT_BYTES,
    MAX_PARAMETERS,
    read_safetensors,
    write_safetensors,
)
from steer_envs.baselines.common.configuration import PolicyConfig, Preset, TrainSettings
from steer_envs.baselines.common.normalize import NORMALIZATION_MODES, FeatureStats, Normalizer
from steer_envs.baselines.common.torch_policy import (
    CHECKPOINT_FORMAT,
    MAX_SAMPLES,
    TorchPolicy,
    observation_history,
    read_checkpoint,
    write_checkpoint,
)
from steer_envs.io import CheckpointError

__all__ = [
    "CHECKPOINT_FORMAT",
    "MAX_CHECKPOINT_BYTES",
    "MAX_PARAMETERS",
    "MAX_SAMPLES",
    "NORMALIZATION_MODES",
    "CheckpointError",
    "FeatureStats",
    "Normalizer",
    "PolicyConfig",
    "Preset",
    "TorchPolicy",
    "TrainSettings",
    "observation_history",
    "read_checkpoint",
    "read_safetensors",
    "write_checkpoint",
    "write_safetensors",
]
