"""ITPS steering samplers (thesis §2.3): six strategies that bias a frozen policy toward a user's input.

Every sampler is a strategy object with one call::

    result = sampler(policy, obs, interaction, n, generator=rng)   # -> SteeringResult

``result.plans`` is the batch ``(n, H, d)`` in env units, ``result.costs`` the
alignment cost ``xi`` of every plan (env units, :mod:`steer_envs.core.objectives`),
``result.chosen`` the index of the plan the sampler picks and ``result.timings``
the wall time (and network evaluations of the diffusion samplers).

=====  ============================  ===============================  ======================
name   class                         needs                            interactions
=====  ============================  ===============================  ======================
RS     :class:`RandomSampling`       ``TrajectoryPolicy.sample``      any (or ``None``)
PR     :class:`PostHocRanking`       ``TrajectoryPolicy.sample``      Point, Sketch
OP     :class:`OutputPerturbation`   ``TrajectoryPolicy.sample``      Sketch, Nudge
BI     :class:`BiasedInitialization` ``DiffusionPolicyLike``          Point, Sketch
GD     :class:`GuidedDiffusion`      ``DiffusionPolicyLike``          Point, Sketch
SS     :class:`StochasticSampling`   ``DiffusionPolicyLike``          Point, Sketch
=====  ============================  ===============================  ======================

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
the policy's normalized space; ranking costs in env units.

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
"""

from __future__ import annotations

import inspect
import itertools
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import torch

from steer_envs.core.interaction import Interaction, Nudge, Point, Sketch
from steer_envs.core.objectives import alignment_cost_np, point_cost, resample_path_torch, sketch_cost
from steer_envs.core.policy import DiffusionPolicyLike, TrajectoryPolicy
from steer_envs.core.validation import describe, integer, real_scalar

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
    "benchmark_latency",
    "interaction_dims",
    "make_sampler",
    "output_perturbation_point",
    "place_observation",
]


@dataclass(frozen=True)
class SteeringResult:
    """What one steering call produced.

    Attributes:
        plans: ``(n, H, d)`` float64 plans in env units.
        costs: ``(n,)`` alignment cost of every plan (env units; NaN without an interaction).
        chosen: index of the plan the sampler selects.
        sampler: short name of the sampler (``"RS"``, ``"SS"``, ...).
        timings: ``total_ms`` (wall time of the call) and, for diffusion samplers,
            ``network_evals`` (calls of ``predict_noise``).
        perturbed_state: where OP moved the agent before sampling (``None`` otherwise);
            :class:`~steer_envs.wrappers.steering.SteeringWrapper` moves the real agent there.
    """

    plans: np.ndarray
    costs: np.ndarray
    chosen: int
    sampler: str
    timings: Mapping[str, float] = field(default_factory=dict)
    perturbed_state: np.ndarray | None = None

    @property
    def plan(self) -> np.ndarray:
        """The chosen plan ``(H, d)``."""
        return self.plans[self.chosen]


#: the most plans one steering call samples (a batch beyond this cannot fit in memory next to a policy).
MAX_BATCH = 1 << 20
#: the most MCMC iterations per noise level of SS (ITPS: 4).
MAX_MCMC_STEPS = 1000
#: the most denoising steps a diffusion sampler runs (``policy.num_inference_steps``; DP: 10-100).
MAX_DENOISING_STEPS = 10_000


# --------------------------------------------------------------------- helpers
def _check_n(n: Any) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise TypeError(f"`n` must be a positive integer (the batch size), got {describe(n)}")
    if not 1 <= n <= MAX_BATCH:
        raise ValueError(f"`n` must be a positive integer (the batch size) <= {MAX_BATCH}, got {n!r}")
    return int(n)


def _check_generator(generator: Any) -> np.random.Generator:
    if generator is None:
        return np.random.default_rng()
    if not isinstance(generator, np.random.Generator):
        raise TypeError(f"`generator` must be a numpy.random.Generator or None, got {type(generator).__name__}")
    return generator


def _check_plans(plans: Any, n: int, policy: Any, who: str) -> np.ndarray:
    """``plans`` as float64 ``(n, policy.horizon, policy.action_dim)`` (ValueError naming ``who`` otherwise)."""
    arr = np.asarray(plans.detach().cpu().numpy() if isinstance(plans, torch.Tensor) else plans, dtype=np.float64)
    shape = (n, int(policy.horizon), int(policy.action_dim))
    if arr.shape != shape:
        raise ValueError(f"{who} must return plans of shape {shape} (n, horizon, action_dim), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{who} returned non-finite plans")
    return arr


