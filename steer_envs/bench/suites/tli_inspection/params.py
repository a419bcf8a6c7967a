"""The parameters and axes of ``tli-inspection``: what its suite declares and its protocol runs with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from steer_envs.bench.trials import PushedEpisodesParams

__all__ = ["ENV_ID", "METHODS", "InspectionParams"]

ENV_ID = "steer_envs/InspectionLine-v0"
METHODS: tuple[str, ...] = ("vanilla-ds", "ltl-ds", "ltl-ds+mod")


@dataclass(frozen=True)
class InspectionParams(PushedEpisodesParams):
    """Parameters of ``tli-inspection``: episodes per condition, pushes per episode, push lengths, step cap.

    The counts keep :class:`~steer_envs.bench.trials.PushedEpisodesParams`'s
    defaults (10 episodes, one push each, 3000 steps).
    """

    suite_name: ClassVar[str] = "tli-inspection"
    min_push: float = 4.0
    max_push: float = 10.0

    def __post_init__(self) -> None:
        super().__post_init__()
        self.require_at_least(0, "min_push")
        self.require("max_push", self.max_push >= self.min_push, ">= min_push")
