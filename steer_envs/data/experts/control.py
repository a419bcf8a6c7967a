"""Low-level control shared by the scripted experts of the kinematic envs."""

from __future__ import annotations

import numpy as np


def velocity_toward(pos: np.ndarray, target: np.ndarray, max_speed: float, dt: float) -> np.ndarray:
    """Batched velocity ``(N, 2)`` that moves each row of ``pos`` straight at ``target``.

    Full speed far away; near the target the speed drops so that one step of
    length ``dt`` lands exactly on it (no overshoot, no chatter).
    """
    delta = target - pos
    dist = np.linalg.norm(delta, axis=1, keepdims=True)
    speed = np.minimum(max_speed, dist / dt)
    return np.where(dist > 1e-12, delta / np.maximum(dist, 1e-12) * speed, 0.0)
