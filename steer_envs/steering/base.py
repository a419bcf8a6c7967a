"""The steering contract: :class:`Sampler`, its :class:`SteeringResult`, and the checks every sampler shares.

A sampler is a strategy object with one call,
``sampler(policy, obs, interaction, n, generator=rng) -> SteeringResult``; the
six ITPS strategies (:mod:`~steer_envs.steering.ranking`,
:mod:`~steer_envs.steering.diffusion`) implement :meth:`Sampler._run` only.
"""

from __future__ import annotations

import itertools
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import torch

from steer_envs.core.interaction import Interaction, Nudge, Point, Sketch
from steer_envs.core.policy import DiffusionPolicyLike, FlowPolicyLike, TrajectoryPolicy
from steer_envs.core.validation import describe
from steer_envs.steering.costs import WeightedCosts
from steer_envs.steering.objectives import alignment_cost_np

__all__ = [
    "MAX_BATCH",
    "MAX_DENOISING_STEPS",
    "MAX_MCMC_STEPS",
    "Sampler",
    "SteeringResult",
    "argmin_choice",
    "check_batch",
    "check_generator",
    "check_plans",
    "finish_plans",
    "initial_noise",
    "interaction_dims",
    "plan_costs",
]


@dataclass(frozen=True)
class SteeringResult:
    """What one steering call produced.

    Attributes:
        plans: ``(n, H, d)`` float64 plans in env units.
        costs: ``(n,)`` alignment cost of every plan (env units; NaN without an interaction).
        chosen: index of the plan the sampler selects.
        sampler: short name of the sampler (``"RS"``, ``"SS"``, ...).
        timings: ``total_ms`` (wall time of the call) and, for BI/GD/SS,
            ``network_evals`` (calls of ``predict_noise``, or of a flow's ``predict_velocity``).
        perturbed_state: where OP moved the agent before sampling (``None`` otherwise);
            :class:`~steer_envs.wrappers.steering.SteeringWrapper` moves the real agent there.
        plan_costs: ``(n,)`` weighted extra costs of every plan (:meth:`Sampler.with_costs`;
            ``None`` without): the plan chosen minimises ``costs + plan_costs``.
    """

    plans: np.ndarray
    costs: np.ndarray
    chosen: int
    sampler: str
    timings: Mapping[str, float] = field(default_factory=dict)
    perturbed_state: np.ndarray | None = None
    plan_costs: np.ndarray | None = None

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


