"""ITPS, inference-time policy steering (thesis ch. 2): six samplers that bias a frozen policy toward a user's input.

Every sampler is a strategy object with one call::

    result = sampler(policy, obs, interaction, n, generator=rng)   # -> SteeringResult

``result.plans`` is the batch ``(n, H, d)`` in env units, ``result.costs`` the
alignment cost ``xi`` of every plan (env units, :mod:`~steer_envs.steering.objectives`),
``result.chosen`` the index of the plan the sampler picks and ``result.timings``
the wall time (and network evaluations of the diffusion samplers).
:class:`~steer_envs.wrappers.SteeringWrapper` turns an env into one driven
by interactions with a sampler inside.

=====  ============================  =============================================  ======================
name   class                         needs                                          interactions
=====  ============================  =============================================  ======================
RS     :class:`RandomSampling`       ``TrajectoryPolicy.sample``                    any (or ``None``)
PR     :class:`PostHocRanking`       ``TrajectoryPolicy.sample``                    Point, Sketch
OP     :class:`OutputPerturbation`   ``TrajectoryPolicy.sample``                    Sketch, Nudge
BI     :class:`BiasedInitialization` ``DiffusionPolicyLike`` / ``FlowPolicyLike``   Point, Sketch
GD     :class:`GuidedDiffusion`      ``DiffusionPolicyLike`` / ``FlowPolicyLike``   Point, Sketch
SS     :class:`StochasticSampling`   ``DiffusionPolicyLike`` / ``FlowPolicyLike``   Point, Sketch
=====  ============================  =============================================  ======================

Hyperparameters default to the public ITPS code:
GD adds ``20 * grad xi`` to the noise estimate at every step ``t > 0``; SS runs
``M = 4`` iterations per noise level with ``60 * grad xi``, the first ``M - 1``
predicting ``x0`` (clipped) and re-noising it to the *same* level with fresh
noise (``scheduler.add_noise``), the last a normal DDIM step (thesis Algorithm 1);
BI starts at ``t = 50`` from the sketch plus ``0.5 N(0, I)`` and denoises without
guidance; OP moves the agent onto the sketch's 20th point (or the last point
before the sketch's first collision) and ranks fresh samples from there like PR;
PR ranks by the mean L2 to the sketch; RS takes a random plan of the same batch
PR ranks (same generator state -> same batch). Guidance gradients are taken in
the policy's normalized space; ranking costs in env units. Given a
flow-matching policy (``FlowPolicyLike``), BI, GD and SS take the same
arguments and run the flow's own form (:mod:`~steer_envs.steering.flow`: the
guided velocity ``v - (beta / tau) grad xi``, SS re-noising to the same flow
time, BI starting at ``tau = 1 - start_t / T``).

Every sampler except RS (and OP given a Nudge, whose fresh plans all satisfy
it) returns the batch's minimum-cost plan as ``chosen``, so "the chosen plan's
distance" is Table 2.1's *Min L2* (for RS it is a random plan's distance, which
is why RS's Min L2 ~ its Avg L2 there).

Noise comes from the numpy ``generator`` (float32 draws for float32 policies),
so a diffusion sampler with zero guidance reproduces the policy's own
``sample`` for the same generator state when that draws its initial noise the
same way (``steer_envs.baselines.diffusion.modeling`` does): RS, PR, BI, GD and SS of
one seed start from the same noise, as in ITPS.

Optional policy members: ``dtype`` (torch dtype of the denoised tensor, default
float32); ``diffusion_horizon`` and ``extract_plan(traj)`` for policies whose
denoised tensor is longer than the plan they return (length of the tensor,
default ``policy.horizon``; unnormalized ``(n, T, d)`` -> ``(n, H, d)``, default
identity). Guidance always acts on the whole denoised tensor, as in ITPS.

Modules:

* :mod:`~steer_envs.steering.base` - :class:`Sampler`, :class:`SteeringResult`, shared checks;
* :mod:`~steer_envs.steering.observations` - what a policy observes (stacked histories, a moved agent);
* :mod:`~steer_envs.steering.ranking` - RS, PR, OP;
* :mod:`~steer_envs.steering.diffusion` - BI, GD, SS;
* :mod:`~steer_envs.steering.flow` - their flow-matching forms and the unguided Euler loop
  :func:`~steer_envs.steering.flow.integrate_plans`;
* :mod:`~steer_envs.steering.registry` - :data:`SAMPLERS`, :func:`make_sampler`;
* :mod:`~steer_envs.steering.objectives` - the alignment costs ``xi(tau, z)`` (torch, differentiable);
* :mod:`~steer_envs.steering.latency` - :func:`benchmark_latency`;
* :mod:`~steer_envs.steering.maze` - one steering call in Maze2D, scored as thesis Table 2.1;
* :mod:`~steer_envs.steering.blockstack` - building a tower by sketches (Table 2.2), probing a skill policy;
* :mod:`~steer_envs.steering.kitchen` - a clicked Kitchen rollout (Table 2.3), the guide-ratio sweep (Fig. 2.10);
* :mod:`~steer_envs.steering.study` - held-out scenes and the aligned / successful quadrants of a user study.

The robosuite modules (``blockstack``, ``kitchen``) are not imported here.

>>> import numpy as np
>>> from steer_envs.core.interaction import Sketch
>>> class Straight:  # a stand-in TrajectoryPolicy: noisy straight plans from the origin to (1, 1)
...     horizon, action_dim = 8, 2
...     def sample(self, obs, n, *, generator=None):
...         return np.linspace([0.0, 0.0], [1.0, 1.0], 8) + generator.normal(0.0, 0.05, (n, 8, 2))
>>> result = PostHocRanking()(Straight(), np.zeros(2), Sketch([[0, 0], [1, 1]]), 4, generator=np.random.default_rng(0))
>>> result.sampler, result.plan.shape
('PR', (8, 2))
"""

from __future__ import annotations

from steer_envs.steering.base import (
    MAX_BATCH,
    MAX_DENOISING_STEPS,
    MAX_MCMC_STEPS,
    Sampler,
    SteeringResult,
    interaction_dims,
)
from steer_envs.steering.diffusion import BiasedInitialization, GuidedDiffusion, StochasticSampling
from steer_envs.steering.latency import benchmark_latency
from steer_envs.steering.objectives import (
    alignment_cost,
    alignment_cost_np,
    apply_nudge,
    nudge_cost,
    point_cost,
    resample_path_torch,
    sketch_cost,
)
from steer_envs.steering.observations import place_observation, policy_observation
from steer_envs.steering.ranking import OutputPerturbation, PostHocRanking, RandomSampling, output_perturbation_point
from steer_envs.steering.registry import SAMPLERS, make_sampler

__all__ = [
    "MAX_BATCH",
    "MAX_DENOISING_STEPS",
    "MAX_MCMC_STEPS",
    "SAMPLERS",
    "BiasedInitialization",
    "GuidedDiffusion",
    "OutputPerturbation",
    "PostHocRanking",
    "RandomSampling",
    "Sampler",
    "SteeringResult",
    "StochasticSampling",
    "alignment_cost",
    "alignment_cost_np",
    "apply_nudge",
    "benchmark_latency",
    "interaction_dims",
    "make_sampler",
    "nudge_cost",
    "output_perturbation_point",
    "place_observation",
    "point_cost",
    "policy_observation",
    "resample_path_torch",
    "sketch_cost",
]
