"""Alignment objectives ``xi(tau, z)`` of thesis §2.2 as differentiable torch functions.

Every cost takes a batch of trajectories ``tau`` of shape ``(B, T, d)`` and
returns one cost per trajectory, shape ``(B,)``, in ``tau``'s dtype and device;
lower is better aligned. Gradients flow to ``tau`` (guided diffusion and
stochastic sampling differentiate these costs through the denoiser).

* point:  ``xi = (1/T) sum_t ||s_t - z||`` (mean L2 distance of every state to the target);
* sketch: ``xi = reduce_t ||s_t - g_t||`` with ``g`` the sketch resampled to ``T`` points
  uniformly in index. The thesis writes a *sum* over ``t``; the public ITPS code uses the
  *mean* (``1/H`` factor). ``reduction="mean"`` (default, ITPS code) or ``"sum"`` (thesis text)
  - they differ only by the factor ``T``, which rescales a guide ratio;
* nudge:  a hard constraint: ``0`` if the first ``k`` states equal the nudge (within ``atol``),
  ``inf`` otherwise. It has no useful gradient; samplers satisfy it by projection with
  :func:`apply_nudge`, which overwrites the first ``k`` states.

The interaction may be given as a :class:`~steer_envs.core.interaction.Point` /
``Sketch`` / ``Nudge`` or as a raw array/tensor, so a sampler can pass a sketch
already mapped to the policy's normalized space. :func:`alignment_cost_np`
wraps the dispatcher for numpy callers (metrics, rankers without torch tensors);
:func:`apply_nudge` accepts numpy arrays too.
"""

from __future__ import annotations

from typing import Any, Literal, TypeVar

import numpy as np
import torch

from steer_envs.core.interaction import Interaction, Nudge, Point, Sketch, as_finite_array
from steer_envs.core.validation import real_scalar

Reduction = Literal["mean", "sum"]
ArrayOrTensor = TypeVar("ArrayOrTensor", np.ndarray, torch.Tensor)

__all__ = [
    "alignment_cost",
    "alignment_cost_np",
    "apply_nudge",
    "nudge_cost",
    "point_cost",
    "resample_path_torch",
    "sketch_cost",
]


def _check_tau(tau: Any) -> torch.Tensor:
    if not isinstance(tau, torch.Tensor):
        raise TypeError(f"`tau` must be a torch.Tensor of shape (B, T, d), got {type(tau).__name__}")
    if tau.ndim != 3:
        raise ValueError(f"`tau` must have shape (B, T, d), got shape {tuple(tau.shape)}")
    if not tau.is_floating_point():
        raise TypeError(f"`tau` must be a floating-point tensor, got dtype {tau.dtype}")
    if tau.shape[1] < 1 or tau.shape[2] < 1:
        raise ValueError(f"`tau` needs T >= 1 steps and d >= 1 dimensions, got shape {tuple(tau.shape)}")
    return tau


def _as_like(value: Any, tau: torch.Tensor, *, name: str, ndim: int, min_len: int) -> torch.Tensor:
    """Interaction data as a tensor on ``tau``'s dtype/device, rank and dimension checked."""
    d = tau.shape[-1]
    if isinstance(value, Point | Sketch | Nudge):
        value = value.array
    if isinstance(value, torch.Tensor):
        if value.dtype == torch.bool or value.is_complex():
            raise TypeError(f"`{name}` must hold real numbers, got a tensor of dtype {value.dtype}")
        if value.ndim != ndim or value.shape[0] < min_len or value.shape[-1] != d:
            raise ValueError(f"`{name}` must have {ndim}-D shape with state dimension {d}, got {tuple(value.shape)}")
        if not bool(torch.isfinite(value).all()):
            raise ValueError(f"`{name}` must be finite (no NaN or inf)")
        return value.to(dtype=tau.dtype, device=tau.device)
    arr = as_finite_array(value, name=name, ndim=ndim, min_len=min_len, dim=d)
    return torch.as_tensor(np.array(arr), dtype=tau.dtype, device=tau.device)


def _check_reduction(reduction: str) -> None:
    if reduction not in ("mean", "sum"):
        raise ValueError(f"`reduction` must be 'mean' or 'sum', got {reduction!r}")


