"""What a session call returns: a steering call's batch of plans, and what executing a plan or a controller did."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from steer_envs.core.interaction import Point, Sketch
from steer_envs.ui.settings import SteerSettings

__all__ = ["SteerOutcome", "StepOutcome"]


@dataclass
class SteerOutcome:
    """One steering call: the batch of plans and how it was made.

    Attributes:
        plans: ``(B, H, 2)`` plans in world units (the executed part: from the policy's ``exec_start``).
        chosen: index of the plan the sampler selects.
        costs: ``(B,)`` alignment cost of every plan (NaN unsteered).
        collides: ``(B,)`` bool, a plan crosses a wall (``None`` when the env cannot tell).
        interaction: the interaction in world units (a sketch resampled by arc length), or ``None``.
        timings: ``network_ms`` (the policy's network), ``sampler_ms`` (the rest of the call),
            ``total_ms``, ``network_evals``.
        settings: the settings of the call.
        perturbed_state: where OP moves the agent before the plan runs (``None`` for the other samplers).
    """

    plans: np.ndarray
    chosen: int
    costs: np.ndarray
    collides: np.ndarray | None
    interaction: Point | Sketch | None
    timings: dict[str, float]
    settings: SteerSettings
    perturbed_state: np.ndarray | None = None

    @property
    def plan(self) -> np.ndarray:
        """The chosen plan ``(H, 2)``."""
        return self.plans[self.chosen]


@dataclass
class StepOutcome:
    """What executing (part of) the chosen plan did."""

    executed: np.ndarray
    reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any] = field(default_factory=dict)
