"""Scripted experts: privileged controllers that solve each registered env.

Experts read the env's ground truth (the unwrapped env's task model and state)
and are used to generate demonstrations (TLI: 1-3 demos, GLiDE: fewer than 10)
and by the smoke suite. The expert of an env is declared by its registry entry
(:attr:`steer_envs.envs.registry.EnvEntry.expert`); use :func:`make_expert` to
get it.
"""

from __future__ import annotations

import importlib
import sys
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np

from steer_envs.envs.registry import ENTRIES, entry

__all__ = ["RLConventionExpert", "ScriptedExpert", "has_expert", "make_expert"]


@runtime_checkable
class ScriptedExpert(Protocol):
    """A closed-loop controller for one env instance."""

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Called after every ``env.reset``."""

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for the current observation."""


def make_expert(env: gym.Env[Any, Any], **kwargs: Any) -> ScriptedExpert:
    """The scripted expert of ``env`` (a made, possibly wrapped, steer-envs env).

    ``kwargs`` go to the expert's constructor. On an env made with RL options
    (the ``...Dense-v0`` ids) it comes wrapped in :class:`RLConventionExpert`,
    which maps its observations and actions. ``TypeError`` for a non-env,
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
    if _rl_conventions(env.unwrapped):
        return RLConventionExpert(expert, env.unwrapped)
    return expert


def _rl_conventions(env: Any) -> bool:
    """Whether ``env`` (unwrapped) observes or acts unlike the thesis's interface the experts are written for."""
    from steer_envs.envs.kinematic import Kinematic2DEnv

    if isinstance(env, Kinematic2DEnv):
        return bool(env.observe_sensors or env.normalize_actions)
    maze = sys.modules.get("steer_envs.envs.maze2d")  # imported if env is a Maze2D (no MuJoCo import otherwise)
    return maze is not None and isinstance(env, maze.Maze2DEnv) and bool(env.normalize_actions or env.relative_actions)


class RLConventionExpert:
    """A scripted expert on an env made with RL options (the ``...Dense-v0`` ids' observed sensors, normalised
    or relative actions): the expert plans in the plain interface (xy; a velocity or an absolute waypoint), this
    hands it the xy part of the observation and turns its action into the env's.

    Kinematic envs: the velocity over ``max_speed`` when ``normalize_actions``; Maze2D: the waypoint mapped
    linearly into ``[-1, 1]^2`` (``normalize_actions``) or its offset from the agent clipped to one cell
    (``relative_actions``). Other attributes, read or set, are the wrapped expert's.

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> env = gym.make("steer_envs/ConvexModeDense-v0")  # sensors observed, actions in [-1, 1]
    >>> expert = make_expert(env)
    >>> obs, info = env.reset(seed=0)
    >>> expert.reset(obs, info)
    >>> bool(abs(expert.act(obs, info)).max() <= 1.0), type(expert.inner).__name__
    (True, 'ConvexModeExpert')
    """

    _OWN = frozenset({"inner", "env"})

    def __init__(self, inner: ScriptedExpert, env: Any) -> None:
        self.inner = inner
        self.env = env

    def __getattr__(self, name: str) -> Any:
        if name in self._OWN:  # not set yet (e.g. while unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.inner, name)

    def __setattr__(self, name: str, value: Any) -> None:
        # a setting of the expert (e.g. a gain) reaches the expert, not this wrapper
        if name in self._OWN:
            object.__setattr__(self, name, value)
        else:
            setattr(self.inner, name, value)

    def _obs(self, obs: Any) -> Any:
        if getattr(self.env, "observe_sensors", False) and hasattr(self.env, "max_speed"):  # kinematic: xy first
            return np.asarray(obs)[..., :2]
        return obs

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        """The wrapped expert's reset, on the observation's xy part (kinematic envs)."""
        self.inner.reset(self._obs(obs), info)

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """The wrapped expert's action in the env's action convention (float32)."""
        action = np.asarray(self.inner.act(self._obs(obs), info), dtype=np.float64)
        env = self.env
        if hasattr(env, "max_speed"):  # kinematic: a velocity
            out = action / env.max_speed if env.normalize_actions else action
        elif env.relative_actions:  # Maze2D: an absolute waypoint
            out = np.clip(action - env.state, -1.0, 1.0)
        else:
            low, high = env.grid.low, env.grid.high
            out = np.clip(2.0 * (action - low) / (high - low) - 1.0, -1.0, 1.0)
        return out.astype(np.float32)


def has_expert(env_id: str) -> bool:
    """Whether ``env_id`` (with or without the namespace) has a scripted expert.

    >>> has_expert("steer_envs/Cooking-v0")
    True
    """
    return entry(env_id).expert is not None


def _with_experts() -> list[str]:
    return [e.name for e in ENTRIES if e.expert is not None]
