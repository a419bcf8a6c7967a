"""The flow-matching policy: Diffusion Policy's U-Net on a rectified-flow velocity, sampled by Euler steps.

>>> from steer_envs.baselines.flow import FlowConfig, FlowPolicy
>>> FlowPolicy(FlowConfig(obs_dim=2, action_dim=2, horizon=8, down_dims=(8, 16))).num_inference_steps
10
"""

from steer_envs.baselines.flow.configuration import PRESETS, FlowConfig
from steer_envs.baselines.flow.modeling import FlowPolicy

__all__ = ["PRESETS", "FlowConfig", "FlowPolicy"]
