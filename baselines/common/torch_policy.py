"""The base of the chunked trajectory policies (DP, ACT): seeded network, device, normalizers, checkpoints.

A checkpoint is one safetensors file: the weights plus a JSON header in its
``__metadata__`` naming the policy, its config and its normalization
statistics (safetensors executes no code on load, unlike a pickle). It is
written atomically through :mod:`steer_envs.io`.

>>> from steer_envs.baselines.act import ACTConfig, ACTPolicy
>>> policy = ACTPolicy(ACTConfig(obs_dim=3, action_dim=2, chunk_size=4, d_model=8, n_heads=1, dim_feedforward=8))
>>> policy.observation_history([1.0, 2.0, 3.0]).shape
(1, 3)
"""

from __future__ import annotations

import os
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, ClassVar, Self

import numpy as np
import torch

from steer_envs.baselines.common.checkpoint import (
    check_parameter_count,
    check_state,
    read_safetensors,
    write_safetensors,
)
from steer_envs.baselines.common.configuration import PolicyConfig
from steer_envs.baselines.common.normalize import FEATURES, FeatureStats, Normalizer, parse_stats
from steer_envs.core.validation import describe, integer, real_array
from steer_envs.io import CheckpointError

__all__ = [
    "CHECKPOINT_FORMAT",
    "MAX_SAMPLES",
    "CheckpointError",
    "TorchPolicy",
    "check_device",
    "check_sample_args",
    "check_tensor",
    "observation_history",
    "read_checkpoint",
    "write_checkpoint",
]

#: the ``format`` of the checkpoint header written by :meth:`TorchPolicy.save`.
CHECKPOINT_FORMAT = "steer_envs.baselines.policy/2"
#: the most plans one ``sample`` call draws (the batch goes through the network at once)
MAX_SAMPLES = 65536


def observation_history(
    obs: Any, n_obs: int, obs_dim: int, obs_indices: tuple[int, ...] | None = None, *, owner: str | None = None
) -> np.ndarray:
    """The last ``n_obs`` policy observations ``(n_obs, obs_dim)`` float32 from an env observation or history.

    ``obs`` is one observation ``(D,)`` or a history ``(k, D)``, oldest first:
    finite real numbers (a sequence, numpy array or torch tensor; strings,
    complex numbers and bools are a ``TypeError``, NaN/inf and other shapes a
    ``ValueError``, naming ``owner``). With ``obs_indices`` the policy's
    observation is those entries of each (``D`` may be larger); without, ``D``
    must be ``obs_dim``. A history shorter than ``n_obs`` is padded by
    repeating its oldest entry, as LeRobot fills its observation queue after a
    reset (one observation = at rest).

    >>> observation_history([1.0, 2.0, 0.5, 0.5], 2, 2, (0, 1)).tolist()
    [[1.0, 2.0], [1.0, 2.0]]
    """
    arr = real_array(obs, "obs", owner=owner)
    if arr.ndim == 1:
        arr = arr[None]
    if obs_indices is None:
        ok, want = arr.ndim == 2 and arr.shape[1] == obs_dim, f"D = obs_dim = {obs_dim}"
    else:
        ok, want = arr.ndim == 2 and arr.shape[1] > max(obs_indices), f"D > {max(obs_indices)} (obs_indices)"
    where = f"{owner}: obs" if owner else "obs"
    if not ok or arr.shape[0] < 1:
        raise ValueError(f"{where} must have shape (D,) or (k, D) with {want}, got {np.shape(arr)}")
    hist = arr[-n_obs:] if obs_indices is None else arr[-n_obs:, list(obs_indices)]
    if len(hist) < n_obs:
        hist = np.concatenate([np.repeat(hist[:1], n_obs - len(hist), axis=0), hist])
    return hist.astype(np.float32)


