"""Modes of states: the mode-predictor protocol, labelling demos, and the grounding metrics.

Anything with ``predict(states) -> modes`` is a :class:`ModePredictor`: the
trained GLiDE classifier (:class:`~steer_envs.baselines.glide.classifier.ModeClassifier`),
the k-means baseline (:class:`~steer_envs.baselines.glide.kmeans.KMeansSegmentation`,
:class:`~steer_envs.baselines.glide.kmeans.KMeansModes`) or a ground-truth oracle.
:func:`label_demonstrations` labels demonstrations with one (what GLiDE's
policies segment them by); :func:`workspace_grid`, :func:`mode_overlap` and
:func:`mode_iou` score a 2-D labelling against the ground truth.
No torch needed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

__all__ = ["ModePredictor", "label_demonstrations", "mode_iou", "mode_overlap", "workspace_grid"]


class ModePredictor(Protocol):
    """Anything that labels states with mode indices (classifier, k-means baseline)."""

    def predict(self, states: np.ndarray) -> np.ndarray:
        """The mode index of each state ``(N, d) -> (N,)``."""
        ...


def label_demonstrations(predictor: ModePredictor, demos: Sequence[np.ndarray], num_modes: int) -> list[np.ndarray]:
    """The predicted mode of every state of every demo (``(T_i,)`` int arrays).

    The labels are what :func:`~steer_envs.data.segmentation.segment_demonstrations`
    splits demonstrations by; a mode outside ``[0, num_modes)`` is an error.

    >>> import numpy as np
    >>> class LeftRight:  # mode 1 right of x = 0
    ...     def predict(self, s): return (np.asarray(s)[:, 0] > 0).astype(int)
    >>> label_demonstrations(LeftRight(), [np.array([[-1.0, 0.0], [1.0, 0.0]])], 2)
    [array([0, 1])]
    """
    if len(demos) == 0:
        raise ValueError("demos must not be empty")
    out = []
    for i, d in enumerate(demos):
        arr = np.asarray(d, dtype=np.float64)
        if arr.ndim != 2:
            raise ValueError(f"demos[{i}] must be (T, d), got {arr.shape}")
        modes = np.asarray(predictor.predict(arr), dtype=np.int64)
        if np.any((modes < 0) | (modes >= num_modes)):
            raise ValueError(f"the predictor returned modes outside [0, {num_modes}) for demos[{i}]")
        out.append(modes)
    return out


# --------------------------------------------------------------------------- metrics
def workspace_grid(low: np.ndarray, high: np.ndarray, resolution: int = 200) -> np.ndarray:
    """``resolution x resolution`` grid points ``(R*R, 2)`` spanning the box ``[low, high]``.

    >>> workspace_grid(np.zeros(2), np.ones(2), 2).tolist()
    [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]
    """
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or resolution < 2:
        raise ValueError(f"resolution must be an int >= 2, got {resolution!r}")
    lo, hi = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    if lo.shape != (2,) or hi.shape != (2,) or np.any(lo >= hi):
        raise ValueError("low and high must be 2-vectors with low < high")
    xs, ys = np.linspace(lo[0], hi[0], resolution), np.linspace(lo[1], hi[1], resolution)
    gx, gy = np.meshgrid(xs, ys)
    return np.stack([gx.ravel(), gy.ravel()], axis=1)


def mode_overlap(predicted: np.ndarray, truth: np.ndarray) -> float:
    """Fraction of points whose predicted mode equals the true mode (the grounding study's overlap).

    >>> mode_overlap(np.array([0, 1, 1, 2]), np.array([0, 1, 2, 2]))
    0.75
    """
    p, t = np.asarray(predicted), np.asarray(truth)
    if p.shape != t.shape or p.ndim != 1 or len(p) == 0:
        raise ValueError(f"predicted and truth must be equal-length 1-D arrays, got {p.shape} and {t.shape}")
    return float(np.mean(p == t))


def mode_iou(predicted: np.ndarray, truth: np.ndarray, num_modes: int) -> np.ndarray:
    """Per-mode intersection over union ``(K,)`` (stricter than overlap where one mode dominates the grid).

    >>> mode_iou(np.array([0, 1, 1, 2]), np.array([0, 1, 2, 2]), 3).round(2).tolist()
    [1.0, 0.5, 0.5]
    """
    p, t = np.asarray(predicted), np.asarray(truth)
    if p.shape != t.shape:
        raise ValueError(f"predicted and truth must have the same shape, got {p.shape} and {t.shape}")
    out = np.zeros(num_modes)
    for m in range(num_modes):
        union = np.sum((p == m) | (t == m))
        out[m] = np.sum((p == m) & (t == m)) / union if union else 1.0
    return out
