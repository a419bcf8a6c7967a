"""Scripted experts: privileged controllers that solve each registered env.

Experts read the env's ground truth (``env.unwrapped.model``) and are used to
generate demonstrations (TLI: 1-3 demos, GLiDE: < 10) and by the smoke suite.
Use :func:`make_expert` to get the expert of any registered env.
"""

from __future__ import annotations

import importlib
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np

from steer_envs.envs.registry import entry

#: env name (without namespace and version-specific kwargs) -> "module:Class"
_EXPERTS: dict[str, str] = {
    "SoupScoop-v0": "steer_envs.data.experts.soup_scoop:SoupScoopExpert",
    "Cooking-v0": "steer_envs.data.experts.cooking:CookingExpert",
    "ConvexMode-v0": "steer_envs.data.experts.convex_mode:ConvexModeExpert",
    "PolygonNav-3Mode-v0": "steer_envs.data.experts.polygon_nav:PolygonNavExpert",
    "PolygonNav-4Mode-v0": "steer_envs.data.experts.polygon_nav:PolygonNavExpert",
    "PolygonNav-5Mode-v0": "steer_envs.data.experts.polygon_nav:PolygonNavExpert",
    "Maze2D-Umaze-v0": "steer_envs.data.experts.maze2d:Maze2DExpert",
    "Maze2D-Medium-v0": "steer_envs.data.experts.maze2d:Maze2DExpert",
    "Maze2D-Large-v0": "steer_envs.data.experts.maze2d:Maze2DExpert",
}


@runtime_checkable
class ScriptedExpert(Protocol):
    """A closed-loop controller for one env instance."""

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Called after every ``env.reset``."""

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for the current observation."""


def make_expert(env: gym.Env, **kwargs: Any) -> ScriptedExpert:
    """The scripted expert of ``env`` (a made, possibly wrapped, steer-envs env)."""
    if not isinstance(env, gym.Env):
        raise TypeError(f"env must be a gymnasium.Env, got {type(env).__name__}")
    spec = env.spec or env.unwrapped.spec
    if spec is None:
        raise ValueError("env has no spec; make it with gymnasium.make('steer_envs/...')")
    name = entry(spec.id).name
    if name not in _EXPERTS:
        raise ValueError(f"no scripted expert for {spec.id!r}; experts exist for {sorted(_EXPERTS)}")
    module_name, cls_name = _EXPERTS[name].split(":")
    cls = getattr(importlib.import_module(module_name), cls_name)
    return cls(env.unwrapped, **kwargs)


def has_expert(env_id: str) -> bool:
    """Whether ``env_id`` has a scripted expert."""
    return entry(env_id).name in _EXPERTS