def check_sample_args(
    n: Any, generator: Any, *, owner: str | None = None, max_samples: int = MAX_SAMPLES
) -> np.random.Generator:
    """Validate ``sample``'s ``n`` (an int in ``[1, max_samples]``) and ``generator`` (a numpy ``Generator``
    or ``None``); returns the generator to draw from."""
    integer(n, "n", low=1, high=max_samples, owner=owner)
    if generator is not None and not isinstance(generator, np.random.Generator):
        where = f"{owner}: generator" if owner else "generator"
        raise TypeError(f"{where} must be a numpy Generator or None, got {describe(generator)}")
    return generator if generator is not None else np.random.default_rng()


def check_tensor(
    value: Any, name: str, shape: tuple[int | None, ...], *, owner: str | None = None, finite: bool = True
) -> torch.Tensor:
    """``value`` if it is a real (floating or integer, not bool or complex) torch tensor of ``shape``.

    ``None`` in ``shape`` matches any length. ``TypeError`` for another kind,
    ``ValueError`` for another shape or (with ``finite``) NaN / inf entries.
    """
    where = f"{owner}: {name}" if owner else name
    if not isinstance(value, torch.Tensor):
        raise TypeError(f"{where} must be a torch.Tensor, got {describe(value)}")
    if value.is_complex() or value.dtype == torch.bool:
        raise TypeError(f"{where} must hold real numbers, got dtype {value.dtype}")
    if value.ndim != len(shape) or any(w is not None and w != g for w, g in zip(shape, value.shape, strict=False)):
        want = "(" + ", ".join("N" if w is None else str(w) for w in shape) + ")"
        raise ValueError(f"{where} must have shape {want}, got {tuple(value.shape)}")
    if finite and value.is_floating_point() and not bool(torch.isfinite(value.detach()).all()):
        raise ValueError(f"{where} must be finite (no NaN or inf)")
    return value


def check_device(device: Any, name: str = "device") -> torch.device:
    """``device`` (a ``torch.device`` or a string such as ``"cpu"``, ``"cuda:0"``) as a ``torch.device``."""
    if not isinstance(device, (str, torch.device)):
        raise TypeError(f"{name} must be a torch.device or a str such as 'cpu', got {describe(device)}")
    if isinstance(device, str):
        try:
            device = torch.device(device)
        except (RuntimeError, ValueError):
            raise ValueError(f"{name} must name a torch device such as 'cpu' or 'cuda:0', got {device!r}") from None
    if device.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"{name} is {str(device)!r} but CUDA is not available (torch {torch.__version__})")
    if device.type == "cuda" and device.index is not None and device.index >= torch.cuda.device_count():
        raise ValueError(f"{name} is {str(device)!r} but only {torch.cuda.device_count()} CUDA devices exist")
    return device


def _default_stats(mode: str, dim: int) -> FeatureStats:
    """Statistics under which ``mode`` is the identity map (for a policy made without data)."""
    if mode == "min_max":
        return FeatureStats(min=-np.ones(dim), max=np.ones(dim))
    if mode == "mean_std":
        return FeatureStats(mean=np.zeros(dim), std=np.ones(dim))
    return FeatureStats()


