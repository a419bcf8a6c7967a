"""ACT, the action-chunking transformer: config, presets, network and policy.

>>> from steer_envs.baselines.act import ACTConfig, ACTPolicy
>>> ACTPolicy(ACTConfig(obs_dim=3, action_dim=2, chunk_size=4, d_model=8, n_heads=1, dim_feedforward=8)).horizon
4
"""

from steer_envs.baselines.act.configuration import PRESETS, ACTConfig
from steer_envs.baselines.act.modeling import ACTModel, ACTPolicy

__all__ = ["PRESETS", "ACTConfig", "ACTModel", "ACTPolicy"]
