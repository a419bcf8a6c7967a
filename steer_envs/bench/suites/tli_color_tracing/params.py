"""The parameters and axes of ``tli-color-tracing``: what its suite declares and its protocol runs with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from steer_envs.bench.params import SuiteParams

__all__ = ["AUTOMATA", "ENV_ID", "ColorTracingParams"]

ENV_ID = "steer_envs/ColorTracing-v0"
AUTOMATA: tuple[str, ...] = ("a", "b", "c")


@dataclass(frozen=True)
class ColorTracingParams(SuiteParams):
    """Parameters of ``tli-color-tracing``.

    ``n_episodes`` per condition (no pushes / pushes); ``n_pushes`` pushes into
    D per episode, each from its own random tile after ``1..max_dwell`` steps
    on it; ``max_steps`` per episode;
    ``modulation`` learns cuts from invariance failures; the first
    ``plot_seeds`` experiments keep episodes for the figure.
    """

    suite_name: ClassVar[str] = "tli-color-tracing"
    n_episodes: int = 10
    n_pushes: int = 3
    max_dwell: int = 15
    max_steps: int = 2500
    modulation: bool = True
    plot_seeds: int = 1

    def __post_init__(self) -> None:
        self.require_at_least(1, "n_episodes", "max_dwell", "max_steps")
        self.require_at_least(0, "n_pushes", "plot_seeds")
