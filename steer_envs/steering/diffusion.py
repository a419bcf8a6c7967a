"""The samplers that steer the denoising of a diffusion policy: BI, GD and SS (thesis §2.3, Algorithm 1).

They need a :class:`~steer_envs.core.policy.DiffusionPolicyLike` with a
DDPM/DDIM-style scheduler; the network may predict the noise, the clean plan
or ``v`` (:mod:`~steer_envs.steering.schedulers` converts, and refuses
schedulers it cannot be correct for). Given a
:class:`~steer_envs.core.policy.FlowPolicyLike` instead (and no
``DiffusionPolicyLike``: a policy that is both is denoised), the same classes,
with the same arguments, run the flow's own form of BI, GD and SS
(:mod:`~steer_envs.steering.flow`). Guidance gradients are taken in the
policy's normalized space (:class:`NormalizedObjective`); the initial noise
comes from the numpy generator and a stochastic scheduler step's noise from a
torch generator seeded by it, so with zero guidance they reproduce
:func:`denoise_plans` (and a policy's own ``sample`` that draws alike) for the
same generator state.
"""

from __future__ import annotations

import inspect
from typing import Any

import numpy as np
import torch

from steer_envs.core.interaction import Point, Sketch
from steer_envs.core.policy import DiffusionPolicyLike, FlowPolicyLike
from steer_envs.core.validation import describe, integer, real_scalar
from steer_envs.steering.base import (
    MAX_DENOISING_STEPS,
    MAX_MCMC_STEPS,
    Sampler,
    argmin_choice,
    finish_plans,
    initial_noise,
    interaction_dims,
)
from steer_envs.steering.costs import WeightedCosts
from steer_envs.steering.flow import biased_plans, guided_plans, is_flow_policy, plan_dtype
from steer_envs.steering.objectives import point_cost, resample_path_torch, sketch_cost
from steer_envs.steering.schedulers import check_scheduler, from_epsilon, step_generator, to_epsilon

__all__ = ["BiasedInitialization", "GuidedDiffusion", "NormalizedObjective", "StochasticSampling", "denoise_plans"]


class NormalizedObjective:
    """``xi`` of a Point/Sketch mapped into the policy's normalized space, with its gradient."""

    def __init__(
        self, policy: DiffusionPolicyLike | FlowPolicyLike, interaction: Point | Sketch, dtype: torch.dtype
    ) -> None:
        data = interaction.target if isinstance(interaction, Point) else interaction.points
        self.dims = interaction_dims(policy)
        self.action_dim = int(policy.action_dim)
        full = np.zeros((*data.shape[:-1], self.action_dim))
        full[..., list(self.dims)] = data
        normalized = np.asarray(policy.normalize(full), dtype=np.float64)
        if normalized.shape != full.shape or not np.all(np.isfinite(normalized)):
            raise ValueError(f"policy.normalize must map {full.shape} to finite {full.shape}, got {normalized.shape}")
        normalized = normalized[..., list(self.dims)]
        self.is_point = isinstance(interaction, Point)
        self.target = torch.as_tensor(normalized, dtype=dtype, device=policy.device)
        self._goals: dict[int, torch.Tensor] = {}

    def _view(self, x: torch.Tensor) -> torch.Tensor:
        return x if len(self.dims) == self.action_dim else x[..., list(self.dims)]

    def cost(self, x: torch.Tensor) -> torch.Tensor:
        view = self._view(x)
        return point_cost(view, self.target) if self.is_point else sketch_cost(view, self.target)

    def grad(self, x: torch.Tensor) -> torch.Tensor:
        """``grad_x sum_b xi(x_b)``: each plan's own gradient (plans do not interact).

        In closed form (what autograd gives for the mean of per-step L2
        distances, ~6x cheaper on CPU): ``(x_h - g_h) / (H ||x_h - g_h||)`` per
        step, 0 where a step sits on its goal.
        """
        view = self._view(x.detach())
        horizon = view.shape[1]
        goal = self._goals.get(horizon)
        if goal is None:
            goal = self.target.expand(horizon, -1) if self.is_point else resample_path_torch(self.target, horizon)
            goal = self._goals[horizon] = goal.to(view.dtype)
        diff = view - goal
        dist = torch.linalg.vector_norm(diff, dim=-1, keepdim=True)
        g = torch.where(dist > 0, diff / dist.clamp_min(torch.finfo(diff.dtype).tiny), 0.0) / horizon
        if len(self.dims) == self.action_dim:
            return g
        full = torch.zeros_like(x)
        full[..., list(self.dims)] = g
        return full

    def as_trajectory(self, horizon: int) -> torch.Tensor:
        """The interaction as a ``(H, d)`` trajectory (a point repeated, a sketch resampled in index)."""
        part = self.target.expand(horizon, -1).clone() if self.is_point else resample_path_torch(self.target, horizon)
        if len(self.dims) == self.action_dim:
            return part
        out = torch.zeros(horizon, self.action_dim, dtype=part.dtype, device=part.device)
        out[:, list(self.dims)] = part
        return out


