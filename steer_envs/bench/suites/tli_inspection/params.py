"""The parameters and axes of ``tli-inspection``: what its suite declares and its protocol runs with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from steer_envs.bench.params import SuiteParams

__all__ = ["ENV_ID", "METHODS", "InspectionParams"]

ENV_ID = "steer_envs/InspectionLine-v0"
METHODS: tuple[str, ...] = ("vanilla-ds", "ltl-ds", "ltl-ds+mod")


@dataclass(frozen=True)
class InspectionParams(SuiteParams):
    """Parameters of ``tli-inspection``: episodes per condition, pushes per episode, push lengths, step cap."""

    suite_name: ClassVar[str] = "tli-inspection"
    n_episodes: int = 10
    n_pushes: int = 1
    min_push: float = 4.0
    max_push: float = 10.0
    max_steps: int = 3000
    plot_seeds: int = 1

    def __post_init__(self) -> None:
        self.require_at_least(1, "n_episodes", "max_steps")
        self.require_at_least(0, "n_pushes", "min_push", "plot_seeds")
        self.require("max_push", self.max_push >= self.min_push, ">= min_push")
