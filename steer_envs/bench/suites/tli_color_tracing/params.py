"""The parameters and axes of ``tli-color-tracing``: what its suite declares and its protocol runs with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from steer_envs.bench.trials import DwellPushesParams

__all__ = ["AUTOMATA", "ENV_ID", "ColorTracingParams"]

ENV_ID = "steer_envs/ColorTracing-v0"
AUTOMATA: tuple[str, ...] = ("a", "b", "c")


@dataclass(frozen=True)
class ColorTracingParams(DwellPushesParams):
    """Parameters of ``tli-color-tracing``.

    ``n_episodes`` per condition (no pushes / pushes); ``n_pushes`` pushes into
    D per episode, each from its own random tile after ``1..max_dwell`` steps
    on it; ``max_steps`` per episode;
    ``modulation`` learns cuts from invariance failures; the first
    ``plot_seeds`` experiments keep episodes for the figure.
    """

    suite_name: ClassVar[str] = "tli-color-tracing"
    n_pushes: int = 3
    max_steps: int = 2500
    max_dwell: int = 15
    modulation: bool = True