def check_batch(n: Any) -> int:
    """``n`` as a batch size in ``[1, MAX_BATCH]`` (``TypeError``/``ValueError`` otherwise)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise TypeError(f"`n` must be a positive integer (the batch size), got {describe(n)}")
    if not 1 <= n <= MAX_BATCH:
        raise ValueError(f"`n` must be a positive integer (the batch size) <= {MAX_BATCH}, got {n!r}")
    return int(n)


def check_generator(generator: Any) -> np.random.Generator:
    """``generator``, or a fresh unseeded one for ``None`` (``TypeError`` for anything else)."""
    if generator is None:
        return np.random.default_rng()
    if not isinstance(generator, np.random.Generator):
        raise TypeError(f"`generator` must be a numpy.random.Generator or None, got {type(generator).__name__}")
    return generator


def check_plans(plans: Any, n: int, policy: Any, who: str) -> np.ndarray:
    """``plans`` as float64 ``(n, policy.horizon, policy.action_dim)`` (ValueError naming ``who`` otherwise)."""
    arr = np.asarray(plans.detach().cpu().numpy() if isinstance(plans, torch.Tensor) else plans, dtype=np.float64)
    shape = (n, int(policy.horizon), int(policy.action_dim))
    if arr.shape != shape:
        raise ValueError(f"{who} must return plans of shape {shape} (n, horizon, action_dim), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{who} returned non-finite plans")
    return arr


def initial_noise(rng: np.random.Generator, shape: tuple[int, ...], dtype: torch.dtype, device: Any) -> torch.Tensor:
    """A standard normal ``shape`` tensor from ``rng``: float32 draws for float32 policies, float64 otherwise.

    The same stream a policy's own sampler draws when it calls
    ``rng.standard_normal(shape, dtype=np.float32)``, so the samplers that
    denoise or integrate start from RS's initial noise for one generator state.
    """
    np_dtype = np.float32 if dtype == torch.float32 else np.float64
    return torch.as_tensor(rng.standard_normal(shape, dtype=np_dtype), dtype=dtype, device=device)


def finish_plans(policy: Any, x: torch.Tensor, n: int) -> np.ndarray:
    """Normalized ``x`` as checked plans in env units: ``policy.unnormalize``, then ``policy.extract_plan`` if any."""
    traj = policy.unnormalize(x.detach())
    traj = traj.detach().cpu().numpy() if isinstance(traj, torch.Tensor) else np.asarray(traj)
    extract = getattr(policy, "extract_plan", None)
    if callable(extract):
        traj = extract(traj)
    process = "denoising" if isinstance(policy, DiffusionPolicyLike) else "integration"
    return check_plans(traj, n, policy, f"{type(policy).__name__} {process} (+ extract_plan)")


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


def plan_costs(plans: np.ndarray, interaction: Interaction | None, dims: tuple[int, ...]) -> np.ndarray:
    """Alignment cost of every plan on its entries ``dims`` (env units; NaN without an interaction)."""
    if interaction is None:
        return np.full(plans.shape[0], np.nan)
    view = plans if len(dims) == plans.shape[-1] else plans[..., list(dims)]
    return alignment_cost_np(view, interaction)


class Sampler(ABC):
    """A steering strategy: ``sampler(policy, obs, interaction, n, generator) -> SteeringResult``."""

    name: ClassVar[str]
    requires_diffusion: ClassVar[bool] = False
    #: whether ``None`` (no interaction: an unsteered call) is accepted (RS only)
    accepts_none: ClassVar[bool] = False
    #: interaction types the sampler accepts
    interactions: ClassVar[tuple[type[Point] | type[Sketch] | type[Nudge], ...]] = (Point, Sketch)
    #: whether extra plan costs can change what it returns (:meth:`with_costs`; RS picks at random)
    takes_costs: ClassVar[bool] = True
    #: the extra plan costs (none until :meth:`with_costs`)
    _costs: WeightedCosts = WeightedCosts(None)

    def with_costs(self, costs: Any) -> Sampler:
        """Add plan costs to the user's alignment; returns the sampler.

        ``costs``: plan costs (:mod:`steer_envs.steering.costs`: any
        differentiable ``cost(plans (n, H, d) in env units) -> (n,)``, e.g.
        :func:`~steer_envs.steering.costs.safety_cost`) or ``(cost, weight)``
        pairs. Every sampler then picks the plan minimising alignment plus the
        weighted costs; GD and SS also shift each step's clean-plan estimate
        down the costs' gradient. ``ValueError`` for RS (it picks at random).
        """
        if not self.takes_costs:
            raise ValueError(f"{type(self).__name__} ({self.name}) picks a random plan: costs cannot change it")
        self._costs = WeightedCosts(costs)
        return self

    def __call__(
        self,
        policy: TrajectoryPolicy,
        obs: Any,
        interaction: Interaction | None,
        n: int = 32,
        *,
        generator: np.random.Generator | None = None,
    ) -> SteeringResult:
        """Sample ``n`` plans for ``obs`` steered by ``interaction``; see :mod:`steer_envs.steering`."""
        n = check_batch(n)
        rng = check_generator(generator)
        self.check_policy(policy)
        self._check_interaction(interaction, policy)
        t0 = time.perf_counter()
        plans, chosen, extra, perturbed = self._run(policy, obs, interaction, n, rng)
        timings = {"total_ms": (time.perf_counter() - t0) * 1e3, **extra}
        costs = plan_costs(plans, interaction, interaction_dims(policy))
        if not self._costs:
            return SteeringResult(plans, costs, int(chosen(costs)), self.name, timings, perturbed)
        added = self._costs.values(plans)
        total = added if interaction is None else costs + added
        return SteeringResult(plans, costs, int(chosen(total)), self.name, timings, perturbed, added)

    def check_policy(self, policy: Any) -> None:
        """``TypeError`` unless ``policy`` is what this sampler needs.

        BI/GD/SS (``requires_diffusion``) need a ``DiffusionPolicyLike`` or a
        ``FlowPolicyLike``; the others a ``TrajectoryPolicy``.
        """
        if self.requires_diffusion:
            if isinstance(policy, (DiffusionPolicyLike, FlowPolicyLike)):
                return
            need = (
                "a DiffusionPolicyLike (sample, scheduler, num_inference_steps, device, encode_obs, "
                "predict_noise, normalize, unnormalize) or a FlowPolicyLike (sample, num_inference_steps, "
                "device, encode_obs, predict_velocity, normalize, unnormalize)"
            )
        elif isinstance(policy, TrajectoryPolicy):
            return
        else:
            need = "a TrajectoryPolicy (horizon, action_dim, sample)"
        raise TypeError(f"{type(self).__name__} needs `policy` to be {need}, got {type(policy).__name__}")

    def _check_interaction(self, interaction: Any, policy: TrajectoryPolicy) -> None:
        if interaction is None and self.accepts_none:
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
        if self._costs:
            params += f"{', ' if params else ''}costs={len(self._costs.terms)}"
        return f"{type(self).__name__}({params})"


def argmin_choice(costs: np.ndarray) -> int:
    """The index of the lowest cost: how every ranking sampler picks its plan."""
    return int(np.argmin(costs))
