"""Scripted expert of SoupScoop-v0: a closed-loop waypoint controller over the true geometry.

The expert is memoryless: its action is a function of the spoon position and
the current mode (``info["mode"]``), so after any push it re-plans from where
it is, and a spill simply sends it back to scoop again. Per mode:

* ``a`` (reach): head for a point 1 unit deep in the yellow soup strip, away
  from the pink column (the mode switches to ``b`` on contact).
* ``b`` (scoop): first sink 0.5 below the soup surface (so the path never
  grazes white), then move sideways into the pink column through the soup:
  the yellow -> pink move that loads soup.
* ``c`` (transport): centre horizontally in the pink column (so the path
  never leaves pink/green), then go up into green.
* ``d`` (done): stay.

The speed is ``max_speed`` except in the last step before a waypoint. ``act``
also accepts a batch (obs ``(N, 2)`` and the vector env's ``infos``; build the expert on
``venv.unwrapped.env``), which
makes 100-episode evaluations a few numpy calls per step.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.data.experts.control import positions, step_toward
from steer_envs.envs.soup_scoop import MODE_A, MODE_B, MODE_C, SoupScoopEnv

#: depth below the soup surface (``y = -4``) of the reach target.
REACH_DEPTH = 1.0
#: the scoop path runs at least this far below the soup surface.
SCOOP_DEPTH = 0.5
#: how far inside a region a waypoint sits (so the mode switches before it is reached).
MARGIN = 0.5


class SoupScoopExpert:
    """Closed-loop scripted expert of :class:`SoupScoopEnv` (also batched); see the module docstring."""

    def __init__(self, env: SoupScoopEnv) -> None:
        if not isinstance(env, SoupScoopEnv):
            raise TypeError(f"env must be a SoupScoopEnv (env.unwrapped), got {type(env).__name__}")
        self.env = env
        model = env.model
        yx0, _, yx1, ysurf = model.rects["yellow"]
        px0, _, px1, _ = model.rects["pink"]
        _, gy0, _, gy1 = model.rects["green"]
        self._surface = ysurf
        self._pink_x = (px0, px1)
        self._yellow_x = (yx0, yx1)
        self._reach_y = ysurf - REACH_DEPTH
        self._scoop_y = ysurf - SCOOP_DEPTH
        self._transport_target = np.array([(px0 + px1) / 2.0, (gy0 + gy1) / 2.0])

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Nothing to reset: the expert is memoryless."""

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Velocity command(s): ``(2,)`` for one env, ``(N, 2)`` for a batch."""
        pos, single = positions(obs)
        mode = np.asarray(info["mode"], dtype=np.int64).reshape(-1)
        if len(mode) != len(pos):
            raise ValueError(f"info['mode'] must have one entry per observation ({len(pos)}), got {len(mode)}")
        return step_toward(self.env, pos, self._targets(pos, mode), single)

    # ------------------------------------------------------------ planning
    def _targets(self, pos: np.ndarray, mode: np.ndarray) -> np.ndarray:
        x, y = pos[:, 0], pos[:, 1]
        px0, px1 = self._pink_x
        yx0, yx1 = self._yellow_x
        # the side of the pink column to enter the soup from (and to scoop from)
        left = (x - px0) <= (px1 - x)
        entry_x = np.where(left, np.clip(x, yx0 + MARGIN, px0 - MARGIN), np.clip(x, px1 + MARGIN, yx1 - MARGIN))
        target = pos.copy()  # mode d: stay
        # a: into the soup strip, beside the pink column
        reach = mode == MODE_A
        target[reach] = np.stack([entry_x, np.full_like(x, self._reach_y)], axis=1)[reach]
        # b: sink below the surface, then through the soup into the pink column
        scoop = mode == MODE_B
        sink = scoop & (y > self._scoop_y)
        target[sink] = np.stack([x, np.full_like(x, self._reach_y)], axis=1)[sink]
        cross = scoop & ~sink
        scoop_x = np.where(x < px0, px0 + MARGIN, px1 - MARGIN)
        scoop_y = np.minimum(y, self._scoop_y - MARGIN)
        target[cross] = np.stack([scoop_x, scoop_y], axis=1)[cross]
        # c: centre in the pink column, then up into green
        carry = mode == MODE_C
        centre = (px0 + px1) / 2.0
        off_centre = carry & (np.abs(x - centre) > (px1 - px0) / 2.0 - MARGIN)
        target[off_centre] = np.stack([np.full_like(x, centre), y], axis=1)[off_centre]
        up = carry & ~off_centre
        target[up] = self._transport_target
        return target


__all__ = ["SoupScoopExpert"]
