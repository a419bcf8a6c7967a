"""Environments of steer-envs; one module per domain. See ``registry.py`` for ids."""
