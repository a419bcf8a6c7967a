"""Scripted expert of ColorTracing-v0: a wave through the tiles' waypoints into red (the single demonstration).

On tile ``i`` it heads for the tile's waypoint (its centre, alternately
``WAVE`` above and below the row's axis) until it is past it, then for the next
tile's waypoint: the path crosses every shared edge and bends inside every
tile. In the dark region it re-enters the tile it left (or the one the env's
``automaton`` prescribes) through the dark region only
(:func:`~steer_envs.envs.color_tracing.reentry_target`). Memoryless; ``act``
also accepts a batch (obs ``(N, 2)`` and the vector env's ``infos``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from steer_envs.data.experts.control import step_toward
from steer_envs.envs.color_tracing import (
    DARK_MODES,
    EXIT_MODE,
    REENTRY,
    ROW_X0,
    TILE_WIDTH,
    TILES,
    ColorTracingEnv,
    reentry_target,
)

#: the waypoints' offset from the row's axis (alternating sign, red's is on the axis)
WAVE = 0.8
#: a waypoint counts as passed this far before its x
PASS_MARGIN = 0.1


def waypoints() -> np.ndarray:
    """The expert's waypoint on each tile, ``(6, 2)``."""
    xs = ROW_X0 + TILE_WIDTH * (np.arange(len(TILES)) + 0.5)
    ys = np.array([WAVE * (-1) ** i for i in range(len(TILES))])
    ys[-1] = 0.0
    return np.stack([xs, ys], axis=1)


class ColorTracingExpert:
    """Closed-loop scripted expert of :class:`ColorTracingEnv` (also batched)."""

    def __init__(self, env: ColorTracingEnv) -> None:
        if not isinstance(env, ColorTracingEnv):
            raise TypeError(f"env must be a ColorTracingEnv (env.unwrapped), got {type(env).__name__}")
        self.env = env
        self._waypoints = waypoints()
        table: Mapping[str, str] = REENTRY.get(env.model.automaton or "", {})
        # re-enter where the automaton says, else at the tile left (dark4: orange)
        left = {d: next(t for t, m in EXIT_MODE.items() if m == d) for d in DARK_MODES}
        self._reentry = np.array([TILES.index(table.get(d, left[d])) for d in DARK_MODES], dtype=np.int64)

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Nothing to reset: the expert is memoryless."""

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Velocity command(s): ``(2,)`` for one env, ``(N, 2)`` for a batch."""
        raw = np.asarray(obs, dtype=np.float64)
        single = raw.ndim == 1
        pos = raw.reshape(len(raw) if not single else 1, -1)[:, :2]
        mode = np.asarray(info["mode"], dtype=np.int64).reshape(-1)
        n_tiles = len(TILES)  # tile modes come first: a tile mode's index is its tile index
        on_tile = mode < n_tiles
        tile = np.where(on_tile, mode, 0)
        wp = self._waypoints[tile]
        passed = pos[:, 0] >= wp[:, 0] - PASS_MARGIN
        nxt = self._waypoints[np.minimum(tile + 1, n_tiles - 1)]
        target = np.where(passed[:, None], nxt, wp)
        dark = np.clip(mode - n_tiles, 0, len(DARK_MODES) - 1)
        back = reentry_target(pos, self._reentry[dark])
        target = np.where(on_tile[:, None], target, back)
        return step_toward(self.env, pos, target, single)


__all__ = ["ColorTracingExpert", "waypoints"]