def interaction_dims(policy: Any) -> tuple[int, ...]:
    """The plan entries an interaction constrains: ``policy.interaction_dims`` if set, else all.

    ``ValueError`` when the attribute is not distinct increasing indices below ``policy.action_dim``.
    """
    d = int(policy.action_dim)
    dims = getattr(policy, "interaction_dims", None)
    if dims is None:
        return tuple(range(d))
    if isinstance(dims, (str, bytes)) or not hasattr(dims, "__iter__"):
        raise TypeError(f"policy.interaction_dims must be a tuple of ints or None, got {describe(dims)}")
    out = tuple(dims)
    if (
        not out
        or any(isinstance(i, bool) or not isinstance(i, (int, np.integer)) for i in out)
        or any(b <= a for a, b in itertools.pairwise(out))
        or not 0 <= out[0]
        or out[-1] >= d
    ):
        raise ValueError(
            f"policy.interaction_dims must be increasing indices in [0, action_dim={d}), got {list(out)!r}"
        )
    return tuple(int(i) for i in out)


def _costs(plans: np.ndarray, interaction: Interaction | None, dims: tuple[int, ...]) -> np.ndarray:
    if interaction is None:
        return np.full(plans.shape[0], np.nan)
    view = plans if len(dims) == plans.shape[-1] else plans[..., list(dims)]
    return alignment_cost_np(view, interaction)


def place_observation(obs: Any, xy: Any) -> np.ndarray:
    """``obs`` with the agent placed at rest at ``xy``: the default observation builder of OP.

    The first ``d = len(xy)`` entries of the last axis become ``xy`` and the rest
    (velocities) zero, on every row of an observation history ``(n_obs, obs_dim)``
    (a teleported agent has the same position over its whole history).
    """
    arr = np.array(obs, dtype=np.float32, copy=True)
    point = np.asarray(xy, dtype=np.float32).reshape(-1)
    if arr.ndim == 0 or arr.shape[-1] < point.size:
        raise ValueError(f"`obs` must have at least {point.size} entries on its last axis, got shape {arr.shape}")
    arr[..., : point.size] = point
    arr[..., point.size :] = 0.0
    return arr


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


class _ObjectiveInNormalizedSpace:
    """``xi`` of a Point/Sketch mapped into the policy's normalized space, with its gradient."""

    def __init__(self, policy: DiffusionPolicyLike, interaction: Point | Sketch, dtype: torch.dtype) -> None:
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


# --------------------------------------------------------------------- samplers
class Sampler(ABC):
    """A steering strategy: ``sampler(policy, obs, interaction, n, generator) -> SteeringResult``."""

    name: ClassVar[str]
    requires_diffusion: ClassVar[bool] = False
    #: interaction types the sampler accepts (``None`` is accepted by RS only)
    interactions: ClassVar[tuple[type[Point] | type[Sketch] | type[Nudge], ...]] = (Point, Sketch)

    def __call__(
        self,
        policy: TrajectoryPolicy,
        obs: Any,
        interaction: Interaction | None,
        n: int = 32,
        *,
        generator: np.random.Generator | None = None,
    ) -> SteeringResult:
        """Sample ``n`` plans for ``obs`` steered by ``interaction``; see the module docstring."""
        n = _check_n(n)
        rng = _check_generator(generator)
        self._check_policy(policy)
        self._check_interaction(interaction, policy)
        t0 = time.perf_counter()
        plans, chosen, extra, perturbed = self._run(policy, obs, interaction, n, rng)
        timings = {"total_ms": (time.perf_counter() - t0) * 1e3, **extra}
        costs = _costs(plans, interaction, interaction_dims(policy))
        return SteeringResult(plans, costs, int(chosen(costs)), self.name, timings, perturbed)

    def _check_policy(self, policy: Any) -> None:
        proto = DiffusionPolicyLike if self.requires_diffusion else TrajectoryPolicy
        if not isinstance(policy, proto):
            need = (
                "a DiffusionPolicyLike (sample, scheduler, num_inference_steps, device, encode_obs, "
                "predict_noise, normalize, unnormalize)"
                if self.requires_diffusion
                else "a TrajectoryPolicy (horizon, action_dim, sample)"
            )
            raise TypeError(f"{type(self).__name__} needs `policy` to be {need}, got {type(policy).__name__}")

    def _check_interaction(self, interaction: Any, policy: TrajectoryPolicy) -> None:
        if interaction is None and isinstance(self, RandomSampling):
            return
        if not isinstance(interaction, self.interactions):
            names = ", ".join(t.__name__ for t in self.interactions)
            raise TypeError(f"{type(self).__name__} needs `interaction` to be one of {names}, got {interaction!r}")
        interaction.validate(len(interaction_dims(policy)))

    @abstractmethod
    def _run(
        self, policy: Any, obs: Any, interaction: Any, n: int, rng: np.random.Generator
    ) -> tuple[np.ndarray, Callable[[np.ndarray], int], dict[str, float], np.ndarray | None]:
        """``(plans, choose(costs) -> index, extra timings, perturbed state)``."""

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in vars(self).items() if not k.startswith("_"))
        return f"{type(self).__name__}({params})"


