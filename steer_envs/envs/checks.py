"""Argument checks shared by the envs: ``reset`` seeds and options, render modes, reward types, xy and actions.

Each returns the checked value or raises ``TypeError`` (wrong kind) / ``ValueError``
(wrong value) naming the argument and its owner.

>>> check_options({"state": [0.0, 0.0]}, frozenset({"state"}), "MyEnv.reset")
{'state': [0.0, 0.0]}
>>> check_seed(3, "MyEnv.reset"), check_vector_seed(3, 2, "MyVectorEnv.reset")
(3, [3, 4])
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from gymnasium import spaces

from steer_envs.core.validation import describe, integer, one_of, real_array

#: accepted ``reward_type`` values (Gymnasium-Robotics' names): ``"sparse"`` (the default) or ``"dense"``.
REWARD_TYPES: tuple[str, ...] = ("sparse", "dense")
RewardType = Literal["sparse", "dense"]


def check_reward_type(reward_type: Any, owner: str) -> RewardType:
    """``reward_type``: ``"sparse"`` or ``"dense"`` (:data:`REWARD_TYPES`); anything else is a ``ValueError``."""
    if not isinstance(reward_type, str):
        raise TypeError(f"{owner}: reward_type must be one of {list(REWARD_TYPES)}, got {describe(reward_type)}")
    one_of(reward_type, "reward_type", REWARD_TYPES, owner=owner)
    return "dense" if reward_type == "dense" else "sparse"


def check_seed(seed: Any, owner: str) -> int | None:
    """A ``reset`` seed: None or an int >= 0 (numpy ints too), as a Python int."""
    return None if seed is None else integer(seed, "seed", low=0, owner=owner)


def check_options(options: Any, keys: frozenset[str], owner: str) -> dict[str, Any]:
    """``reset`` options: None or a dict with only the known ``keys``; unknown keys are an error, not ignored."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise TypeError(f"{owner}: options must be a dict or None, got {describe(options)}")
    unknown = set(options) - keys
    if unknown:
        raise ValueError(f"{owner}: unknown reset options {sorted(map(str, unknown))}; expected some of {sorted(keys)}")
    return dict(options)


def check_render_mode(render_mode: Any, modes: list[str], owner: str) -> str | None:
    """``render_mode``: None or one of ``modes``."""
    if render_mode is None:
        return None
    if not isinstance(render_mode, str):
        raise TypeError(f"{owner}: render_mode must be one of {modes} or None, got {describe(render_mode)}")
    return one_of(render_mode, "render_mode", modes, owner=owner)


def check_xy(value: Any, name: str, owner: str | None = None) -> np.ndarray:
    """A state or displacement: 2 finite real numbers (see :func:`steer_envs.core.validation.real_array`)."""
    return real_array(value, name, shape=(2,), owner=owner)


def check_action(action: Any, space: spaces.Space[Any], owner: str | None = None) -> np.ndarray:
    """An action: finite real numbers of the action space's shape (not yet clipped)."""
    return real_array(action, "action", shape=space.shape, owner=owner)


def check_vector_seed(seed: Any, num_envs: int, owner: str) -> list[int | None]:
    """A vector ``reset`` seed as one seed per agent: None (all None), an int ``s`` >= 0
    (``s, s + 1, ...``) or a list of ``num_envs`` seeds, each None or an int >= 0 (the sync vector env's rules).
    """
    if seed is None:
        return [None] * num_envs
    if isinstance(seed, list | tuple):
        if len(seed) != num_envs:
            raise ValueError(f"{owner}: seed as a list must hold num_envs={num_envs} seeds, got {len(seed)}")
        return [check_seed(s, owner) for s in seed]
    first = check_seed(seed, owner)
    assert first is not None
    return [first + i for i in range(num_envs)]
