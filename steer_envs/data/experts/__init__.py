"""Scripted experts: privileged controllers that solve each registered env.

Experts read the env's ground truth (the unwrapped env's task model and state)
and are used to generate demonstrations (TLI: 1-3 demos, GLiDE: fewer than 10)
and by the smoke suite. The expert of an env is declared by its registry entry
(:attr:`steer_envs.envs.registry.EnvEntry.expert`); use :func:`make_expert` to
get it.
"""

from __future__ import annotations

import importlib
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np

from steer_envs.envs.registry import ENTRIES, entry

__all__ = ["ScriptedExpert", "has_expert", "make_expert"]


@runtime_checkable
class ScriptedExpert(Protocol):
    """A closed-loop controller for one env instance."""

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Called after every ``env.reset``."""

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for the current observation."""


def make_expert(env: gym.Env[Any, Any], **kwargs: Any) -> ScriptedExpert:
    """The scripted expert of ``env`` (a made, possibly wrapped, steer-envs env).

    ``kwargs`` go to the expert's constructor. ``TypeError`` for a non-env,
    ``ValueError`` for an env without a registered id or without an expert.

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> env = gym.make("steer_envs/ConvexMode-v0")
    >>> expert = make_expert(env)
    >>> obs, info = env.reset(seed=0)
    >>> expert.reset(obs, info)
    >>> expert.act(obs, info).shape
    (2,)
    """
    if not isinstance(env, gym.Env):
        raise TypeError(f"make_expert: `env` must be a gymnasium.Env, got {type(env).__name__}")
    spec = env.spec or env.unwrapped.spec
    if spec is None:
        raise ValueError("make_expert: `env` has no spec; make it with gymnasium.make('steer_envs/...')")
    target = entry(spec.id).expert
    if target is None:
        raise ValueError(f"make_expert: no scripted expert for {spec.id!r}; experts exist for {_with_experts()}")
    module_name, cls_name = target.split(":")
    cls = getattr(importlib.import_module(module_name), cls_name)
    expert: ScriptedExpert = cls(env.unwrapped, **kwargs)
    return expert


def has_expert(env_id: str) -> bool:
    """Whether ``env_id`` (with or without the namespace) has a scripted expert.

    >>> has_expert("steer_envs/Cooking-v0")
    True
    """
    return entry(env_id).expert is not None


def _with_experts() -> list[str]:
    return [e.name for e in ENTRIES if e.expert is not None]
