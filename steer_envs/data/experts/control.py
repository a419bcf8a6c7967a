"""Low-level control shared by the scripted experts of the kinematic envs."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from steer_envs.envs.kinematic import sensor_columns


def velocity_toward(pos: np.ndarray, target: np.ndarray, max_speed: float, dt: float) -> np.ndarray:
    """Batched velocity ``(N, 2)`` that moves each row of ``pos`` straight at ``target``.

    Full speed far away; near the target the speed drops so that one step of
    length ``dt`` lands exactly on it (no overshoot, no chatter).
    """
    delta = target - pos
    dist = np.linalg.norm(delta, axis=1, keepdims=True)
    speed = np.minimum(max_speed, dist / dt)
    return np.where(dist > 1e-12, delta / np.maximum(dist, 1e-12) * speed, 0.0)


def positions(obs: Any) -> tuple[np.ndarray, bool]:
    """``obs`` as ``(N, 2)`` float64 positions, and whether it was a single observation ``(2,)``."""
    pos = np.asarray(obs, dtype=np.float64)
    return pos.reshape(-1, 2), pos.ndim == 1


def sensor_rows(info: Mapping[str, Any], aps: Sequence[str]) -> np.ndarray:
    """``info["sensors"]`` as ``(N, len(aps))`` bool rows: one env's reading, a vector env's dict of ``(N,)``
    arrays or rows already."""
    sensors = info["sensors"]
    if isinstance(sensors, Mapping):  # one env's reading or a vector env's dict of (N,) arrays
        sensors = sensor_columns(sensors, aps)
    return np.asarray(sensors, dtype=bool).reshape(-1, len(aps))


def step_toward(env: Any, pos: np.ndarray, target: np.ndarray, single: bool) -> np.ndarray:
    """The float32 :func:`velocity_toward` ``target`` at ``env``'s speed limit (``(2,)`` if ``single``)."""
    action = velocity_toward(pos, target, env.max_speed, env.dt).astype(np.float32)
    return action[0] if single else action
