"""What a policy observes: an observation history stacked for it, an observation with the agent moved.

:func:`policy_observation` is what ``policy.sample`` gets from an episode's
observations (a stacked history for policies with ``n_obs_steps > 1``);
:func:`place_observation` is the observation of an agent teleported to a
point (OP's default, and what :class:`~steer_envs.wrappers.SteeringWrapper`
records after OP moved the agent).

>>> class TwoSteps:
...     n_obs_steps = 2
>>> policy_observation(TwoSteps(), [[1.0, 2.0]]).tolist()  # a fresh reset: the first observation repeated
[[1.0, 2.0], [1.0, 2.0]]
>>> place_observation([[0.0, 0.0, 0.5, 0.5]], [3.0, 4.0]).tolist()
[[3.0, 4.0, 0.0, 0.0]]
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["place_observation", "policy_observation"]


def policy_observation(policy: Any, history: Sequence[Any]) -> Any:
    """What ``policy.sample`` gets from an observation history (oldest first, current last).

    ``policy.n_obs_steps > 1``: the last ``n_obs_steps`` observations stacked
    ``(n_obs_steps, obs_dim)``, padded at the front with the oldest one (a
    freshly reset agent has been at rest). Otherwise the current observation.
    """
    if len(history) == 0:
        raise ValueError("`history` must hold at least the current observation")
    steps = getattr(policy, "n_obs_steps", 1)
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"policy.n_obs_steps must be a positive int, got {steps!r}")
    if steps == 1:
        return history[-1]
    recent = list(history[-int(steps) :])
    recent = [recent[0]] * (steps - len(recent)) + recent
    return np.stack([np.asarray(o, dtype=np.float32) for o in recent])


def place_observation(obs: Any, xy: Any) -> np.ndarray:
    """``obs`` with the agent placed at rest at ``xy``: the default observation builder of OP.

    The first ``d = len(xy)`` entries of the last axis become ``xy`` and the rest
    (velocities) zero, on every row of an observation history ``(n_obs, obs_dim)``
    (a teleported agent has the same position over its whole history).
    """
    arr = np.array(obs, dtype=np.float32, copy=True)
    point = np.asarray(xy, dtype=np.float32).reshape(-1)
    if arr.ndim == 0 or arr.shape[-1] < point.size:
        raise ValueError(f"`obs` must have at least {point.size} entries on its last axis, got shape {arr.shape}")
    arr[..., : point.size] = point
    arr[..., point.size :] = 0.0
    return arr