class TorchPolicy(ABC):
    """What DP and ACT share: config, normalizers, a network built under a fixed seed, checkpoints.

    Subclasses set :attr:`name` and :attr:`config_class`, build the network in
    :meth:`_build_model` and implement the plan layout, ``sample`` and ``loss``.

    Args:
        config: the policy's config; its feature fields must be set.
        stats: normalization statistics ``{"observation": ..., "action": ...}``
            (mappings of ``min``/``max``/``mean``/``std`` or
            :class:`~steer_envs.baselines.common.normalize.FeatureStats`), e.g.
            ``dataset.stats()``; ``None``: the identity (data already normalized).
        seed: seed of the initial weights (the caller's torch RNG is left alone).
        device: torch device of the network.
    """

    #: the policy's name in the factory and in checkpoints
    name: ClassVar[str]
    config_class: ClassVar[type[PolicyConfig]]
    #: the pre-factory checkpoint format this class can still read (see :meth:`upgrade_legacy`)
    legacy_format: ClassVar[str | None] = None

    model: torch.nn.Module
    _device: torch.device
    #: the plan entries a user's point or sketch constrains (``None``: all; read by the ITPS samplers)
    interaction_dims: tuple[int, ...] | None = None

    def __init__(
        self,
        config: PolicyConfig,
        stats: Mapping[str, Any] | None = None,
        *,
        seed: int = 0,
        device: str | torch.device = "cpu",
    ) -> None:
        if not isinstance(config, self.config_class):
            raise TypeError(f"config must be a {self.config_class.__name__}, got {type(config).__name__}")
        config.require_features()
        self.config = config
        dims = {"observation": self.obs_dim, "action": self.action_dim}
        parsed = parse_stats(stats)
        if stats is None:
            parsed = {k: _default_stats(config.normalization, dims[k]) for k in FEATURES}
        #: the normalization statistics per feature (saved in the checkpoint)
        self.stats: dict[str, FeatureStats] = parsed
        self.obs_normalizer = Normalizer(
            config.normalization, parsed["observation"], dims["observation"], "observation"
        )
        self.action_normalizer = Normalizer(config.normalization, parsed["action"], dims["action"], "action")
        self._check_relative()
        #: the ``extra`` dict of the checkpoint the policy was loaded from
        self.checkpoint_info: dict[str, Any] = {}
        self._init_network(self._build_model, seed, device)

    def _check_relative(self) -> None:
        if not self.config.relative or self.config.action_obs_indices is None:
            return
        idx = list(self.config.action_obs_indices)
        obs_p, act_p = self.obs_normalizer.params, self.action_normalizer.params
        if not all(np.array_equal(o[idx], a) for o, a in zip(obs_p, act_p, strict=True)):
            raise ValueError(
                "relative=True: the observation entries action_obs_indices="
                f"{list(self.config.action_obs_indices)} must be normalized with the actions' statistics, got "
                f"{self.stats['observation'].to_dict()} vs {self.stats['action'].to_dict()}"
            )

    def _init_network(self, build: Callable[[], torch.nn.Module], seed: Any, device: str | torch.device) -> None:
        seed = integer(seed, "seed", low=0, owner=type(self).__name__)
        self._device = check_device(device)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(int(seed))
            self.model = build()
        self.model.to(self._device).eval()

    @abstractmethod
    def _build_model(self) -> torch.nn.Module:
        """The network for ``self.config`` (called under the weight seed)."""

    # ------------------------------------------------------------ features
    @property
    def obs_dim(self) -> int:
        """Entries of the policy's observation at one step."""
        assert self.config.obs_dim is not None  # checked by require_features
        return self.config.obs_dim

    @property
    def action_dim(self) -> int:
        """Entries of one plan waypoint."""
        assert self.config.action_dim is not None
        return self.config.action_dim

    @property
    def horizon(self) -> int:
        """Waypoints per plan (the config's)."""
        return self.config.horizon

    @property
    def n_obs_steps(self) -> int:
        """Observations of history the policy conditions on (the config's)."""
        return self.config.n_obs_steps

    @property
    def exec_start(self) -> int:
        """Index of the first plan waypoint to execute (the config's)."""
        return self.config.exec_start

    @property
    def window_layout(self) -> dict[str, int]:
        """:class:`~steer_envs.data.trajectories.PlanWindows` arguments giving this policy's training pairs."""
        return self.config.window_layout

    @abstractmethod
    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        """``n`` plans ``(n, horizon, action_dim)`` float64 in data units."""

    @abstractmethod
    def loss(self, obs: torch.Tensor, plans: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """Training loss on a batch ``obs (B, n_obs_steps, obs_dim)``, ``plans (B, horizon, action_dim)``."""

    #: the most plans one :meth:`sample` call draws (raise it on a class or an instance for a large GPU)
    max_samples: int = MAX_SAMPLES

    def observation_history(self, obs: Any) -> np.ndarray:
        """The policy's observation history ``(n_obs_steps, obs_dim)`` from an env observation or history.

        See :func:`observation_history` for what ``obs`` may be.
        """
        return observation_history(
            obs, self.n_obs_steps, self.obs_dim, self.config.obs_indices, owner=f"{type(self).__name__}"
        )

    def encode_obs(self, obs: Any) -> torch.Tensor:
        """Global condition ``(1, n_obs_steps * obs_dim)``: the normalized observation history (DP, the flow)."""
        hist = self.observation_history(obs)
        return self.obs_normalizer.normalize(torch.from_numpy(hist).to(self._device)).reshape(1, -1)

    def _noised_batch(
        self, obs: torch.Tensor, plans: torch.Tensor, generator: torch.Generator | None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.device]:
        """A checked training batch: ``(normalized plans, condition, standard normal noise, generator device)``.

        The noise is the first draw from ``generator`` (on its device), so a
        loss that draws its noise level next keeps one draw order.
        """
        self._check_batch(obs, plans, generator)
        clean = self.normalize(plans.to(self._device, torch.float32))
        cond = self.obs_normalizer.normalize(obs.to(self._device, torch.float32)).reshape(plans.shape[0], -1)
        gen_device = generator.device if generator is not None else self._device
        noise = torch.randn(clean.shape, generator=generator, device=gen_device).to(self._device)
        return clean, cond, noise, gen_device

    def _sample_args(self, n: Any, generator: Any) -> np.random.Generator:
        return check_sample_args(n, generator, owner=f"{type(self).__name__}.sample", max_samples=self.max_samples)

    def _check_batch(self, obs: Any, plans: Any, generator: Any) -> None:
        """``loss``'s arguments: real finite tensors ``obs (B, n_obs_steps, obs_dim)``, ``plans (B, horizon,
        action_dim)``, and a ``torch.Generator`` or ``None``."""
        owner = f"{type(self).__name__}.loss"
        plans = check_tensor(plans, "plans", (None, self.horizon, self.action_dim), owner=owner)
        check_tensor(obs, "obs", (plans.shape[0], self.n_obs_steps, self.obs_dim), owner=owner)
        if generator is not None and not isinstance(generator, torch.Generator):
            raise TypeError(f"{owner}: generator must be a torch.Generator or None, got {describe(generator)}")

    def normalize(self, traj: Any) -> Any:
        """Plans / actions in data units -> network units, over ``(..., action_dim)``; numpy or torch."""
        return self.action_normalizer.normalize(traj)

    def unnormalize(self, traj: Any) -> Any:
        """Inverse of :meth:`normalize`."""
        return self.action_normalizer.unnormalize(traj)

    # -------------------------------------------------------------- device
    @property
    def device(self) -> torch.device:
        """Torch device of the network."""
        return self._device

    def to(self, device: str | torch.device) -> Self:
        """Move the network to ``device``; returns self."""
        self._device = check_device(device)
        self.model.to(self._device)
        return self

    def num_parameters(self) -> int:
        """Trainable parameters of the network."""
        return sum(p.numel() for p in self.model.parameters())

    # --------------------------------------------------------- persistence
    def save(self, path: str | os.PathLike[str], extra: Mapping[str, Any] | None = None) -> Path:
        """Write weights, config and normalization statistics to a ``.safetensors`` file atomically."""
        header = {
            "format": CHECKPOINT_FORMAT,
            "policy": self.name,
            "config": self.config.to_dict(),
            "stats": {k: v.to_dict() for k, v in self.stats.items()},
            "extra": dict(extra or {}),
        }
        return write_checkpoint(path, self.model.state_dict(), header)

    @classmethod
    def load(cls, path: str | os.PathLike[str], device: str | torch.device = "cpu") -> Self:
        """A policy from a file written by :meth:`save` (safetensors: loading runs no code).

        :class:`~steer_envs.io.CheckpointError` (naming the file) for anything
        wrong with the file: see :meth:`from_checkpoint`.
        """
        check_device(device)
        tensors, header = read_checkpoint(path)
        return cls.from_checkpoint(tensors, header, device=device, source=str(path))

    @classmethod
    def from_checkpoint(
        cls,
        tensors: Mapping[str, torch.Tensor],
        header: Mapping[str, Any],
        *,
        device: str | torch.device = "cpu",
        source: str = "checkpoint",
    ) -> Self:
        """A policy from the contents of a checkpoint (see :func:`read_checkpoint`).

        Everything is checked before the network is built: the header's format
        and policy name, the config and statistics, the network size the
        config implies (at most
        :data:`~steer_envs.baselines.common.checkpoint.MAX_PARAMETERS`, and
        equal to the numbers the tensors hold), then the tensors' names, shapes
        and dtypes against the built network. Any mismatch is a
        :class:`~steer_envs.io.CheckpointError` naming ``source``.
        """
        check_device(device)
        if not isinstance(header, Mapping):
            raise CheckpointError(f"{source}: the checkpoint header must be a JSON object, got {describe(header)}")
        fmt = header.get("format")
        try:
            if fmt == CHECKPOINT_FORMAT:
                if header.get("policy") != cls.name:
                    raise CheckpointError(f"{source} holds a {header.get('policy')!r} policy, expected {cls.name!r}")
                config, stats = cls.config_class.from_dict(header["config"]), header["stats"]
            elif cls.legacy_format is not None and fmt == cls.legacy_format:
                config, stats = cls.upgrade_legacy(header)
            else:
                raise CheckpointError(f"{source} holds format {fmt!r}, expected {CHECKPOINT_FORMAT!r} ({cls.name})")
            config.require_features()
            expected = config.parameter_count()
        except CheckpointError:
            raise
        except (KeyError, TypeError, ValueError, AttributeError) as err:
            raise CheckpointError(
                f"{source}: malformed {cls.name} checkpoint header ({type(err).__name__}: {err})"
            ) from None
        if expected is not None:
            check_parameter_count(expected, tensors, source)
        extra = header.get("extra", {})
        if not isinstance(extra, Mapping):
            raise CheckpointError(f"{source}: the header's 'extra' must be a JSON object, got {describe(extra)}")
        try:
            policy = cls(config, stats, device=device)
        except (TypeError, ValueError) as err:
            raise CheckpointError(f"{source}: {err}") from None
        check_state(policy.model.state_dict(), tensors, source)
        policy.model.load_state_dict(dict(tensors))
        policy.model.to(policy.device).eval()
        policy.checkpoint_info = dict(extra)
        return policy

    @classmethod
    def upgrade_legacy(cls, header: Mapping[str, Any]) -> tuple[PolicyConfig, dict[str, Any]]:
        """Config and statistics from a header in :attr:`legacy_format` (subclasses that have one)."""
        raise ValueError(f"{cls.name} has no legacy checkpoint format")

    @classmethod
    def upgrade_legacy_config(cls, values: Mapping[str, Any]) -> PolicyConfig:
        """A config from the ``model`` dict of a legacy checkpoint or training record."""
        raise ValueError(f"{cls.name} has no legacy config format")


def write_checkpoint(path: str | os.PathLike[str], tensors: Mapping[str, torch.Tensor], header: dict[str, Any]) -> Path:
    """Write ``tensors`` with ``header`` (JSON-serializable) as a safetensors file, atomically.

    ``ValueError`` for a path not ending in ``.safetensors`` or tensors holding NaN / inf.
    """
    return write_safetensors(path, tensors, "config", header)


def read_checkpoint(path: str | os.PathLike[str]) -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
    """Tensors and header of a file written by :func:`write_checkpoint`, checked before loading.

    :class:`~steer_envs.io.CheckpointError` (a ``ValueError``) naming the file
    for a missing, truncated, corrupt or foreign file and for non-finite
    weights (see :func:`~steer_envs.baselines.common.checkpoint.read_safetensors`).
    """
    return read_safetensors(path, "config")
