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
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, Generic, Self, TypeVar

import numpy as np

from steer_envs.baselines.common.normalize import MAX_FEATURE_DIM, NORMALIZATION_MODES
from steer_envs.core.validation import boolean, describe, integer, one_of, real_scalar

__all__ = ["PRECISIONS", "PolicyConfig", "Preset", "TrainSettings", "check_int", "int_tuple"]

#: the longest tuple field of a config (``down_dims``, index lists)
_MAX_TUPLE = 4096


def check_int(value: Any, name: str, minimum: int = 1) -> int:
    """``value`` as an int ``>= minimum``: ``TypeError`` for another kind (bools and floats are not ints),
    ``ValueError`` naming ``name`` when it is too small.

    >>> check_int(3, "horizon")
    3
    """
    return integer(value, name, low=minimum)


def int_tuple(value: Any, name: str, minimum: int = 0) -> tuple[int, ...]:
    """``value`` (a list or tuple of ints ``>= minimum``, not a string) as a tuple of ints.

    >>> int_tuple([8, 16], "down_dims", 1)
    (8, 16)
    """
    if not isinstance(value, (list, tuple, range, np.ndarray)) or (isinstance(value, np.ndarray) and value.ndim != 1):
        raise TypeError(f"{name} must be a list or tuple of ints, got {describe(value)}")
    if len(value) > _MAX_TUPLE:
        raise ValueError(f"{name} may have at most {_MAX_TUPLE} entries, got {len(value)}")
    return tuple(integer(v, f"{name} entry", low=minimum) for v in value)


def _indices(value: Any, name: str) -> tuple[int, ...] | None:
    if value is None:
        return None
    out = int_tuple(value, name, 0)
    if not out or len(set(out)) != len(out):
        raise ValueError(f"{name} must be non-empty and without repeats, got {list(out)}")
    return out


class _FieldsMixin:
    """What a policy config and the training settings share: their field names, validated copies, dicts."""

    @classmethod
    def field_names(cls) -> set[str]:
        """Names of the fields (what ``--model`` / ``--train KEY=VALUE`` accept)."""
        return {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]

    def replace(self, **changes: Any) -> Self:
        """A copy with ``changes`` (validated); ``ValueError`` naming an unknown field."""
        unknown = set(changes) - self.field_names()
        if unknown:
            fields = ", ".join(sorted(self.field_names()))
            raise ValueError(f"{sorted(unknown)} not fields of {type(self).__name__} (fields: {fields})")
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> Self:
        """Inverse of ``to_dict`` (lists become tuples); ``ValueError`` naming an unknown key."""
        if not isinstance(values, Mapping):
            raise TypeError(f"values must be a mapping, got {type(values).__name__}")
        unknown = set(values) - cls.field_names()
        if unknown:
            raise ValueError(f"{sorted(unknown)} not fields of {cls.__name__}")
        kwargs: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return cls(**kwargs)


