"""Helpers the robosuite tests share: module marks, a module-scoped env fixture, refused bad arguments."""

from __future__ import annotations

import importlib.util
from collections.abc import Callable, Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from steer_envs.utils.imports import resolve_function

#: ``pytestmark`` of a robosuite test module: robosuite's warnings ignored, skipped without the extra
ROBOSUITE_MARKS = [
    pytest.mark.filterwarnings("ignore::DeprecationWarning", "ignore::UserWarning"),
    pytest.mark.skipif(importlib.util.find_spec("robosuite") is None, reason="the robosuite extra is not installed"),
]


def module_env(maker: str, *args: Any) -> Callable[[], Iterator[gym.Env[Any, Any]]]:
    """A module-scoped fixture of an env, closed after the module's tests.

    ``maker``: an env id (``gym.make(maker, *args)``) or a ``"module:function"``
    that makes one (``function(*args)``, imported when the fixture first runs).
    """

    @pytest.fixture(scope="module")
    def env() -> Iterator[gym.Env[Any, Any]]:
        made = resolve_function(maker)(*args) if ":" in maker else gym.make(maker, *args)
        yield made
        made.close()

    return env


def lazy_arms() -> Iterator[dict[str, gym.Env[Any, Any]]]:
    """A fixture body: a dict that makes ``steer_envs/<name>-v0`` on first lookup; every env made is closed after."""
    made: dict[str, gym.Env[Any, Any]] = {}

    class Lazy(dict[str, gym.Env[Any, Any]]):
        def __missing__(self, name: str) -> gym.Env[Any, Any]:
            made[name] = self[name] = gym.make(f"steer_envs/{name}-v0")
            return made[name]

    yield Lazy()
    for env in made.values():
        env.close()


def refuse_bad_perturb_and_action(env: gym.Env[Any, Any]) -> np.ndarray:
    """A NaN push, a push to a string and an action of the wrong size raise; returns the eef state before them."""
    base = env.unwrapped
    before = base.state
    with pytest.raises(ValueError, match="delta"):
        base.perturb(delta=[np.nan, 0.0, 0.0])
    with pytest.raises(TypeError, match="to"):
        base.perturb(to="up")
    with pytest.raises(ValueError, match="action"):
        env.step(np.zeros(6))
    return before
