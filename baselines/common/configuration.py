"""What every trajectory-policy config shares, the training settings, and the preset that pairs them.

:class:`PolicyConfig` carries the input/output features of a policy and how
they are normalized; the feature fields left ``None`` are filled from the
training dataset by :func:`steer_envs.baselines.factory.make_policy`. A
:class:`Preset` is a named (model config, :class:`TrainSettings`) pair,
registered per policy (``steer_envs.baselines.factory.register_preset``).

>>> from steer_envs.baselines.diffusion import DiffusionConfig
>>> preset = Preset(DiffusionConfig(horizon=16, down_dims=(8, 16)), TrainSettings(steps=10))
>>> preset.model.obs_dim is None, preset.train.steps
(True, 10)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, Generic, Self, TypeVar

import numpy as np

from steer_envs.baselines.common.normalize import NORMALIZATION_MODES

__all__ = ["PolicyConfig", "Preset", "TrainSettings", "check_int"]


def check_int(value: Any, name: str, minimum: int = 1) -> int:
    """``value`` as an int ``>= minimum``; ``ValueError`` naming ``name`` otherwise (bools are not ints).

    >>> check_int(3, "horizon")
    3
    """
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < minimum:
        raise ValueError(f"{name} must be an int >= {minimum}, got {value!r}")
    return int(value)


def _indices(value: Any, name: str) -> tuple[int, ...] | None:
    if value is None:
        return None
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise TypeError(f"{name} must be a sequence of ints or None, got {type(value).__name__}")
    out = tuple(check_int(v, f"{name} entry", 0) for v in value)
    if not out or len(set(out)) != len(out):
        raise ValueError(f"{name} must be non-empty and without repeats, got {list(out)}")
    return out


@dataclass(frozen=True, kw_only=True)
class PolicyConfig:
    """Features and normalization of a trajectory policy (the base of each policy's config).

    Attributes:
        obs_dim: entries of the policy's observation at one step (``None``: from the dataset).
        action_dim: entries of one plan waypoint / action (``None``: from the dataset).
        normalization: how observations and actions are normalized, one of
            :data:`~steer_envs.baselines.common.normalize.NORMALIZATION_MODES`,
            each with its own feature's statistics.
        obs_indices: the entries of the env observation that form the policy's
            observation, e.g. ``(0, 1)`` for the position of an ``(x, y, vx, vy)``
            observation. ``None``: the whole observation, which must have
            ``obs_dim`` entries.
        action_obs_indices: for position-controlled actions, the observation
            entry each action dimension sets (the action is that entry's next
            value); ``None`` when actions are not states. Needed by ``relative``.
        relative: plan relative to the current state: the network sees plans
            minus the current values of ``action_obs_indices`` (normalized).
            Those observation entries must be normalized with the same
            statistics as the actions (datasets that declare
            ``action_obs_indices`` pool them).
    """

    obs_dim: int | None = None
    action_dim: int | None = None
    normalization: str = "min_max"
    obs_indices: tuple[int, ...] | None = None
    action_obs_indices: tuple[int, ...] | None = None
    relative: bool = False

    def __post_init__(self) -> None:
        for name in ("obs_dim", "action_dim"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, check_int(getattr(self, name), name))
        if self.normalization not in NORMALIZATION_MODES:
            raise ValueError(f"normalization must be one of {NORMALIZATION_MODES}, got {self.normalization!r}")
        for name in ("obs_indices", "action_obs_indices"):
            object.__setattr__(self, name, _indices(getattr(self, name), name))
        if not isinstance(self.relative, bool):
            raise TypeError(f"relative must be a bool, got {type(self.relative).__name__}")
        if self.obs_indices is not None and self.obs_dim is not None and len(self.obs_indices) != self.obs_dim:
            raise ValueError(f"obs_indices must have obs_dim={self.obs_dim} entries, got {list(self.obs_indices)}")
        if self.action_obs_indices is not None:
            if self.action_dim is not None and len(self.action_obs_indices) != self.action_dim:
                raise ValueError(
                    f"action_obs_indices must have action_dim={self.action_dim} entries, "
                    f"got {list(self.action_obs_indices)}"
                )
            if self.obs_dim is not None and max(self.action_obs_indices) >= self.obs_dim:
                raise ValueError(
                    f"action_obs_indices must index the observation (< obs_dim={self.obs_dim}), "
                    f"got {list(self.action_obs_indices)}"
                )

    def require_features(self) -> None:
        """``ValueError`` unless the features a network needs are set (a policy calls this)."""
        missing = [name for name in ("obs_dim", "action_dim") if getattr(self, name) is None]
        if missing:
            raise ValueError(
                f"{type(self).__name__}.{' and '.join(missing)} must be set (make_policy takes them from the dataset)"
            )
        if self.relative and self.action_obs_indices is None:
            raise ValueError(
                "relative=True needs action_obs_indices (the observation entries the actions set); "
                "the dataset declares none: set relative=False or declare them"
            )

    def replace(self, **changes: Any) -> Self:
        """A copy with ``changes`` (validated); ``ValueError`` naming an unknown field."""
        unknown = set(changes) - self.field_names()
        if unknown:
            fields = ", ".join(sorted(self.field_names()))
            raise ValueError(f"{sorted(unknown)} not fields of {type(self).__name__} (fields: {fields})")
        return dataclasses.replace(self, **changes)

    @classmethod
    def field_names(cls) -> set[str]:
        """Names of the config's fields (what ``--model KEY=VALUE`` accepts)."""
        return {f.name for f in dataclasses.fields(cls)}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (tuples become lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> Self:
        """Inverse of :meth:`to_dict` (lists become tuples); ``ValueError`` naming an unknown key."""
        if not isinstance(values, Mapping):
            raise TypeError(f"values must be a mapping, got {type(values).__name__}")
        unknown = set(values) - cls.field_names()
        if unknown:
            raise ValueError(f"{sorted(unknown)} not fields of {cls.__name__}")
        kwargs: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return cls(**kwargs)


@dataclass(frozen=True)
class TrainSettings:
    """Optimization settings of one training run (AdamW, linear warm-up then cosine decay to 0).

    ``static_history_prob``: the fraction of training histories replaced by the
    current observation repeated, i.e. what a policy sees right after a reset
    (only matters with ``n_obs_steps > 1``). ``ema_power > 0`` keeps an
    exponential moving average of the weights (Diffusion Policy's warm-up
    decay ``1 - (1 + step) ** -power``) and saves it instead of the raw weights.

    >>> TrainSettings(steps=100, lr=1e-4).batch_size
    64
    """

    steps: int = 1000
    batch_size: int = 64
    lr: float = 1e-3
    weight_decay: float = 1e-6
    betas: tuple[float, float] = (0.95, 0.999)
    warmup_steps: int = 200
    grad_clip: float = 10.0
    static_history_prob: float = 0.0
    ema_power: float = 0.0
    seed: int = 0
    log_every: int = 50

    def __post_init__(self) -> None:
        for name in ("steps", "batch_size", "warmup_steps", "seed", "log_every"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise TypeError(f"{name} must be an int, got {type(value).__name__}")
        if self.steps < 1 or self.batch_size < 1 or self.log_every < 1:
            raise ValueError(
                f"steps, batch_size and log_every must be >= 1, got {self.steps}, {self.batch_size}, {self.log_every}"
            )
        if self.warmup_steps < 0 or self.seed < 0:
            raise ValueError(f"warmup_steps and seed must be >= 0, got {self.warmup_steps} and {self.seed}")
        for name in ("lr", "grad_clip"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite float, got {value!r}")
        if not (math.isfinite(self.weight_decay) and self.weight_decay >= 0):
            raise ValueError(f"weight_decay must be a finite float >= 0, got {self.weight_decay!r}")
        betas = tuple(float(b) for b in self.betas)
        if len(betas) != 2 or not all(0 <= b < 1 for b in betas):
            raise ValueError(f"betas must be two floats in [0, 1), got {self.betas!r}")
        object.__setattr__(self, "betas", betas)
        if not 0 <= self.static_history_prob <= 1:
            raise ValueError(f"static_history_prob must be in [0, 1], got {self.static_history_prob!r}")
        if not (math.isfinite(self.ema_power) and 0 <= self.ema_power <= 1):
            raise ValueError(f"ema_power must be in [0, 1] (0 = no EMA), got {self.ema_power!r}")

    def replace(self, **changes: Any) -> TrainSettings:
        """A copy with ``changes``; ``ValueError`` naming an unknown field."""
        unknown = set(changes) - self.field_names()
        if unknown:
            raise ValueError(f"{sorted(unknown)} not fields of TrainSettings (fields: {sorted(self.field_names())})")
        return dataclasses.replace(self, **changes)

    @classmethod
    def field_names(cls) -> set[str]:
        """Names of the settings (what ``--train KEY=VALUE`` accepts)."""
        return {f.name for f in dataclasses.fields(cls)}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {**asdict(self), "betas": list(self.betas)}

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> TrainSettings:
        """Inverse of :meth:`to_dict`; ``ValueError`` naming an unknown key."""
        unknown = set(values) - cls.field_names()
        if unknown:
            raise ValueError(f"{sorted(unknown)} not fields of TrainSettings")
        kwargs: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return cls(**kwargs)


ConfigT = TypeVar("ConfigT", bound=PolicyConfig)


@dataclass(frozen=True)
class Preset(Generic[ConfigT]):
    """A named starting point for training: the model config and the training settings.

    The config's feature fields are normally left ``None`` (taken from the dataset).
    """

    model: ConfigT
    train: TrainSettings
    description: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.model, PolicyConfig):
            raise TypeError(f"model must be a PolicyConfig, got {type(self.model).__name__}")
        if not isinstance(self.train, TrainSettings):
            raise TypeError(f"train must be TrainSettings, got {type(self.train).__name__}")
