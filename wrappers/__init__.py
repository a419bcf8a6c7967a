"""Composable wrappers of steer-envs (installed as ``steer_envs.wrappers``)."""