def _argmin(costs: np.ndarray) -> int:
    return int(np.argmin(costs))


class RandomSampling(Sampler):
    """RS: a random plan of an unmodified batch (the baseline; ``None`` interaction = unsteered)."""

    name = "RS"
    interactions = (Point, Sketch, Nudge)

    def _run(self, policy: Any, obs: Any, interaction: Any, n: int, rng: np.random.Generator) -> Any:
        plans = _check_plans(policy.sample(obs, n, generator=rng), n, policy, "policy.sample")
        pick = int(rng.integers(n))  # drawn after the batch, so PR with the same generator ranks the same batch
        return plans, lambda costs: pick, {}, None


class PostHocRanking(Sampler):
    """PR: rank an unmodified batch by ``xi`` and pick the best plan."""

    name = "PR"

    def _run(self, policy: Any, obs: Any, interaction: Any, n: int, rng: np.random.Generator) -> Any:
        plans = _check_plans(policy.sample(obs, n, generator=rng), n, policy, "policy.sample")
        return plans, _argmin, {}, None


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
        plans = _check_plans(policy.sample(new_obs, n, generator=rng), n, policy, "policy.sample")
        if isinstance(interaction, Nudge):
            pick = int(rng.integers(n))
            return plans, lambda costs: pick, {}, target
        return plans, _argmin, {}, target