class _DiffusionSampler(Sampler):
    """Shared denoising loop of BI, GD and SS (a DDPM/DDIM-style scheduler, any prediction type)."""

    requires_diffusion = True

    def _setup(self, policy: Any, obs: Any, interaction: Any) -> tuple[Any, Any, int, torch.dtype]:
        check_scheduler(policy.scheduler, type(self).__name__)
        objective = NormalizedObjective(policy, interaction, plan_dtype(policy))
        cond, horizon, dtype = _prepare(policy, obs, type(self).__name__)
        return objective, cond, horizon, dtype

    # float32 draws for float32 policies: the same stream a policy's own sampler draws (same initial noise as RS)
    _noise = staticmethod(initial_noise)
    _finish = staticmethod(finish_plans)

    @staticmethod
    def _eps(policy: Any, x: torch.Tensor, t: Any, cond: Any) -> torch.Tensor:
        return _noise_estimate(policy, x, t, cond)

    @staticmethod
    def _objective(policy: Any, interaction: Any) -> NormalizedObjective:
        """The guidance objective of a flow policy (in its dtype)."""
        return NormalizedObjective(policy, interaction, plan_dtype(policy))


def _check_ratio(value: Any, name: str) -> float:
    return real_scalar(value, f"`{name}`", low=0.0)


