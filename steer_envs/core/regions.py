"""Regions of a task's space: unions of axis-aligned boxes, what a plan must stay out of or inside.

A :class:`Boxes` region is what :class:`~steer_envs.core.task.TaskSpec`
names in ``regions`` (a maze's walls, a mode's workspace); the steering
safety cost (:func:`steer_envs.steering.costs.safety_cost`) penalises how
deep a plan goes into a forbidden one. ``dims`` says which plan entries the
boxes live in (a maze: the xy of a plan of xy; an arm: the xyz of
``[x, y, z, gripper]``).

>>> walls = Boxes([[0.5, 0.5]], [[1.5, 1.5]])
>>> walls.contains([[1.0, 1.0], [2.0, 2.0]]).tolist()
[True, False]
>>> walls.depth([[1.0, 1.2], [2.0, 2.0]]).round(2).tolist()  # how far inside (0 outside)
[0.3, 0.0]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from steer_envs.core.validation import real_array

__all__ = ["Boxes"]


@dataclass(frozen=True, eq=False)
class Boxes:
    """A union of ``k`` axis-aligned boxes ``low[i] <= p <= high[i]`` in the plan entries ``dims``.

    Args:
        low, high: ``(k, m)`` corners (``low <= high``), finite reals.
        dims: the ``m`` plan entries the boxes constrain (default: the first ``m``).
    """

    low: np.ndarray
    high: np.ndarray
    dims: tuple[int, ...] = field(default=())

    def __post_init__(self) -> None:
        low = real_array(self.low, "`low`", owner="Boxes").astype(np.float64)
        high = real_array(self.high, "`high`", owner="Boxes").astype(np.float64)
        if low.ndim != 2 or low.shape != high.shape or low.shape[1] < 1:
            raise ValueError(f"Boxes: `low` and `high` must both be (k, m) arrays, got {low.shape} and {high.shape}")
        if np.any(high < low):
            raise ValueError("Boxes: every `high` must be >= its `low`")
        dims = tuple(range(low.shape[1])) if self.dims == () else tuple(int(i) for i in self.dims)
        if len(dims) != low.shape[1] or len(set(dims)) != len(dims) or min(dims) < 0:
            raise ValueError(f"Boxes: `dims` must name {low.shape[1]} distinct plan entries, got {self.dims!r}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)
        object.__setattr__(self, "dims", dims)

    @classmethod
    def cells(
        cls, centers: Sequence[Sequence[float]] | np.ndarray, size: float = 1.0, dims: Sequence[int] = ()
    ) -> Boxes:
        """Square cells of side ``size`` around ``centers`` ``(k, m)`` (a maze's wall cells)."""
        c = np.asarray(centers, dtype=np.float64).reshape(len(centers), -1)
        return cls(c - size / 2, c + size / 2, tuple(dims))

    def __len__(self) -> int:
        return len(self.low)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Boxes):
            return NotImplemented
        return self.dims == other.dims and np.array_equal(self.low, other.low) and np.array_equal(self.high, other.high)

    def __hash__(self) -> int:
        return hash((self.dims, self.low.tobytes(), self.high.tobytes()))

    def _points(self, points: Any) -> np.ndarray:
        arr = real_array(points, "`points`", owner="Boxes").astype(np.float64)
        if arr.ndim == 0 or arr.shape[-1] <= max(self.dims):
            raise ValueError(f"Boxes: `points` need entries {self.dims} on the last axis, got shape {arr.shape}")
        return arr[..., list(self.dims)]

    def depth(self, points: Any) -> np.ndarray:
        """``(...)``: how far each point is inside the union (distance to the nearest face out; 0 outside)."""
        p = self._points(points)[..., None, :]
        inside = np.minimum(p - self.low, self.high - p).min(axis=-1)  # (..., k), negative outside a box
        return np.clip(inside.max(axis=-1), 0.0, None) if len(self) else np.zeros(p.shape[:-2])

    def contains(self, points: Any) -> np.ndarray:
        """``(...)`` bool: whether each point lies in one of the boxes (faces included)."""
        p = self._points(points)[..., None, :]
        return ((p >= self.low) & (p <= self.high)).all(axis=-1).any(axis=-1)
