"""The samplers that rank a batch of any trajectory policy: RS, PR and OP (thesis §2.3).

They need only ``TrajectoryPolicy.sample``: RS takes a random plan of an
unmodified batch, PR ranks that batch by the alignment cost ``xi``, OP moves
the agent onto the user's input and ranks fresh samples from there like PR.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from steer_envs.core.interaction import Nudge, Point, Sketch
from steer_envs.core.validation import integer
from steer_envs.steering.base import Sampler, argmin_choice, check_plans
from steer_envs.steering.observations import place_observation

__all__ = ["OutputPerturbation", "PostHocRanking", "RandomSampling", "output_perturbation_point"]


def output_perturbation_point(
    sketch: Sketch, index: int = 20, collides: Callable[[np.ndarray], np.ndarray] | None = None
) -> np.ndarray:
    """Where OP moves the agent: the sketch's ``index``-th point, or the one before its first collision.

    ``collides`` maps points ``(G, d)`` to bool ``(G,)`` (e.g. ``Maze2DEnv.is_wall``).
    As in the ITPS code, a collision at the sketch's first point is ignored (the
    start is where the agent already is); ``index`` is clamped to the sketch.
    """
    if not isinstance(sketch, Sketch):
        raise TypeError(f"`sketch` must be a Sketch, got {type(sketch).__name__}")
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or index < 1:
        raise ValueError(f"`index` must be a positive integer, got {index!r}")
    points = sketch.points
    k = min(int(index), len(points) - 1)
    if collides is not None:
        flags = np.asarray(collides(points), dtype=bool).reshape(-1)
        if flags.shape != (len(points),):
            raise ValueError(f"`collides` must return one flag per sketch point ({len(points)}), got {flags.shape}")
        first = int(np.argmax(flags)) if flags.any() else -1
        if 0 < first <= k:
            return np.array(points[first - 1])
    return np.array(points[k])


class RandomSampling(Sampler):
    """RS: a random plan of an unmodified batch (the baseline; ``None`` interaction = unsteered)."""

    name = "RS"
    accepts_none = True
    takes_costs = False
    interactions = (Point, Sketch, Nudge)

    def _run(self, policy: Any, obs: Any, interaction: Any, n: int, rng: np.random.Generator) -> Any:
        plans = check_plans(policy.sample(obs, n, generator=rng), n, policy, "policy.sample")
        pick = int(rng.integers(n))  # drawn after the batch, so PR with the same generator ranks the same batch
        return plans, lambda costs: pick, {}, None


class PostHocRanking(Sampler):
    """PR: rank an unmodified batch by ``xi`` and pick the best plan."""

    name = "PR"

    def _run(self, policy: Any, obs: Any, interaction: Any, n: int, rng: np.random.Generator) -> Any:
        plans = check_plans(policy.sample(obs, n, generator=rng), n, policy, "policy.sample")
        return plans, argmin_choice, {}, None


class OutputPerturbation(Sampler):
    """OP: move the agent onto the user's input, sample from there, rank like PR.

    Args:
        index: the sketch point the agent is moved to (ITPS: 20).
        collides: points ``(G, d) -> bool (G,)``; with it the agent stops before the
            sketch's first collision (e.g. ``env.unwrapped.is_wall``).
        obs_at: ``(obs, xy) -> obs`` building the observation at the new position
            (default :func:`place_observation`: the agent at rest at ``xy``).

    A :class:`Nudge` moves the agent to its last state (the physical correction
    is executed); its plans all satisfy it, so the pick is random.
    """

    name = "OP"
    interactions = (Sketch, Nudge)

    def __init__(
        self,
        index: int = 20,
        collides: Callable[[np.ndarray], np.ndarray] | None = None,
        obs_at: Callable[[Any, np.ndarray], Any] | None = None,
    ) -> None:
        index = integer(index, "`index`", low=1)
        if collides is not None and not callable(collides):
            raise TypeError(f"`collides` must be callable or None, got {type(collides).__name__}")
        if obs_at is not None and not callable(obs_at):
            raise TypeError(f"`obs_at` must be callable or None, got {type(obs_at).__name__}")
        self.index = int(index)
        self.collides = collides
        self.obs_at = obs_at

    def perturbation(self, interaction: Sketch | Nudge) -> np.ndarray:
        """The state the agent is moved to for ``interaction``."""
        if isinstance(interaction, Nudge):
            return np.array(interaction.states[-1])
        return output_perturbation_point(interaction, self.index, self.collides)

    def _run(self, policy: Any, obs: Any, interaction: Any, n: int, rng: np.random.Generator) -> Any:
        target = self.perturbation(interaction)
        new_obs = (self.obs_at or place_observation)(obs, target)
        plans = check_plans(policy.sample(new_obs, n, generator=rng), n, policy, "policy.sample")
        if isinstance(interaction, Nudge):
            pick = int(rng.integers(n))
            return plans, lambda costs: pick, {}, target
        return plans, argmin_choice, {}, target