def resample_path_torch(path: torch.Tensor, n: int) -> torch.Tensor:
    """Torch twin of :func:`~steer_envs.core.interaction.resample_path` (differentiable in ``path``)."""
    if path.ndim != 2 or path.shape[0] < 1:
        raise ValueError(f"`path` must have shape (G, d) with G >= 1, got {tuple(path.shape)}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"`n` must be a positive integer, got {n!r}")
    g = path.shape[0]
    idx = torch.linspace(0.0, g - 1.0, int(n), dtype=torch.float64, device=path.device)
    lo = idx.floor().long().clamp(0, g - 1)
    hi = (lo + 1).clamp(max=g - 1)
    frac = (idx - lo.to(torch.float64)).to(path.dtype)[:, None]
    return (1.0 - frac) * path[lo] + frac * path[hi]


def point_cost(tau: torch.Tensor, target: Point | torch.Tensor | Any) -> torch.Tensor:
    """Point objective: mean over steps of ``||s_t - z||_2``; returns ``(B,)``."""
    tau = _check_tau(tau)
    z = _as_like(target, tau, name="target", ndim=1, min_len=1)
    return torch.linalg.vector_norm(tau - z, dim=-1).mean(dim=-1)


def sketch_cost(
    tau: torch.Tensor, sketch: Sketch | torch.Tensor | Any, *, reduction: Reduction = "mean"
) -> torch.Tensor:
    """Sketch objective: per-step L2 to the sketch resampled to ``T``, reduced over steps; ``(B,)``.

    ``reduction="mean"`` follows the ITPS code, ``"sum"`` the thesis equation.
    """
    tau = _check_tau(tau)
    _check_reduction(reduction)
    path = _as_like(sketch, tau, name="sketch", ndim=2, min_len=2)
    goal = resample_path_torch(path, tau.shape[1])
    dist = torch.linalg.vector_norm(tau - goal, dim=-1)
    return dist.mean(dim=-1) if reduction == "mean" else dist.sum(dim=-1)


def apply_nudge(tau: ArrayOrTensor, nudge: Nudge | torch.Tensor | Any) -> ArrayOrTensor:
    """Projection for physical corrections: ``[z_1..z_k, s_{k+1}..s_T]`` for every plan.

    Accepts a torch tensor (gradients flow to the kept states ``s_{k+1..T}``) or a
    numpy array ``(B, T, d)``; returns a new object of the same kind, ``tau`` is
    not modified. Raises ``ValueError`` when ``k > T``.

    >>> apply_nudge(np.zeros((1, 3, 2)), Nudge([[1.0, 1.0]]))[0]
    array([[1., 1.],
           [0., 0.],
           [0., 0.]])
    """
    if isinstance(tau, np.ndarray):
        out = apply_nudge(torch.as_tensor(np.asarray(tau, dtype=np.float64)), nudge)
        return out.numpy()
    tau = _check_tau(tau)
    states = _as_like(nudge, tau, name="nudge", ndim=2, min_len=1)
    k = states.shape[0]
    if k > tau.shape[1]:
        raise ValueError(f"`nudge` has k={k} states but `tau` only T={tau.shape[1]} steps")
    head = states.unsqueeze(0).expand(tau.shape[0], k, tau.shape[2])
    return torch.cat([head, tau[:, k:]], dim=1)


def nudge_cost(tau: torch.Tensor, nudge: Nudge | torch.Tensor | Any, *, atol: float = 1e-6) -> torch.Tensor:
    """Nudge objective: ``0`` where the first ``k`` states match within ``atol`` (max-norm), else ``inf``."""
    tau = _check_tau(tau)
    atol = real_scalar(atol, "`atol`", finite=False)
    if not atol >= 0.0:
        raise ValueError(f"`atol` must be >= 0, got {atol!r}")
    states = _as_like(nudge, tau, name="nudge", ndim=2, min_len=1)
    k = states.shape[0]
    if k > tau.shape[1]:
        raise ValueError(f"`nudge` has k={k} states but `tau` only T={tau.shape[1]} steps")
    match = ((tau[:, :k] - states).abs() <= atol).flatten(1).all(dim=1)
    zero = torch.zeros((), dtype=tau.dtype, device=tau.device)
    return torch.where(match, zero, torch.full_like(zero, float("inf")))


def alignment_cost(
    tau: torch.Tensor, interaction: Interaction, *, reduction: Reduction = "mean", atol: float = 1e-6
) -> torch.Tensor:
    """Dispatch on the interaction type; returns ``(B,)`` costs (lower = better aligned).

    ``reduction`` applies to sketches only (a point cost is a mean by definition);
    ``atol`` to nudges only.

    >>> tau = torch.zeros(2, 4, 2, requires_grad=True)  # two plans resting at the origin
    >>> cost = alignment_cost(tau, Point([3.0, 4.0]))
    >>> cost.tolist()
    [5.0, 5.0]
    >>> cost.sum().backward()  # guidance differentiates the cost
    >>> tuple(tau.grad.shape)
    (2, 4, 2)
    """
    if isinstance(interaction, Point):
        return point_cost(tau, interaction)
    if isinstance(interaction, Sketch):
        return sketch_cost(tau, interaction, reduction=reduction)
    if isinstance(interaction, Nudge):
        return nudge_cost(tau, interaction, atol=atol)
    raise TypeError(f"`interaction` must be a Point, Sketch or Nudge, got {type(interaction).__name__}")


def alignment_cost_np(
    tau: np.ndarray | Any, interaction: Interaction, *, reduction: Reduction = "mean", atol: float = 1e-6
) -> np.ndarray:
    """Numpy convenience: ``tau`` array-like ``(B, T, d)`` -> float64 costs ``(B,)`` (no gradients).

    >>> alignment_cost_np(np.zeros((1, 3, 2)), Sketch([[0.0, 0.0], [0.0, 2.0]]))
    array([1.])
    """
    arr = np.asarray(tau)
    if arr.ndim != 3:
        raise ValueError(f"`tau` must have shape (B, T, d), got shape {arr.shape}")
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"`tau` must hold real numbers, got dtype {arr.dtype}")
    with torch.no_grad():
        cost = alignment_cost(torch.as_tensor(arr.astype(np.float64)), interaction, reduction=reduction, atol=atol)
    return cost.numpy()
