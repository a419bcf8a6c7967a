"""Feature statistics and the normalizers built from them (min-max to [-1, 1], mean/std, identity).

A policy normalizes its observations and its actions separately, each with
the statistics of that feature over the training data. Statistics travel as a
plain mapping ``{"observation": {"min": ..., "max": ..., "mean": ..., "std": ...},
"action": {...}}`` (what :meth:`steer_envs.data.trajectories.TrajectoryDataset.stats`
returns and what a checkpoint stores), or as :class:`FeatureStats` per feature.

A dimension that is constant in the data (``max == min`` or ``std == 0``) is
mapped to 0 instead of being divided by zero: its range is widened to
``value +- 1`` (min-max) or its std taken as 1 (mean/std).

>>> norm = Normalizer("min_max", FeatureStats(min=[0.0, 0.0], max=[2.0, 4.0]), dim=2)
>>> norm.normalize([[1.0, 4.0]]).tolist()
[[0.0, 1.0]]
>>> norm.unnormalize([[0.0, 1.0]]).tolist()
[[1.0, 4.0]]
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from steer_envs.core.validation import real_array

__all__ = ["FEATURES", "NORMALIZATION_MODES", "FeatureStats", "Normalizer", "as_coords", "parse_stats"]

#: how a feature is mapped to the network's units: ``min_max`` -> [-1, 1]; ``mean_std`` -> zero mean, unit std.
NORMALIZATION_MODES = ("min_max", "mean_std", "identity")
#: the features a trajectory policy normalizes.
FEATURES = ("observation", "action")
_NEEDS = {"min_max": ("min", "max"), "mean_std": ("mean", "std"), "identity": ()}
#: the most dimensions a feature's statistics may have
MAX_FEATURE_DIM = 2**20


def as_coords(value: Any, d: int, name: str) -> np.ndarray:
    """``value`` as a float64 array of ``d``-dimensional points ``(..., d)``; raises naming ``name``.

    Real numbers only (``TypeError`` for strings, complex numbers, bools,
    objects); NaN and inf pass through (they map to NaN / inf).

    >>> as_coords([1, 2], 2, "point").dtype
    dtype('float64')
    """
    arr = real_array(value, name, finite=False)
    if arr.ndim == 0 or arr.shape[-1] != d:
        raise ValueError(f"{name} must have shape (..., {d}), got {arr.shape}")
    return arr


def _vector(value: Any, name: str) -> np.ndarray | None:
    if value is None:
        return None
    arr = real_array(value, name, max_size=MAX_FEATURE_DIM)
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D array of finite floats, got shape {arr.shape}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class FeatureStats:
    """Per-dimension statistics of one feature over a dataset; any of them may be absent.

    A normalizer checks that the ones its mode needs are present (min-max:
    ``min``/``max``; mean/std: ``mean``/``std``).

    >>> FeatureStats.from_data([[0.0, 1.0], [2.0, 3.0]]).to_dict()
    {'min': [0.0, 1.0], 'max': [2.0, 3.0], 'mean': [1.0, 2.0], 'std': [1.0, 1.0]}
    """

    min: Any = None
    max: Any = None
    mean: Any = None
    std: Any = None

    def __post_init__(self) -> None:
        dims = set()
        for key in ("min", "max", "mean", "std"):
            arr = _vector(getattr(self, key), key)
            object.__setattr__(self, key, arr)
            if arr is not None:
                dims.add(arr.shape[0])
        if len(dims) > 1:
            raise ValueError(f"min, max, mean and std must have one length, got {sorted(dims)}")
        if self.min is not None and self.max is not None and np.any(self.max < self.min):
            raise ValueError(
                f"max must be >= min in every dimension, got min={self.min.tolist()} max={self.max.tolist()}"
            )
        if self.std is not None and np.any(self.std < 0):
            raise ValueError(f"std must be >= 0, got {self.std.tolist()}")

    @property
    def dim(self) -> int | None:
        """Number of dimensions (``None`` when no statistic is set)."""
        for key in ("min", "max", "mean", "std"):
            arr = getattr(self, key)
            if arr is not None:
                return int(arr.shape[0])
        return None

    @classmethod
    def from_data(cls, data: Any) -> FeatureStats:
        """All four statistics of ``data`` ``(N, d)`` along its first axis (float64)."""
        arr = real_array(data, "data")
        if arr.ndim != 2 or len(arr) == 0:
            raise ValueError(f"data must have shape (N, d) with N >= 1, got {arr.shape}")
        return cls(min=arr.min(axis=0), max=arr.max(axis=0), mean=arr.mean(axis=0), std=arr.std(axis=0))

    @classmethod
    def from_dict(cls, value: FeatureStats | Mapping[str, Any]) -> FeatureStats:
        """From ``{"min": [...], ...}`` (unknown keys are a ``ValueError``); a ``FeatureStats`` passes through."""
        if isinstance(value, FeatureStats):
            return value
        if not isinstance(value, Mapping):
            raise TypeError(f"feature statistics must be a mapping or FeatureStats, got {type(value).__name__}")
        unknown = set(value) - {"min", "max", "mean", "std"}
        if unknown:
            raise ValueError(f"unknown statistics {sorted(unknown)}; expected min, max, mean, std")
        return cls(**dict(value))

    def to_dict(self) -> dict[str, list[float]]:
        """JSON-ready: the statistics that are set, as lists."""
        return {k: getattr(self, k).tolist() for k in ("min", "max", "mean", "std") if getattr(self, k) is not None}

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FeatureStats):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


def parse_stats(stats: Mapping[str, Any] | None) -> dict[str, FeatureStats]:
    """``{"observation": ..., "action": ...}`` (mappings or :class:`FeatureStats`) -> ``FeatureStats`` per feature.

    ``None`` gives empty statistics for both (only the identity mode, or a
    policy's defaults, can use them).

    >>> parse_stats({"observation": {"mean": [0.0], "std": [1.0]}, "action": {}})["observation"].dim
    1
    """
    if stats is None:
        return {name: FeatureStats() for name in FEATURES}
    if not isinstance(stats, Mapping):
        raise TypeError(f"stats must be a mapping {{'observation': ..., 'action': ...}}, got {type(stats).__name__}")
    unknown = set(stats) - set(FEATURES)
    if unknown:
        raise ValueError(f"stats has unknown features {sorted(unknown)}; expected {list(FEATURES)}")
    return {name: FeatureStats.from_dict(stats.get(name, {})) for name in FEATURES}


class Normalizer:
    """Maps one feature between data units and the network's units; numpy in numpy out, torch in torch out.

    Args:
        mode: one of :data:`NORMALIZATION_MODES`.
        stats: the feature's statistics (those the mode needs must be set).
        dim: the feature's dimension (checked against the statistics).
        name: the feature's name, for error messages.

    ``min_max``: ``2 (x - min) / (max - min) - 1``; ``mean_std``: ``(x - mean) / std``.
    Torch inputs are computed in their own dtype and device.
    """

    def __init__(self, mode: str, stats: FeatureStats, dim: int, name: str = "feature") -> None:
        if mode not in NORMALIZATION_MODES:
            raise ValueError(f"mode must be one of {NORMALIZATION_MODES}, got {mode!r}")
        if not isinstance(stats, FeatureStats):
            raise TypeError(f"stats must be FeatureStats, got {type(stats).__name__}")
        self.mode, self.dim, self.name = mode, int(dim), name
        missing = [k for k in _NEEDS[mode] if getattr(stats, k) is None]
        if missing:
            raise ValueError(f"{mode} normalization of {name} needs the statistics {missing}, got {stats.to_dict()}")
        for key in _NEEDS[mode]:
            if getattr(stats, key).shape != (self.dim,):
                raise ValueError(
                    f"{name} statistic {key!r} must have {self.dim} entries, got {getattr(stats, key).size}"
                )
        self.stats = stats
        if mode == "min_max":
            const = stats.max == stats.min
            a, b = np.where(const, stats.min - 1.0, stats.min), np.where(const, stats.max + 1.0, stats.max)
        elif mode == "mean_std":
            a, b = stats.mean, np.where(stats.std == 0, 1.0, stats.std)
        else:
            a = b = np.zeros(self.dim)
        with np.errstate(over="ignore"):
            span = np.asarray(b, np.float64) - np.asarray(a, np.float64) if mode == "min_max" else np.asarray(b)
        if not np.all(np.isfinite(span)):
            raise ValueError(f"{name} statistics span more than a float64 can hold, got {stats.to_dict()}")
        #: the two parameters of the affine map: (low, high) for min-max, (mean, std) for mean/std
        self.params: tuple[np.ndarray, np.ndarray] = (np.array(a, np.float64), np.array(b, np.float64))
        self._cache: dict[tuple[torch.device, torch.dtype], tuple[torch.Tensor, torch.Tensor]] = {}

    def _torch(self, like: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if not like.is_floating_point() or like.ndim == 0 or like.shape[-1] != self.dim:
            got = f"{like.dtype} {tuple(like.shape)}"
            raise ValueError(f"{self.name} must be a floating tensor of shape (..., {self.dim}), got {got}")
        key = (like.device, like.dtype)
        if key not in self._cache:
            a, b = (torch.as_tensor(p, dtype=torch.float64).to(like.device, like.dtype) for p in self.params)
            self._cache[key] = (a, b)
        return self._cache[key]

    def _operands(self, x: Any) -> tuple[Any, Any, Any]:
        """``x`` checked (an array or tensor of shape ``(..., dim)``) and the mode's two parameters in its kind."""
        if isinstance(x, torch.Tensor):
            return (x, *self._torch(x))
        return (as_coords(x, self.dim, self.name), *self.params)

    def normalize(self, x: Any) -> Any:
        """Data units -> network units, elementwise over ``(..., dim)``."""
        if self.mode == "identity":
            return x if isinstance(x, torch.Tensor) else as_coords(x, self.dim, self.name)
        x, a, b = self._operands(x)
        if self.mode == "min_max":
            return 2 * (x - a) / (b - a) - 1
        return (x - a) / b

    def unnormalize(self, x: Any) -> Any:
        """Inverse of :meth:`normalize`."""
        if self.mode == "identity":
            return x if isinstance(x, torch.Tensor) else as_coords(x, self.dim, self.name)
        x, a, b = self._operands(x)
        if self.mode == "min_max":
            return (x + 1) / 2 * (b - a) + a
        return x * b + a

    def __repr__(self) -> str:
        return f"Normalizer({self.mode!r}, dim={self.dim}, name={self.name!r})"
