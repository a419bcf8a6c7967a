"""The parameters and axes of ``tli-arm-scoop``: what its suite declares and its protocol runs with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from steer_envs.bench.params import SuiteParams

__all__ = ["ENV_ID", "METHODS", "ArmScoopParams"]

ENV_ID = "steer_envs/ArmScoop-v0"
METHODS: tuple[str, ...] = ("ltl-ds", "ltl-ds+mod")


@dataclass(frozen=True)
class ArmScoopParams(SuiteParams):
    """Parameters of ``tli-arm-scoop``.

    ``n_episodes`` pushed episodes per trial (cuts persist across them);
    ``n_pushes`` pushes per episode (the first while scooping, the second while
    carrying, more in random modes), each after ``1..max_dwell`` steps in its
    mode; ``max_steps`` per episode; the first ``plot_seeds`` experiments keep
    data for the figure.
    """

    suite_name: ClassVar[str] = "tli-arm-scoop"
    n_episodes: int = 30
    n_pushes: int = 3
    max_dwell: int = 20
    max_steps: int = 600
    plot_seeds: int = 1

    def __post_init__(self) -> None:
        self.require_at_least(1, "n_episodes", "max_dwell", "max_steps")
        self.require_at_least(0, "n_pushes", "plot_seeds")
