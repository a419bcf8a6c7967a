"""Scripted expert of InspectionLine-v0: to the entry's centre, then along the line's centre into the station.

Memoryless: with the object off the line it heads for the entry (from the
grasping region a straight segment that reaches the track at the entry), with it
on the line it moves along ``y = 0`` (lifting back onto the centre line first)
into the release station. ``act`` also accepts a batch (obs ``(N, 2)`` and the
vector env's ``infos``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.data.experts.control import positions, sensor_rows, step_toward
from steer_envs.envs.inspection_line import SENSORS, InspectionLineEnv


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
        pos, single = positions(obs)
        on_line = sensor_rows(info, SENSORS)[:, 0]
        return step_toward(self.env, pos, np.where(on_line[:, None], self._release, self._entry), single)


__all__ = ["InspectionLineExpert"]
