"""The samplers by their thesis abbreviations: :data:`SAMPLERS` and :func:`make_sampler`."""

from __future__ import annotations

import inspect
from typing import Any

from steer_envs.core.validation import describe
from steer_envs.steering.base import Sampler
from steer_envs.steering.diffusion import BiasedInitialization, GuidedDiffusion, StochasticSampling
from steer_envs.steering.ranking import OutputPerturbation, PostHocRanking, RandomSampling

__all__ = ["SAMPLERS", "make_sampler"]


#: short name -> sampler class (thesis abbreviations)
SAMPLERS: dict[str, type[Sampler]] = {
    "RS": RandomSampling,
    "PR": PostHocRanking,
    "OP": OutputPerturbation,
    "BI": BiasedInitialization,
    "GD": GuidedDiffusion,
    "SS": StochasticSampling,
}


def make_sampler(name: str, **kwargs: Any) -> Sampler:
    """The sampler called ``name`` (``"RS"``, ``"PR"``, ``"OP"``, ``"BI"``, ``"GD"``, ``"SS"``, any case).

    ``kwargs`` go to the sampler's constructor, but ``costs``: plan costs
    added to the alignment (:meth:`~steer_envs.steering.base.Sampler.with_costs`).

    >>> import numpy as np
    >>> from steer_envs.core.interaction import Sketch
    >>> class Noisy:  # a stand-in TrajectoryPolicy: noisy straight plans from the origin to (1, 1)
    ...     horizon, action_dim = 8, 2
    ...     def sample(self, obs, n, *, generator=None):
    ...         plan = np.linspace([0.0, 0.0], [1.0, 1.0], self.horizon)
    ...         return plan + generator.normal(0.0, 0.05, (n, self.horizon, 2))
    >>> sampler = make_sampler("pr")
    >>> result = sampler(Noisy(), np.zeros(2), Sketch([[0, 0], [1, 1]]), 4, generator=np.random.default_rng(0))
    >>> result.sampler, result.plans.shape, result.chosen == int(np.argmin(result.costs))
    ('PR', (4, 8, 2), True)
    >>> make_sampler("GD", guide_ratio=10.0)
    GuidedDiffusion(guide_ratio=10.0, min_guided_t=0, use_clipped_model_output=False)
    """
    if not isinstance(name, str):
        raise TypeError(f"make_sampler: `name` must be a str, one of {sorted(SAMPLERS)}, got {describe(name)}")
    if name.upper() not in SAMPLERS:
        raise ValueError(f"make_sampler: `name` must be one of {sorted(SAMPLERS)}, got {name!r}")
    cls = SAMPLERS[name.upper()]
    if "costs" in kwargs:
        costs = kwargs.pop("costs")
        return make_sampler(name, **kwargs).with_costs(costs)
    accepted = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
    unknown = sorted(set(kwargs) - set(accepted))
    if unknown:
        raise TypeError(
            f"make_sampler: {cls.__name__} ({name.upper()}) takes {accepted or 'no arguments'}, got {unknown}"
        )
    return cls(**kwargs)
