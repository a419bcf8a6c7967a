"""BI, GD and SS in a flow-matching policy's own form, and the unguided Euler loop (:func:`integrate_plans`).

A :class:`~steer_envs.core.policy.FlowPolicyLike` carries noise ``x_0 ~ N(0, I)``
at ``tau = 0`` to a normalized plan at ``tau = 1`` along its velocity field
(rectified flow: ``x_tau = tau x_1 + (1 - tau) x_0``, ``v = x_1 - x_0``) in
``K = num_inference_steps`` Euler steps, ``tau_k = k / K``,
``x <- x + v(x, tau_k) / K``. At ``(x, tau)`` the flow implies a clean plan
``x1_hat = x + (1 - tau) v`` and a noise ``eps = x - tau v``.

* **GD**: ITPS guides the noise estimate, ``eps_hat = eps + beta grad xi(x)``.
  Holding ``x`` fixed, the velocity that implies ``eps_hat`` is
  ``v_hat = (x - eps_hat) / tau = v - (beta / tau) grad xi(x)``; the Euler step
  uses ``v_hat``. The first step (``tau = 0``, where every ``x`` is pure noise
  and no velocity implies a different noise) would divide by zero, so ``tau``
  is floored at the step size ``1 / K`` there: ``v_hat = v - beta K grad xi``.
  Step ``k`` counts as DDIM's step ``t_k = T (K - 1 - k) / K`` (the level it
  lands on; ``T``: :func:`train_timesteps`) and is guided where
  ``t_k > min_guided_t``: the same steps as a DDPM's, so the default 0 leaves
  the last step, which lands on the plan, unguided as ITPS does (guided, it
  would push every plan off the data by ``beta / (K - 1) grad xi`` with no
  step left to correct it).
* **SS**: ``M`` iterations per Euler step; the first ``M - 1`` re-noise the
  guided clean estimate ``x1_hat = x + (1 - tau) v_hat`` to the same ``tau``
  with fresh noise, ``x = tau x1_hat + (1 - tau) z``; the last takes the Euler
  step with ``v_hat``.
* **BI**: start at ``tau_start = 1 - start_t / T`` from the interaction's
  trajectory plus ``init_std * N(0, I)`` and take the Euler steps with
  ``tau_k >= tau_start``, unguided (DP's ``start_t = 50`` of ``T = 100``:
  ``tau_start = 0.5``).

Noise comes from the numpy generator as in
:mod:`~steer_envs.steering.diffusion` (float32 draws for float32 policies), so
GD with ``guide_ratio = 0`` gives RS's plans for a policy whose ``sample`` is
:func:`integrate_plans` (or draws and integrates alike). A flow has no
clipping, so ``use_clipped_model_output`` changes nothing. The classes
:class:`~steer_envs.steering.BiasedInitialization`,
:class:`~steer_envs.steering.GuidedDiffusion` and
:class:`~steer_envs.steering.StochasticSampling` call :func:`guided_plans` and
:func:`biased_plans` for a flow policy; the guidance objective is theirs
(:class:`~steer_envs.steering.diffusion.NormalizedObjective`).

>>> import numpy as np, torch
>>> class ToOne:  # every plan is all ones: v = 1 - x0 = (1 - x) / (1 - tau)
...     horizon, action_dim, num_inference_steps, device = 4, 2, 5, torch.device("cpu")
...     def encode_obs(self, obs): return None
...     def predict_velocity(self, x, tau, cond): return (1 - x) / (1 - tau)
...     def normalize(self, traj): return traj
...     def unnormalize(self, traj): return traj
...     def sample(self, obs, n, *, generator=None): return integrate_plans(self, obs, n, generator)
>>> ToOne().sample(None, 3, generator=np.random.default_rng(0)).round(6).max()
1.0
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
import torch

from steer_envs.core.policy import DiffusionPolicyLike, FlowPolicyLike
from steer_envs.core.validation import describe, integer, real_scalar
from steer_envs.steering.base import (
    MAX_DENOISING_STEPS,
    MAX_MCMC_STEPS,
    check_batch,
    check_generator,
    finish_plans,
    initial_noise,
)
from steer_envs.steering.costs import WeightedCosts

__all__ = [
    "DEFAULT_TRAIN_TIMESTEPS",
    "FlowObjective",
    "biased_plans",
    "guided_plans",
    "integrate_plans",
    "is_flow_policy",
    "plan_dtype",
    "train_timesteps",
]

#: ``T`` when the policy names none: the diffusion steps BI's ``start_t`` and GD's ``min_guided_t`` count in
DEFAULT_TRAIN_TIMESTEPS = 100


class FlowObjective(Protocol):
    """What the guided flow forms need of an objective ``xi`` (in the policy's normalized space).

    :class:`~steer_envs.steering.diffusion.NormalizedObjective` is one.
    """

    def grad(self, x: torch.Tensor) -> torch.Tensor:
        """``grad_x sum_b xi(x_b)``, the shape of ``x`` ``(n, H, d)``."""
        ...

    def as_trajectory(self, horizon: int) -> torch.Tensor:
        """The interaction as a ``(H, d)`` trajectory (BI's start)."""
        ...


def is_flow_policy(policy: Any) -> bool:
    """Whether BI/GD/SS run the flow form for ``policy``: a ``FlowPolicyLike`` that is no ``DiffusionPolicyLike``."""
    return isinstance(policy, FlowPolicyLike) and not isinstance(policy, DiffusionPolicyLike)


def plan_dtype(policy: Any) -> torch.dtype:
    """``policy.dtype`` when it is a floating torch dtype, else float32 (the integrated tensor's dtype)."""
    dtype = getattr(policy, "dtype", torch.float32)
    return dtype if isinstance(dtype, torch.dtype) and dtype.is_floating_point else torch.float32


def train_timesteps(policy: Any) -> int:
    """``T``: ``policy.num_train_timesteps``, else ``policy.config.num_train_timesteps``, else 100.

    The diffusion steps a DDPM counts in: BI's ``start_t`` starts the flow at
    ``tau = 1 - start_t / T`` and GD's ``min_guided_t`` guides where ``T (1 - tau) > min_guided_t``.
    """
    value = getattr(policy, "num_train_timesteps", None)
    if value is None:
        value = getattr(getattr(policy, "config", None), "num_train_timesteps", None)
    if value is None:
        return DEFAULT_TRAIN_TIMESTEPS
    return integer(value, "policy.num_train_timesteps", low=1)


def _setup(policy: Any, obs: Any) -> tuple[Any, int, int, torch.dtype]:
    """``(cond, K, horizon, dtype)`` of one call."""
    steps = integer(policy.num_inference_steps, "policy.num_inference_steps", low=1, high=MAX_DENOISING_STEPS)
    horizon = int(getattr(policy, "diffusion_horizon", policy.horizon))
    with torch.no_grad():
        cond = policy.encode_obs(obs)
    return cond, steps, horizon, plan_dtype(policy)


def _velocity(policy: Any, x: torch.Tensor, tau: float, cond: Any) -> torch.Tensor:
    """``v(x, tau | cond)`` (no gradient), checked: a tensor of ``x``'s shape."""
    with torch.no_grad():
        v = policy.predict_velocity(x, tau, cond)
    if not isinstance(v, torch.Tensor) or v.shape != x.shape:
        got = tuple(v.shape) if isinstance(v, torch.Tensor) else describe(v)
        raise ValueError(f"policy.predict_velocity must return a tensor of shape {tuple(x.shape)}, got {got}")
    return v.to(x.dtype)


def integrate_plans(policy: FlowPolicyLike, obs: Any, n: int, generator: np.random.Generator | None) -> np.ndarray:
    """``n`` unsteered plans ``(n, H, d)`` in env units: ``K`` Euler steps from the generator's noise.

    ``tau_k = k / K``, ``x <- x + v(x, tau_k) / K`` for ``k = 0 .. K - 1`` from a
    float32 (float64 for float64 policies) standard normal draw of ``generator``,
    exactly as BI/GD/SS draw: a flow policy whose ``sample`` calls this gives
    RS the plans GD gives with ``guide_ratio=0``. ``None`` draws fresh noise.
    """
    n = check_batch(n)
    rng = check_generator(generator)
    cond, steps, horizon, dtype = _setup(policy, obs)
    x = initial_noise(rng, (n, horizon, int(policy.action_dim)), dtype, policy.device)
    for k in range(steps):
        x = x + _velocity(policy, x, k / steps, cond) / steps
    return finish_plans(policy, x, n)


def guided_plans(
    policy: FlowPolicyLike,
    obs: Any,
    objective: FlowObjective,
    n: int,
    generator: np.random.Generator,
    *,
    guide_ratio: float,
    mcmc_steps: int = 1,
    min_guided_t: int = 0,
    costs: WeightedCosts | None = None,
) -> tuple[np.ndarray, int]:
    """GD (``mcmc_steps=1``) or SS of a flow policy: ``(plans (n, H, d) in env units, network evaluations)``.

    Every Euler step ``k`` with ``T (K - 1 - k) / K > min_guided_t`` (all but the last for 0) uses
    ``v_hat = v - guide_ratio / max(tau_k, 1 / K) * objective.grad(x)`` (the
    velocity implying ITPS's ``eps_hat = eps + guide_ratio * grad``); with
    ``mcmc_steps = M > 1`` the first ``M - 1`` iterations of a step re-noise
    ``x + (1 - tau_k) v_hat`` to ``tau_k`` with fresh noise from ``generator``
    and the last takes the step ``x + v_hat / K``. ``costs`` (plan costs,
    :mod:`~steer_envs.steering.costs`) shift the clean estimate
    ``x1 = x + (1 - tau) v_hat`` by ``-grad costs(x1)`` at every step:
    ``v_hat - grad / (1 - tau)``.
    """
    beta = real_scalar(guide_ratio, "`guide_ratio`", low=0.0)
    inner = integer(mcmc_steps, "`mcmc_steps`", low=1, high=MAX_MCMC_STEPS)
    min_t = integer(min_guided_t, "`min_guided_t`")
    big_t = train_timesteps(policy)
    cond, steps, horizon, dtype = _setup(policy, obs)
    shape = (n, horizon, int(policy.action_dim))
    x = initial_noise(generator, shape, dtype, policy.device)
    evals = 0
    for k in range(steps):
        tau = k / steps
        # DDIM numbers this step t_k = T (K - 1 - k) / K (the level it lands on): guided where t_k > min_guided_t
        guided = beta > 0 and big_t * (steps - 1 - k) > min_t * steps
        scale = beta / max(tau, 1.0 / steps) if guided else 0.0
        for j in range(inner):
            v = _velocity(policy, x, tau, cond)
            evals += 1
            if scale:
                v = v - scale * objective.grad(x).to(v.dtype)
            if costs:
                v = v - costs.grad(policy, x + (1 - tau) * v).to(v.dtype) / (1 - tau)
            if j < inner - 1:
                clean = x + (1 - tau) * v
                x = tau * clean + (1 - tau) * initial_noise(generator, shape, dtype, policy.device)
            else:
                x = x + v / steps
    return finish_plans(policy, x, n), evals


def biased_plans(
    policy: FlowPolicyLike,
    obs: Any,
    objective: FlowObjective,
    n: int,
    generator: np.random.Generator,
    *,
    start_t: int,
    init_std: float,
) -> tuple[np.ndarray, int]:
    """BI of a flow policy: ``(plans (n, H, d) in env units, network evaluations)``.

    ``x = objective.as_trajectory(H) + init_std * N(0, I)``, then the Euler steps
    with ``tau_k >= 1 - start_t / T``, unguided (none when ``start_t = 0``: the
    noised interaction is the plan; all ``K`` when ``start_t >= T``).
    """
    start = integer(start_t, "`start_t`", low=0)
    std = real_scalar(init_std, "`init_std`", low=0.0)
    big_t = train_timesteps(policy)
    cond, steps, horizon, dtype = _setup(policy, obs)
    shape = (n, horizon, int(policy.action_dim))
    init = objective.as_trajectory(horizon).to(dtype)
    x = init.unsqueeze(0) + std * initial_noise(generator, shape, dtype, policy.device)
    evals = 0
    for k in range(steps):
        if k * big_t < (big_t - start) * steps:  # tau_k < 1 - start_t / T, in integers
            continue
        x = x + _velocity(policy, x, k / steps, cond) / steps
        evals += 1
    return finish_plans(policy, x, n), evals
