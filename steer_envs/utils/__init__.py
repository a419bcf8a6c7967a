"""Helpers shared by every layer: command-line parsing, the steer-env checker, figure helpers."""

from steer_envs.utils.env_checker import CONVENTIONS, SteerEnvCheckError, check_steer_env
from steer_envs.utils.plots import figure_legend, key_line, key_patch, new_figure, save_figure

__all__ = [
    "CONVENTIONS",
    "SteerEnvCheckError",
    "check_steer_env",
    "figure_legend",
    "key_line",
    "key_patch",
    "new_figure",
    "save_figure",
]
