"""Scripted expert of InspectionLine-v0: to the entry's centre, then along the line's centre into the station.

Memoryless: with the object off the line it heads for the entry (from the
grasping region a straight segment that reaches the track at the entry), with it
on the line it moves along ``y = 0`` (lifting back onto the centre line first)
into the release station. ``act`` also accepts a batch (obs ``(N, 2)`` and the
vector env's ``infos``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from steer_envs.data.experts.control import velocity_toward
from steer_envs.envs.inspection_line import SENSORS, InspectionLineEnv
from steer_envs.envs.kinematic import sensor_columns


class InspectionLineExpert:
    """Closed-loop scripted expert of :class:`InspectionLineEnv` (also batched)."""

    def __init__(self, env: InspectionLineEnv) -> None:
        if not isinstance(env, InspectionLineEnv):
            raise TypeError(f"env must be an InspectionLineEnv (env.unwrapped), got {type(env).__name__}")
        self.env = env
        x0, y0, x1, y1 = env.model.rects["entry"]
        self._entry = np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0])
        rx0, ry0, rx1, ry1 = env.model.rects["release"]
        self._release = np.array([(rx0 + rx1) / 2.0, (ry0 + ry1) / 2.0])

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Nothing to reset: the expert is memoryless."""

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Velocity command(s): ``(2,)`` for one env, ``(N, 2)`` for a batch."""
        pos = np.asarray(obs, dtype=np.float64)
        single = pos.ndim == 1
        pos = pos.reshape(-1, 2)
        sensors = info["sensors"]
        if isinstance(sensors, Mapping):  # one env's reading or a vector env's dict of (N,) arrays
            sensors = sensor_columns(sensors, SENSORS)
        on_line = np.asarray(sensors, dtype=bool).reshape(-1, len(SENSORS))[:, 0]
        target = np.where(on_line[:, None], self._release, self._entry)
        action = velocity_toward(pos, target, self.env.max_speed, self.env.dt).astype(np.float32)
        return action[0] if single else action


__all__ = ["InspectionLineExpert"]
