"""Behaviour cloning: an MLP policy (:class:`BCPolicy`), its settings (:class:`BCConfig`), resumable runs.

The defaults are the thesis's BC velocity policy of the TLI study; GLiDE's BC
baselines use the same policy with :class:`~steer_envs.baselines.glide.mode_policies.GlideBCConfig`.
:mod:`.runs` trains one by minibatch steps that can stop and continue from a file (:func:`train_run`).

>>> from steer_envs.baselines.bc import BCConfig, BCPolicy
>>> BCPolicy(BCConfig(hidden=(8,), epochs=1)).config.output
'tanh'
"""

from steer_envs.baselines.bc.modeling import BC_OUTPUTS, BCConfig, BCOutput, BCPolicy, clip_speed
from steer_envs.baselines.bc.runs import BCRun, train_run

__all__ = ["BC_OUTPUTS", "BCConfig", "BCOutput", "BCPolicy", "BCRun", "clip_speed", "train_run"]
