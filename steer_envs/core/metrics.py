"""Steering metrics of thesis ch. 2 (numpy only).

* Motion alignment (``MA``, Maze2D, Table 2.1): per sample, the mean per-step L2
  distance to the sketch resampled to the plan length; reported as the min and
  the mean over the batch (Min L2 / Avg L2; lower = better aligned). ITPS divides
  distances by the maze extent, hence the optional ``scale`` divisor.
* Constraint satisfaction (``CS``): fraction of samples/trials without a violation
  (collision, failed pick/place, invalid skill sequence).
* Task alignment (``TA``): fraction of interactions that executed the intended task.
* Aligned-success quadrants (block stacking / kitchen tables): AS, AF, MS, MF with
  ``TA = AS + AF`` and ``CS = AS + MS``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from steer_envs.core.interaction import Sketch, as_finite_array, resample_path
from steer_envs.core.validation import _from_tensor, real_scalar

__all__ = [
    "MotionAlignment",
    "aligned_success",
    "constraint_satisfaction",
    "motion_alignment",
    "sketch_distances",
    "task_alignment",
]


class MotionAlignment(NamedTuple):
    """Min and mean over a batch of per-sample mean L2 distances to a sketch."""

    min_l2: float
    avg_l2: float


def _as_flags(value: Any, *, name: str) -> np.ndarray:
    """A non-empty 1-D boolean vector; 0/1 integers (or floats) are accepted."""
    arr = np.asarray(value)
    if arr.ndim != 1:
        raise ValueError(f"`{name}` must be a 1-D sequence of booleans, got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"`{name}` must not be empty")
    if arr.dtype == np.bool_:
        return arr
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"`{name}` must hold booleans (or 0/1), got dtype {arr.dtype}")
    if not np.all((arr == 0) | (arr == 1)):
        raise ValueError(f"`{name}` must hold booleans (or 0/1), got values {np.unique(arr)[:8]}")
    return arr.astype(bool)


def sketch_distances(trajs: Any, sketch: Sketch | Any, *, scale: float = 1.0) -> np.ndarray:
    """Per-sample mean per-step L2 distance to the sketch resampled to ``T``: shape ``(B,)``.

    Args:
        trajs: ``(B, T, d)`` batch of planned trajectories.
        sketch: a :class:`Sketch` or a ``(G, d)`` array, ``G >= 2``.
        scale: positive divisor applied to the distances (e.g. the maze extent).
    """
    if isinstance(trajs, (str, bytes)):
        raise TypeError(f"`trajs` must be an array of real numbers of shape (B, T, d), got {type(trajs).__name__}")
    arr = np.asarray(_from_tensor(trajs, "`trajs`"))
    if arr.ndim != 3:
        raise ValueError(f"`trajs` must have shape (B, T, d), got shape {arr.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"`trajs` must hold at least one trajectory of at least one step, got shape {arr.shape}")
    flat = as_finite_array(arr.reshape(-1, arr.shape[-1]), name="trajs", ndim=2).reshape(arr.shape)
    points = sketch.points if isinstance(sketch, Sketch) else sketch
    path = as_finite_array(points, name="sketch", ndim=2, min_len=2, dim=flat.shape[-1])
    scale = real_scalar(scale, "`scale`", finite=False)
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"`scale` must be a positive finite number, got {scale!r}")
    goal = resample_path(path, flat.shape[1])
    dist = np.linalg.norm(flat - goal[None], axis=-1).mean(axis=-1) / float(scale)
    return dist


def motion_alignment(trajs: Any, sketch: Sketch | Any, *, scale: float = 1.0) -> MotionAlignment:
    """``(min_l2, avg_l2)`` over the batch of :func:`sketch_distances` (negative ``MA``).

    >>> import numpy as np
    >>> trajs = np.array([[[0.0, 0.0], [1.0, 0.0]], [[0.0, 1.0], [1.0, 1.0]]])  # two plans of 2 steps
    >>> motion_alignment(trajs, Sketch([[0.0, 0.0], [1.0, 0.0]]))
    MotionAlignment(min_l2=0.0, avg_l2=0.5)
    """
    dist = sketch_distances(trajs, sketch, scale=scale)
    return MotionAlignment(min_l2=float(dist.min()), avg_l2=float(dist.mean()))


def constraint_satisfaction(violated: Any) -> float:
    """``CS``: the fraction of entries *without* a violation (``1 - collision rate``).

    >>> constraint_satisfaction([False, True, False, False])
    0.75
    """
    flags = _as_flags(violated, name="violated")
    return float(1.0 - flags.mean())


def task_alignment(aligned: Any) -> float:
    """``TA``: the fraction of interactions that executed the intended task.

    >>> task_alignment([1, 1, 0, 1])
    0.75
    """
    return float(_as_flags(aligned, name="aligned").mean())


def aligned_success(aligned: Any, success: Any) -> dict[str, float]:
    """Aligned-success quadrants of the ITPS block stacking / kitchen tables.

    Returns fractions ``AS`` (aligned success), ``AF`` (aligned failure), ``MS``
    (misaligned success), ``MF`` (misaligned failure), which sum to 1, plus
    ``TA = AS + AF`` and ``CS = AS + MS``.

    >>> aligned_success([True, True, False, False], [True, False, True, False])["TA"]
    0.5
    """
    a = _as_flags(aligned, name="aligned")
    s = _as_flags(success, name="success")
    if a.shape != s.shape:
        raise ValueError(f"`aligned` and `success` must have the same length, got {a.size} and {s.size}")
    n = float(a.size)
    quad = {
        "AS": np.count_nonzero(a & s) / n,
        "AF": np.count_nonzero(a & ~s) / n,
        "MS": np.count_nonzero(~a & s) / n,
        "MF": np.count_nonzero(~a & ~s) / n,
    }
    quad["TA"] = quad["AS"] + quad["AF"]
    quad["CS"] = quad["AS"] + quad["MS"]
    return {key: float(value) for key, value in quad.items()}
