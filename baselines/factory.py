"""Policy name -> (config class, policy class, presets), and making or loading a policy by name.

The registry is the one place that knows which policies exist: the training
CLI, :mod:`steer_envs.baselines.pretrained` and checkpoint loading go through
it. :func:`make_policy` builds a policy for a dataset the way every
trajectory policy is built: features and normalization statistics from the
data, the rest from the config. A new domain needs no new model code, only a
:class:`~steer_envs.data.trajectories.TrajectoryDataset` and, if the shipped
presets do not fit, a preset (:func:`register_preset`).

>>> import numpy as np
>>> from steer_envs.data.trajectories import TrajectoryDataset
>>> data = TrajectoryDataset(np.random.default_rng(0).normal(size=(50, 7)), np.zeros((50, 4)))
>>> config = make_policy_config("dp", horizon=8, down_dims=(8, 16), obs_embed_dim=8)
>>> policy = make_policy(config, dataset=data)
>>> type(policy).__name__, policy.obs_dim, policy.action_dim
('DiffusionPolicy', 7, 4)
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import torch

from steer_envs.baselines.act import PRESETS as ACT_PRESETS
from steer_envs.baselines.act import ACTConfig, ACTPolicy
from steer_envs.baselines.common.configuration import PolicyConfig, Preset
from steer_envs.baselines.common.torch_policy import CHECKPOINT_FORMAT, TorchPolicy, check_device, read_checkpoint
from steer_envs.baselines.diffusion import PRESETS as DP_PRESETS
from steer_envs.baselines.diffusion import DiffusionConfig, DiffusionPolicy
from steer_envs.baselines.flow import PRESETS as FLOW_PRESETS
from steer_envs.baselines.flow import FlowConfig, FlowPolicy
from steer_envs.data.trajectories import TrajectoryDataset
from steer_envs.io import CheckpointError

__all__ = [
    "POLICIES",
    "PolicySpec",
    "get_config_class",
    "get_policy_class",
    "get_preset",
    "load_policy",
    "make_policy",
    "make_policy_config",
    "policy_names",
    "register_policy",
    "register_preset",
    "with_dataset_features",
]


@dataclass
class PolicySpec:
    """What the factory knows about one policy: its classes and its named presets."""

    config_class: type[PolicyConfig]
    policy_class: type[TorchPolicy]
    presets: dict[str, Preset[Any]] = field(default_factory=dict)


#: policy name -> spec. Extend with :func:`register_policy` / :func:`register_preset`.
POLICIES: dict[str, PolicySpec] = {
    "dp": PolicySpec(DiffusionConfig, DiffusionPolicy, dict(DP_PRESETS)),
    "act": PolicySpec(ACTConfig, ACTPolicy, dict(ACT_PRESETS)),
    "flow": PolicySpec(FlowConfig, FlowPolicy, dict(FLOW_PRESETS)),
}


def policy_names() -> list[str]:
    """The registered policy names, sorted.

    >>> policy_names()
    ['act', 'dp', 'flow']
    """
    return sorted(POLICIES)


def _spec(name: str) -> PolicySpec:
    if not isinstance(name, str) or name not in POLICIES:
        raise ValueError(f"policy must be one of {policy_names()}, got {name!r}")
    return POLICIES[name]


def get_policy_class(name: str) -> type[TorchPolicy]:
    """The policy class registered as ``name`` (``ValueError`` for an unknown name).

    >>> get_policy_class("act").__name__
    'ACTPolicy'
    """
    return _spec(name).policy_class


def get_config_class(name: str) -> type[PolicyConfig]:
    """The config class registered as ``name``.

    >>> get_config_class("dp").__name__
    'DiffusionConfig'
    """
    return _spec(name).config_class


def get_preset(name: str, preset: str) -> Preset[Any]:
    """Preset ``preset`` of policy ``name``; ``ValueError`` listing the presets otherwise.

    >>> get_preset("dp", "cpu").train.steps
    40000
    """
    presets = _spec(name).presets
    if preset not in presets:
        raise ValueError(f"preset must be one of {sorted(presets)} for {name}, got {preset!r}")
    return presets[preset]


def register_policy(name: str, config_class: type[PolicyConfig], policy_class: type[TorchPolicy]) -> None:
    """Add a policy to the registry (its ``policy_class.name`` must be ``name``)."""
    if not (isinstance(config_class, type) and issubclass(config_class, PolicyConfig)):
        raise TypeError(f"config_class must be a PolicyConfig subclass, got {config_class!r}")
    if not (isinstance(policy_class, type) and issubclass(policy_class, TorchPolicy)):
        raise TypeError(f"policy_class must be a TorchPolicy subclass, got {policy_class!r}")
    if getattr(policy_class, "name", None) != name or policy_class.config_class is not config_class:
        raise ValueError(f"policy_class.name must be {name!r} and its config_class {config_class.__name__}")
    if name in POLICIES:
        raise ValueError(f"policy {name!r} is already registered")
    POLICIES[name] = PolicySpec(config_class, policy_class)


def register_preset(name: str, preset_name: str, preset: Preset[Any]) -> None:
    """Register ``preset`` as ``preset_name`` for policy ``name`` (e.g. a new domain's settings).

    >>> from steer_envs.baselines.common import TrainSettings
    >>> register_preset("dp", "doc-example", Preset(DiffusionConfig(horizon=16), TrainSettings(steps=5)))
    >>> get_preset("dp", "doc-example").model.horizon
    16
    >>> del POLICIES["dp"].presets["doc-example"]
    """
    spec = _spec(name)
    if not isinstance(preset, Preset) or not isinstance(preset.model, spec.config_class):
        raise TypeError(f"preset must be a Preset of a {spec.config_class.__name__}, got {preset!r}")
    if preset_name in spec.presets:
        raise ValueError(f"{name} already has a preset {preset_name!r}")
    spec.presets[preset_name] = preset


def make_policy_config(name: str, *, preset: str | None = None, **overrides: Any) -> PolicyConfig:
    """The config of policy ``name``: its defaults, or preset ``preset``'s model, with ``overrides``.

    >>> make_policy_config("act", preset="itps").d_model
    512
    """
    spec = _spec(name)
    base = spec.config_class() if preset is None else get_preset(name, preset).model
    return base.replace(**overrides) if overrides else base


def with_dataset_features(config: PolicyConfig, dataset: TrajectoryDataset) -> PolicyConfig:
    """``config`` with its unset feature fields taken from ``dataset``; ``ValueError`` on a mismatch."""
    found = {
        "obs_dim": dataset.obs_dim,
        "action_dim": dataset.action_dim,
        "obs_indices": dataset.obs_indices,
        "action_obs_indices": dataset.action_obs_indices,
    }
    changes = {}
    for key, value in found.items():
        current = getattr(config, key)
        if current is None:
            if value is not None:
                changes[key] = value
        elif value is not None and current != value:
            raise ValueError(f"config.{key} is {current!r} but the dataset has {value!r}")
    return config.replace(**changes) if changes else config


def make_policy(
    config: PolicyConfig | str,
    *,
    dataset: TrajectoryDataset | None = None,
    stats: Mapping[str, Any] | None = None,
    seed: int = 0,
    device: str | torch.device = "cpu",
) -> TorchPolicy:
    """A fresh policy for ``config`` (or the defaults of a policy name), fitted to ``dataset``.

    With ``dataset`` the config's unset features come from it and the
    normalization statistics are ``dataset.stats()`` (unless ``stats`` is
    given). Without, the config must have its features set; ``stats=None``
    then means data already normalized.
    """
    if isinstance(config, str):
        config = make_policy_config(config)
    if not isinstance(config, PolicyConfig):
        raise TypeError(f"config must be a PolicyConfig or a policy name, got {type(config).__name__}")
    matches = [n for n, s in POLICIES.items() if type(config) is s.config_class]
    if not matches:
        raise ValueError(f"no registered policy takes a {type(config).__name__}")
    if dataset is not None:
        if not isinstance(dataset, TrajectoryDataset):
            raise TypeError(f"dataset must be a TrajectoryDataset, got {type(dataset).__name__}")
        config = with_dataset_features(config, dataset)
        if stats is None:
            stats = dataset.stats()
    return POLICIES[matches[0]].policy_class(config, stats, seed=seed, device=device)


def load_policy(
    path: str | os.PathLike[str], *, name: str | None = None, device: str | torch.device = "cpu"
) -> TorchPolicy:
    """The policy saved at ``path``, of whichever registered kind it holds (``name``: require that kind).

    :class:`~steer_envs.io.CheckpointError` (a ``ValueError``, naming the file)
    when the file is missing, truncated, not a checkpoint, of another kind than
    ``name``, or inconsistent (see :meth:`TorchPolicy.from_checkpoint`); an
    unknown ``name`` or a bad ``device`` is a ``ValueError`` / ``TypeError``.
    """
    if name is not None:
        _spec(name)
    check_device(device)
    tensors, header = read_checkpoint(path)
    fmt = header.get("format")
    if fmt == CHECKPOINT_FORMAT:
        found = header.get("policy")
    else:
        found = next((n for n, s in POLICIES.items() if s.policy_class.legacy_format == fmt), None)
    if not isinstance(found, str) or found not in POLICIES:
        raise CheckpointError(f"{path} holds format {fmt!r} / policy {header.get('policy')!r}, not a registered policy")
    if name is not None and found != name:
        raise CheckpointError(f"{path} holds a {found!r} policy, expected {name!r}")
    return POLICIES[found].policy_class.from_checkpoint(tensors, header, device=device, source=str(path))