# ---------------------------------------------------------- diffusion samplers
class _DiffusionSampler(Sampler):
    """Shared denoising loop of BI, GD and SS (diffusers-style scheduler, epsilon prediction)."""

    requires_diffusion = True

    def _setup(self, policy: Any, obs: Any, interaction: Any) -> tuple[Any, Any, int, torch.dtype]:
        config = getattr(policy.scheduler, "config", None)
        prediction = getattr(config, "prediction_type", "epsilon") if config is not None else "epsilon"
        if prediction != "epsilon":
            raise ValueError(
                f"{type(self).__name__} steers the noise estimate: policy.scheduler must use "
                f"prediction_type='epsilon' (predict_noise returns epsilon), got {prediction!r}"
            )
        horizon = int(getattr(policy, "diffusion_horizon", policy.horizon))
        dtype = getattr(policy, "dtype", torch.float32)
        dtype = dtype if isinstance(dtype, torch.dtype) and dtype.is_floating_point else torch.float32
        objective = _ObjectiveInNormalizedSpace(policy, interaction, dtype)
        with torch.no_grad():
            cond = policy.encode_obs(obs)
        steps = integer(policy.num_inference_steps, "policy.num_inference_steps", low=1, high=MAX_DENOISING_STEPS)
        policy.scheduler.set_timesteps(steps)
        if len(policy.scheduler.timesteps) > MAX_DENOISING_STEPS:
            raise ValueError(
                f"{type(self).__name__}: policy.scheduler has {len(policy.scheduler.timesteps)} timesteps, "
                f"more than {MAX_DENOISING_STEPS} denoising steps"
            )
        return objective, cond, horizon, dtype

    @staticmethod
    def _noise(rng: np.random.Generator, shape: tuple[int, ...], dtype: torch.dtype, device: Any) -> torch.Tensor:
        # float32 draws for float32 policies: the same stream a policy's own sampler draws (same initial noise as RS)
        np_dtype = np.float32 if dtype == torch.float32 else np.float64
        return torch.as_tensor(rng.standard_normal(shape, dtype=np_dtype), dtype=dtype, device=device)

    @staticmethod
    def _eps(policy: Any, x: torch.Tensor, t: Any, cond: Any) -> torch.Tensor:
        with torch.no_grad():
            eps = policy.predict_noise(x, t, cond)
        if not isinstance(eps, torch.Tensor) or eps.shape != x.shape:
            raise ValueError(f"policy.predict_noise must return a tensor of shape {tuple(x.shape)}")
        return eps

    @staticmethod
    def _finish(policy: Any, x: torch.Tensor, n: int) -> np.ndarray:
        traj = policy.unnormalize(x.detach())
        traj = traj.detach().cpu().numpy() if isinstance(traj, torch.Tensor) else np.asarray(traj)
        extract = getattr(policy, "extract_plan", None)
        if callable(extract):
            traj = extract(traj)
        return _check_plans(traj, n, policy, f"{type(policy).__name__} denoising (+ extract_plan)")


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
        return eps

    def _run(self, policy: Any, obs: Any, interaction: Any, n: int, rng: np.random.Generator) -> Any:
        objective, cond, horizon, dtype = self._setup(policy, obs, interaction)
        scheduler = policy.scheduler
        shape = (n, horizon, int(policy.action_dim))
        step_kwargs = self._step_kwargs(scheduler)
        x = self._noise(rng, shape, dtype, policy.device)
        evals = 0
        for t in scheduler.timesteps:
            for j in range(self.mcmc_steps):
                eps = self._guided_eps(policy, objective, x, t, cond)
                evals += 1
                if j < self.mcmc_steps - 1:
                    x = self._renoise(scheduler, x, eps, t, self._noise(rng, shape, dtype, policy.device))
                else:
                    x = scheduler.step(eps, t, x, **step_kwargs).prev_sample
        return self._finish(policy, x, n), _argmin, {"network_evals": float(evals)}, None

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
        abar = torch.as_tensor(scheduler.alphas_cumprod[int(t)], dtype=x.dtype, device=x.device)
        x0 = (x - (1 - abar).sqrt() * eps) / abar.sqrt()
        config = getattr(scheduler, "config", None)
        if config is not None and getattr(config, "clip_sample", False):
            bound = float(getattr(config, "clip_sample_range", 1.0))
            x0 = x0.clamp(-bound, bound)
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
    skipped (ITPS: ``start_t = 50``, ``init_std = 0.5``: 6 of 10 DDIM steps).
    """

    name = "BI"

    def __init__(self, start_t: int = 50, init_std: float = 0.5) -> None:
        self.start_t = integer(start_t, "`start_t`", low=0)
        self.init_std = _check_ratio(init_std, "init_std")

    def _run(self, policy: Any, obs: Any, interaction: Any, n: int, rng: np.random.Generator) -> Any:
        objective, cond, horizon, dtype = self._setup(policy, obs, interaction)
        scheduler = policy.scheduler
        shape = (n, horizon, int(policy.action_dim))
        init = objective.as_trajectory(horizon).to(dtype)
        x = init.unsqueeze(0) + self.init_std * self._noise(rng, shape, dtype, policy.device)
        evals = 0
        for t in scheduler.timesteps:
            if int(t) > self.start_t:
                continue
            x = scheduler.step(self._eps(policy, x, t, cond), t, x).prev_sample
            evals += 1
        return self._finish(policy, x, n), _argmin, {"network_evals": float(evals)}, None


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

    ``kwargs`` go to the sampler's constructor.

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
    accepted = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
    unknown = sorted(set(kwargs) - set(accepted))
    if unknown:
        raise TypeError(
            f"make_sampler: {cls.__name__} ({name.upper()}) takes {accepted or 'no arguments'}, got {unknown}"
        )
    return cls(**kwargs)


#: the most timed (and warm-up) rounds of :func:`benchmark_latency`.
MAX_TIMING_ROUNDS = 10_000


def benchmark_latency(
    policy: TrajectoryPolicy,
    samplers: Mapping[str, Sampler],
    obs: Any,
    interaction: Interaction,
    *,
    batch: int = 32,
    repeats: int = 5,
    warmup: int = 1,
    seed: int = 0,
) -> dict[str, float]:
    """Milliseconds per steering call of every sampler (median over ``repeats``, after ``warmup`` calls).

    Samplers are timed in interleaved rounds (one call each per round) so a
    change of machine load affects all of them alike; every call uses the same
    seed, hence the same initial noise.
    """
    if not isinstance(samplers, Mapping) or not samplers:
        raise ValueError("`samplers` must be a non-empty mapping name -> Sampler")
    for key, sampler in samplers.items():
        if not isinstance(sampler, Sampler):
            raise TypeError(f"`samplers[{key!r}]` must be a Sampler, got {type(sampler).__name__}")
    repeats = integer(repeats, "`repeats`", low=1, high=MAX_TIMING_ROUNDS)
    warmup = integer(warmup, "`warmup`", low=0, high=MAX_TIMING_ROUNDS)
    batch = _check_n(batch)
    times: dict[str, list[float]] = {key: [] for key in samplers}
    for round_ in range(int(warmup) + int(repeats)):
        for key, sampler in samplers.items():
            t0 = time.perf_counter()
            sampler(policy, obs, interaction, batch, generator=np.random.default_rng(seed))
            if round_ >= warmup:
                times[key].append((time.perf_counter() - t0) * 1e3)
    return {key: float(np.median(values)) for key, values in times.items()}
