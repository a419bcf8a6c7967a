"""Helpers shared by every layer: command-line parsing, the steer-env checker."""

from steer_envs.utils.env_checker import CONVENTIONS, SteerEnvCheckError, check_steer_env

__all__ = ["CONVENTIONS", "SteerEnvCheckError", "check_steer_env"]