class GuidedDiffusion(_DiffusionSampler):
    """GD: ``eps_hat = eps + guide_ratio * grad xi(x_t)`` at every step with ``t > min_guided_t``, then DDIM.

    Args:
        guide_ratio: ``beta`` (ITPS maze: 20).
        min_guided_t: guidance is applied where ``t > min_guided_t`` (ITPS: 0, i.e.
            every step but the last). Raising it switches guidance off for the late,
            low-noise steps (thesis block stacking: "GD (beta_{i<50} = 0)").
        use_clipped_model_output: the DDIM step re-derives the noise from the
            *clipped* clean-plan estimate (diffusers' ``use_clipped_model_output``)
            instead of reusing ``eps_hat`` (ITPS's code: False, the default). With a
            clipping scheduler and a guidance push that carries the estimate past the
            clip range, reusing ``eps_hat`` moves ``x_t`` *along* the cost gradient,
            away from the user's input; re-deriving it keeps the step consistent.
            Needs a scheduler whose ``step`` takes that argument (DDIM does).

    For a flow policy (:mod:`~steer_envs.steering.flow`): every Euler step with
    ``T (1 - tau) > min_guided_t`` integrates ``v - guide_ratio / max(tau, 1 / K) * grad xi(x)``,
    the velocity implying the guided noise; ``use_clipped_model_output`` changes nothing (no clipping).
    """

    name = "GD"
    #: inner iterations per noise level (SS overrides)
    mcmc_steps: int = 1

    def __init__(
        self, guide_ratio: float = 20.0, min_guided_t: int = 0, use_clipped_model_output: bool = False
    ) -> None:
        self.guide_ratio = _check_ratio(guide_ratio, "guide_ratio")
        self.min_guided_t = integer(min_guided_t, "`min_guided_t`")
        if not isinstance(use_clipped_model_output, (bool, np.bool_)):
            raise TypeError(f"`use_clipped_model_output` must be a bool, got {describe(use_clipped_model_output)}")
        self.use_clipped_model_output = bool(use_clipped_model_output)

    def _guided_eps(self, policy: Any, objective: Any, x: torch.Tensor, t: Any, cond: Any) -> torch.Tensor:
        eps = self._eps(policy, x, t, cond)
        if self.guide_ratio > 0 and int(t) > self.min_guided_t:
            eps = eps + self.guide_ratio * objective.grad(x).to(eps.dtype)
        if self._costs:
            eps = _cost_shifted(self._costs, policy, x, eps, t)
        return eps

    def _run(self, policy: Any, obs: Any, interaction: Any, n: int, rng: np.random.Generator) -> Any:
        if is_flow_policy(policy):
            # no clipping in a flow: use_clipped_model_output changes nothing there
            plans, evals = guided_plans(
                policy,
                obs,
                self._objective(policy, interaction),
                n,
                rng,
                guide_ratio=self.guide_ratio,
                mcmc_steps=self.mcmc_steps,
                min_guided_t=self.min_guided_t,
                costs=self._costs,
            )
            return plans, argmin_choice, {"network_evals": float(evals)}, None
        objective, cond, horizon, dtype = self._setup(policy, obs, interaction)
        scheduler = policy.scheduler
        shape = (n, horizon, int(policy.action_dim))
        x = self._noise(rng, shape, dtype, policy.device)
        step_kwargs = {**self._step_kwargs(scheduler), **step_generator(scheduler, rng, x.device)}
        evals = 0
        for t in scheduler.timesteps:
            for j in range(self.mcmc_steps):
                eps = self._guided_eps(policy, objective, x, t, cond)
                evals += 1
                if j < self.mcmc_steps - 1:
                    x = self._renoise(scheduler, x, eps, t, self._noise(rng, shape, dtype, policy.device))
                else:
                    x = scheduler.step(from_epsilon(eps, x, t, scheduler), t, x, **step_kwargs).prev_sample
        return self._finish(policy, x, n), argmin_choice, {"network_evals": float(evals)}, None

    def _step_kwargs(self, scheduler: Any) -> dict[str, Any]:
        if not self.use_clipped_model_output:
            return {}
        try:
            accepted = "use_clipped_model_output" in inspect.signature(scheduler.step).parameters
        except (TypeError, ValueError):
            accepted = False
        if not accepted:
            raise ValueError(
                f"{type(self).__name__}(use_clipped_model_output=True) needs a scheduler whose step() takes "
                f"`use_clipped_model_output` (diffusers' DDIMScheduler), got {type(scheduler).__name__}"
            )
        return {"use_clipped_model_output": True}

    @staticmethod
    def _renoise(scheduler: Any, x: torch.Tensor, eps: torch.Tensor, t: Any, z: torch.Tensor) -> torch.Tensor:
        """Predict ``x0`` from ``(x_t, eps_hat)`` (clipped as the scheduler clips); noise it back to level ``t``."""
        abar, x0 = _clean_estimate(scheduler, x, eps, t)
        if hasattr(scheduler, "add_noise"):
            level = torch.full((x.shape[0],), int(t), dtype=torch.long, device=x.device)
            return scheduler.add_noise(x0, z, level).to(x.dtype)
        return abar.sqrt() * x0 + (1 - abar).sqrt() * z


