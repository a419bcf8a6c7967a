"""The parameters and axes of ``tli-cooking``: what its suite declares and its protocol runs with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from steer_envs.bench.trials import ProtocolParams

__all__ = ["ENV_ID", "VARIANTS", "CookingParams"]

ENV_ID = "steer_envs/Cooking-v0"
VARIANTS: tuple[str, ...] = ("phi_cb", "phi_bc", "phi_c", "phi_cc")


@dataclass(frozen=True)
class CookingParams(ProtocolParams):
    """Parameters of ``tli-cooking``.

    ``n_starts`` episodes per condition (no pushes / pushes); ``n_pushes``
    pushes at steps ``1..push_window`` of length up to ``magnitude``;
    ``horizon`` steps per episode; ``deliveries`` chicken deliveries that make
    ``phi_cc`` a success; ``modulation`` learns cuts; the first ``plot_seeds``
    experiments keep their first episode for the figure.
    """

    suite_name: ClassVar[str] = "tli-cooking"
    n_pushes: int = 2
    n_starts: int = 10
    push_window: int = 400
    magnitude: float = 8.0
    horizon: int = 3000
    deliveries: int = 3
    modulation: bool = True

    def __post_init__(self) -> None:
        super().__post_init__()
        self.require_at_least(1, "n_starts", "horizon", "deliveries", "push_window")
        self.require_at_least(0, "magnitude")
