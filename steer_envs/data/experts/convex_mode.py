"""Scripted expert of ConvexMode-v0: a straight line to the attractor.

The mode is convex and the attractor lies inside it, so the segment from any
in-mode state to the attractor stays in the mode. The speed profile is that of
a saturated linear dynamical system, ``u = k (x* - x)`` with ``|u|`` capped:
fast far away, slowing to zero at the attractor, which is the kind of
demonstration an LPV-DS can fit (thesis ch. 3 demos: ~200 samples each).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.core.validation import real_scalar
from steer_envs.envs.convex_mode import ConvexModeEnv


class ConvexModeExpert:
    """Closed-loop ``u = gain * (attractor - x)``, speed capped at ``speed``.

    Args:
        env: the unwrapped :class:`ConvexModeEnv` (ground truth is read from it).
        gain: convergence rate of the linear flow (1/s).
        speed: speed cap (also capped by the env's ``max_speed``).
    """

    def __init__(self, env: ConvexModeEnv, gain: float = 3.0, speed: float = 10.0) -> None:
        if not isinstance(env, ConvexModeEnv):
            raise TypeError(f"env must be an unwrapped ConvexModeEnv, got {type(env).__name__}")
        gain = real_scalar(gain, "gain", low=0.0, low_inclusive=False, owner="ConvexModeExpert")
        speed = real_scalar(speed, "speed", low=0.0, low_inclusive=False, owner="ConvexModeExpert")
        self.env = env
        self.gain = float(gain)
        self.speed = float(min(speed, env.max_speed))

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Memoryless controller: nothing to reset."""

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Velocity toward the attractor (re-computed from the true state every step)."""
        x = self.env.state
        u = self.gain * (self.env.model.attractor - x)
        norm = float(np.linalg.norm(u))
        if norm > self.speed:
            u *= self.speed / norm
        return u.astype(np.float32)
