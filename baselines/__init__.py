"""Baseline policies of steer-envs (installed as ``steer_envs.baselines``).

One folder per policy family: ``diffusion`` and ``act`` (trajectory
policies), ``bc`` (behaviour cloning), ``lpv_ds`` (stable dynamical systems,
LTL-DS), ``glide`` (mode grounding and mode-based policies); ``common`` holds
what they share. Importing this package imports none of them.
"""