class StochasticSampling(GuidedDiffusion):
    """SS (thesis Algorithm 1): GD with ``M`` iterations per noise level; ``M - 1`` re-noise to the same level.

    Each inner iteration ``j < M`` predicts the clean plan ``x0`` from the guided
    noise estimate and re-noises it to level ``t`` with fresh noise (annealed
    ULA-style MCMC at that level, Du et al. 2023); iteration ``M`` is the normal
    DDIM step to the next level. ``M`` times the network evaluations of GD.

    Args:
        guide_ratio: ``beta`` (ITPS maze: 60).
        mcmc_steps: ``M`` (ITPS: 4).
        min_guided_t, use_clipped_model_output: as in :class:`GuidedDiffusion`.

    For a flow policy the ``M - 1`` iterations re-noise the guided clean plan
    ``x + (1 - tau) v_hat`` to the same flow time ``tau`` (:mod:`~steer_envs.steering.flow`).
    """

    name = "SS"

    def __init__(
        self,
        guide_ratio: float = 60.0,
        mcmc_steps: int = 4,
        min_guided_t: int = 0,
        use_clipped_model_output: bool = False,
    ) -> None:
        super().__init__(guide_ratio, min_guided_t, use_clipped_model_output)
        self.mcmc_steps = integer(mcmc_steps, "`mcmc_steps`", low=1, high=MAX_MCMC_STEPS)


class BiasedInitialization(_DiffusionSampler):
    """BI: start denoising at ``t = start_t`` from the user's input plus ``init_std * N(0, I)``; no guidance.

    The interaction (a sketch resampled to the horizon uniformly in index, or a
    point repeated) is mapped to normalized space; steps with ``t > start_t`` are
    skipped (ITPS: ``start_t = 50``, ``init_std = 0.5``: 6 of 10 DDIM steps). A flow
    policy starts at ``tau = 1 - start_t / T`` (``T``: its ``num_train_timesteps``, else
    100) and takes the Euler steps from there (:mod:`~steer_envs.steering.flow`; 5 of 10).
    """

    name = "BI"

    def __init__(self, start_t: int = 50, init_std: float = 0.5) -> None:
        self.start_t = integer(start_t, "`start_t`", low=0)
        self.init_std = _check_ratio(init_std, "init_std")

    def _run(self, policy: Any, obs: Any, interaction: Any, n: int, rng: np.random.Generator) -> Any:
        if is_flow_policy(policy):
            objective = self._objective(policy, interaction)
            plans, evals = biased_plans(policy, obs, objective, n, rng, start_t=self.start_t, init_std=self.init_std)
            return plans, argmin_choice, {"network_evals": float(evals)}, None
        objective, cond, horizon, dtype = self._setup(policy, obs, interaction)
        scheduler = policy.scheduler
        shape = (n, horizon, int(policy.action_dim))
        init = objective.as_trajectory(horizon).to(dtype)
        x = init.unsqueeze(0) + self.init_std * self._noise(rng, shape, dtype, policy.device)
        step_kwargs = step_generator(scheduler, rng, x.device)
        evals = 0
        for t in scheduler.timesteps:
            if int(t) > self.start_t:
                continue
            eps = self._eps(policy, x, t, cond)
            x = scheduler.step(from_epsilon(eps, x, t, scheduler), t, x, **step_kwargs).prev_sample
            evals += 1
        return self._finish(policy, x, n), argmin_choice, {"network_evals": float(evals)}, None


def _cost_shifted(costs: WeightedCosts, policy: Any, x: torch.Tensor, eps: torch.Tensor, t: Any) -> torch.Tensor:
    """``eps`` changed so that the clean plan it implies moves by ``-grad costs`` (taken at that plan).

    A plan cost (a wall, a region) is a function of the *plan*: on the noisy
    ``x_t`` it says little (at high noise every sample crosses walls), so it is
    evaluated on the clean estimate ``x0 = (x_t - sqrt(1 - abar) eps) /
    sqrt(abar)`` (clipped as the scheduler clips) and ``x0`` is shifted by
    ``delta = -grad``: ``eps + sqrt(abar) / sqrt(1 - abar) * grad`` implies ``x0 + delta``.
    """
    abar, x0 = _clean_estimate(policy.scheduler, x, eps, t)
    a, s = abar.sqrt(), (1 - abar).sqrt().clamp_min(torch.finfo(x.dtype).eps)
    return eps + (a / s) * costs.grad(policy, x0).to(eps.dtype)