@dataclass(frozen=True, kw_only=True)
class PolicyConfig(_FieldsMixin):
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

    Every field is checked without coercion: ints must be ints (not floats,
    bools or strings; sizes at most :data:`MAX_FEATURE_DIM`), index fields
    lists or tuples of ints, ``relative`` a bool; ``TypeError`` for the wrong
    kind, ``ValueError`` for a wrong value, naming the field.
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
                object.__setattr__(self, name, integer(getattr(self, name), name, low=1, high=MAX_FEATURE_DIM))
        one_of(self.normalization, "normalization", NORMALIZATION_MODES)
        for name in ("obs_indices", "action_obs_indices"):
            object.__setattr__(self, name, _indices(getattr(self, name), name))
        object.__setattr__(self, "relative", boolean(self.relative, "relative"))
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

    # ------------------------------------------------- plan layout (each config class gives its own)
    @property
    def horizon(self) -> int:
        """Waypoints per plan."""
        raise NotImplementedError

    @property
    def n_obs_steps(self) -> int:
        """Observations of history the policy conditions on."""
        raise NotImplementedError

    @property
    def exec_start(self) -> int:
        """Index of the first plan waypoint to execute (``plan[:exec_start]`` re-states observed steps)."""
        raise NotImplementedError

    @property
    def window_layout(self) -> dict[str, int]:
        """:class:`~steer_envs.data.trajectories.PlanWindows` arguments giving the policy's training pairs."""
        raise NotImplementedError

    def parameter_count(self) -> int | None:
        """Numbers in the state dict of the network this config builds, computed without building it.

        Loaders compare it with a checkpoint's tensors before allocating
        anything; ``None`` where a config class cannot tell (the check is then
        skipped). The features must be set.
        """
        return None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (tuples become lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


#: the arithmetic of the training forward pass: float32, or bfloat16 autocast (AMX units on recent CPUs)
PRECISIONS = ("fp32", "bf16")
#: the most optimizer steps and the largest batch :class:`TrainSettings` accepts
MAX_TRAIN_STEPS = 10**9
MAX_BATCH_SIZE = 2**20


@dataclass(frozen=True)
class TrainSettings(_FieldsMixin):
    """Optimization settings of one training run (AdamW, linear warm-up then cosine decay to 0).

    ``static_history_prob``: the fraction of training histories replaced by the
    current observation repeated, i.e. what a policy sees right after a reset
    (only matters with ``n_obs_steps > 1``). ``ema_power > 0`` keeps an
    exponential moving average of the weights (Diffusion Policy's warm-up
    decay ``1 - (1 + step) ** -power``) and saves it instead of the raw weights.

    Speed options (recorded, since each changes the numerics slightly):
    ``precision="bf16"`` runs the forward pass under bfloat16 autocast (the
    weights and the optimizer stay float32), ``fused_optimizer`` uses torch's
    fused AdamW kernel, ``compile_model`` trains a ``torch.compile`` of the
    network (the first steps pay for the compilation).

    Accepted: ints for ``steps`` (at most :data:`MAX_TRAIN_STEPS`),
    ``batch_size`` (at most :data:`MAX_BATCH_SIZE`), ``log_every`` (>= 1),
    ``warmup_steps`` and ``seed`` (>= 0); finite reals for ``lr`` and
    ``grad_clip`` (> 0), ``weight_decay`` (>= 0), ``betas`` (two in [0, 1)),
    ``static_history_prob`` and ``ema_power`` (in [0, 1]). Strings, bools
    and NaN are refused (``TypeError`` / ``ValueError`` naming the field);
    ``precision`` is one of :data:`PRECISIONS`, the two speed switches bools.

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
    precision: str = "fp32"
    fused_optimizer: bool = False
    compile_model: bool = False

    def __post_init__(self) -> None:
        for name, low, high in (
            ("steps", 1, MAX_TRAIN_STEPS),
            ("batch_size", 1, MAX_BATCH_SIZE),
            ("log_every", 1, None),
            ("warmup_steps", 0, None),
            ("seed", 0, None),
        ):
            object.__setattr__(self, name, integer(getattr(self, name), name, low=low, high=high))
        for name in ("lr", "grad_clip"):
            object.__setattr__(self, name, real_scalar(getattr(self, name), name, low=0.0, low_inclusive=False))
        object.__setattr__(self, "weight_decay", real_scalar(self.weight_decay, "weight_decay", low=0.0))
        if not isinstance(self.betas, (list, tuple)) or len(self.betas) != 2:
            raise ValueError(f"betas must be two floats in [0, 1), got {describe(self.betas)}")
        betas = tuple(real_scalar(b, "betas entry", low=0.0, high=1.0, high_inclusive=False) for b in self.betas)
        object.__setattr__(self, "betas", betas)
        prob = real_scalar(self.static_history_prob, "static_history_prob", low=0.0, high=1.0)
        object.__setattr__(self, "static_history_prob", prob)
        object.__setattr__(self, "ema_power", real_scalar(self.ema_power, "ema_power", low=0.0, high=1.0))
        one_of(self.precision, "precision", PRECISIONS)
        for name in ("fused_optimizer", "compile_model"):
            object.__setattr__(self, name, boolean(getattr(self, name), name))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {**asdict(self), "betas": list(self.betas)}


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
