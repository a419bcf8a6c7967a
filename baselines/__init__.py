"""Baseline policies of steer-envs (installed as ``steer_envs.baselines``)."""