def _clean_estimate(scheduler: Any, x: torch.Tensor, eps: torch.Tensor, t: Any) -> tuple[torch.Tensor, torch.Tensor]:
    """``(abar_t, x0)``: the clean plan ``(x_t - sqrt(1 - abar) eps) / sqrt(abar)``, clipped as the scheduler clips."""
    abar = torch.as_tensor(scheduler.alphas_cumprod[int(t)], dtype=x.dtype, device=x.device)
    x0 = (x - (1 - abar).sqrt() * eps) / abar.sqrt()
    config = getattr(scheduler, "config", None)
    if config is not None and getattr(config, "clip_sample", False):
        bound = float(getattr(config, "clip_sample_range", 1.0))
        x0 = x0.clamp(-bound, bound)
    return abar, x0


def _prepare(policy: Any, obs: Any, who: str) -> tuple[Any, int, torch.dtype]:
    """``(condition, diffusion horizon, dtype)`` of a denoising loop, the scheduler's timesteps set."""
    horizon = int(getattr(policy, "diffusion_horizon", policy.horizon))
    with torch.no_grad():
        cond = policy.encode_obs(obs)
    _set_timesteps(policy, who)
    return cond, horizon, plan_dtype(policy)


def _set_timesteps(policy: Any, who: str) -> None:
    steps = integer(policy.num_inference_steps, "policy.num_inference_steps", low=1, high=MAX_DENOISING_STEPS)
    policy.scheduler.set_timesteps(steps)
    if len(policy.scheduler.timesteps) > MAX_DENOISING_STEPS:
        raise ValueError(
            f"{who}: policy.scheduler has {len(policy.scheduler.timesteps)} timesteps, "
            f"more than {MAX_DENOISING_STEPS} denoising steps"
        )


def _noise_estimate(policy: Any, x: torch.Tensor, t: Any, cond: Any) -> torch.Tensor:
    """``eps(x_t, t | cond)`` from the network's output in the scheduler's prediction type (no gradient)."""
    scheduler = policy.scheduler
    scale = getattr(scheduler, "scale_model_input", None)
    with torch.no_grad():
        model_in = scale(x, t) if callable(scale) else x
        output = policy.predict_noise(model_in, t, cond)
    if not isinstance(output, torch.Tensor) or output.shape != x.shape:
        raise ValueError(f"policy.predict_noise must return a tensor of shape {tuple(x.shape)}")
    return to_epsilon(output, x, t, scheduler)


def denoise_plans(policy: DiffusionPolicyLike, obs: Any, n: int, generator: np.random.Generator) -> np.ndarray:
    """``n`` unsteered plans ``(n, H, d)`` in env units: the samplers' denoising loop without guidance.

    The initial noise is a float32 (float64 for float64 policies) standard
    normal draw from ``generator`` and a stochastic step's noise comes from a
    torch generator seeded by it, exactly as in BI/GD/SS: a policy whose
    ``sample`` calls this gives RS the plans GD gives with ``guide_ratio=0``.
    An adapter for a third-party diffusion policy uses it as its ``sample``.
    """
    check_scheduler(policy.scheduler, "denoise_plans")
    cond, horizon, dtype = _prepare(policy, obs, "denoise_plans")
    scheduler = policy.scheduler
    x = _DiffusionSampler._noise(generator, (n, horizon, int(policy.action_dim)), dtype, policy.device)
    step_kwargs = step_generator(scheduler, generator, x.device)
    with torch.no_grad():
        for t in scheduler.timesteps:
            eps = _noise_estimate(policy, x, t, cond)
            x = scheduler.step(from_epsilon(eps, x, t, scheduler), t, x, **step_kwargs).prev_sample
    return _DiffusionSampler._finish(policy, x, n)
