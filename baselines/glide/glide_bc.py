"""GLiDE+BC's shared core: one BC policy per learned mode, each with a pseudo-attractor (thesis §4.2).

GLiDE+BC ("Mode-based motion generation") labels the successful
demonstrations' states with a mode predictor (the trained classifier, or a
baseline) and fits one BC policy to the (state, action) pairs of each mode;
at test time the mode of the current state picks the policy. Each mode ``k``
also has a *pseudo-attractor*: a target where the demos leave mode ``k``
(where they enter ``k + 1``; in the final mode, where they end) and a
threshold, the ``attractor_quantile`` of the distances from the mode's demo
states to that target (at least a floor). Beyond the threshold the state is
farther from the target than nearly every demo state of its mode (a
perturbation pushed it off the demonstrations), and the action becomes
``(1 - w) * pi_k + w * pull``, ``pull`` a bounded step toward the target.

:class:`GlideBC` is that shared part: the per-mode training loop
(:meth:`GlideBC.fit_modes`), the threshold (:meth:`GlideBC.threshold`) and the
blend (:meth:`GlideBC.blend`). Two domains build on it, and differ where their
observations and actions do:

* :class:`~steer_envs.baselines.glide.mode_policies.GlideBCPolicy` (PolygonNav):
  the state is the 2-D position, the attractor a point (the mean state where
  the demos first enter the next mode), the pull a full-speed step toward it;
  batched over the agents of a vector env, the mode read from the classifier.
* :class:`~steer_envs.baselines.glide.arm_policies.GlideArmPolicy` (robosuite
  arms): the policy reads the 19-D observation and outputs a 7-D box action;
  the attractor is the LLM plan's goal feature of the mode (an eef position,
  or an object-relative one that follows the object), and the pull a clipped
  proportional command on the position part of the action only.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Generic, TypeVar

import numpy as np

from steer_envs.core.validation import integer, real_scalar

__all__ = ["GlideBC"]

P = TypeVar("P")


class GlideBC(Generic[P]):
    """GLiDE+BC's per-mode policies and the attractor blend (the part both domains share).

    Args:
        num_modes: ``K``.
        attractor_weight: ``w`` in ``(1 - w) pi_k + w * pull``, in [0, 1].
        owner: the class name used in error messages.

    >>> import numpy as np
    >>> core = GlideBC(2, attractor_weight=0.25)
    >>> core.fit_modes(np.arange(4.0)[:, None], np.ones((4, 1)), np.array([0, 0, 1, 1]), lambda s, a, k: len(s))
    >>> core.policies, core.blend(np.array([1.0]), np.array([5.0])).tolist()
    ([2, 2], [2.0])
    >>> GlideBC.threshold(np.array([0.0, 1.0, 2.0]), 0.5), GlideBC.threshold(np.zeros(3), 0.9, floor=0.02)
    (1.0, 0.02)
    """

    def __init__(self, num_modes: int, *, attractor_weight: float, owner: str = "GlideBC") -> None:
        self.num_modes = integer(num_modes, "num_modes", low=1, owner=owner)
        self.attractor_weight = real_scalar(attractor_weight, "attractor_weight", low=0.0, high=1.0, owner=owner)
        #: mode -> its policy (None: the domain found too few demo pairs labelled with it)
        self.policies: list[P | None] = []

    def fit_modes(
        self,
        states: np.ndarray,
        actions: np.ndarray,
        state_modes: np.ndarray,
        fit: Callable[[np.ndarray, np.ndarray, int], P | None],
    ) -> None:
        """Fit each mode's policy, in mode order, to the pairs labelled with it: ``fit(states_k, actions_k, k)``."""
        self.policies = []
        for k in range(self.num_modes):
            sel = state_modes == k
            self.policies.append(fit(states[sel], actions[sel], k))

    @staticmethod
    def threshold(distances: np.ndarray, quantile: float, floor: float = 0.0) -> float:
        """The attractor's threshold: the ``quantile`` of the mode's demo ``distances`` to it, at least ``floor``."""
        return max(float(np.quantile(distances, quantile)), floor)

    def blend(self, action: np.ndarray, pull: np.ndarray) -> np.ndarray:
        """``(1 - w) * action + w * pull``: the policy's action pulled toward the attractor."""
        w = self.attractor_weight
        return (1.0 - w) * action + w * pull
