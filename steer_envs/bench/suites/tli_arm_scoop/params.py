"""The parameters and axes of ``tli-arm-scoop``: what its suite declares and its protocol runs with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from steer_envs.bench.trials import DwellPushesParams

__all__ = ["ENV_ID", "METHODS", "ArmScoopParams"]

ENV_ID = "steer_envs/ArmScoop-v0"
METHODS: tuple[str, ...] = ("ltl-ds", "ltl-ds+mod")


@dataclass(frozen=True)
class ArmScoopParams(DwellPushesParams):
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
    max_steps: int = 600
    max_dwell: int = 20
