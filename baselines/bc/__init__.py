"""Behaviour cloning: one MLP policy (:class:`BCPolicy`) and its settings (:class:`BCConfig`).

The defaults are the thesis's BC velocity policy of the TLI study; GLiDE's BC
baselines use the same policy with :class:`~steer_envs.baselines.glide.mode_policies.GlideBCConfig`.

>>> from steer_envs.baselines.bc import BCConfig, BCPolicy
>>> BCPolicy(BCConfig(hidden=(8,), epochs=1)).config.output
'tanh'
"""

from steer_envs.baselines.bc.modeling import BC_OUTPUTS, BCConfig, BCOutput, BCPolicy, clip_speed

__all__ = ["BC_OUTPUTS", "BCConfig", "BCOutput", "BCPolicy", "clip_speed"]
