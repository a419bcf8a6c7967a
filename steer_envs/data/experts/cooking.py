"""Scripted expert of Cooking-v0: a closed-loop waypoint controller over the true geometry.

The expert is memoryless: the action depends on the spoon position and the
sensors (``hc``, ``hb``, ``ch``, ``br``), so it re-plans after any push or
spill. The next food is the first of ``order`` that is not in the pot yet:

* holding food (in its corridor): rise to the pot's height inside the
  corridor, then move sideways into the pot (delivers it);
* in the pot: leave it downward into the white gap (``route="white"``, the
  thesis's ``d1 => w2 => g``) or sideways straight into the next food's
  corridor (``route="direct"``, ``d => g`` of the thesis's Fig. (c), which
  loads the food on the way out);
* empty spoon elsewhere: drop below the corridors (``y < 1``, all white),
  slide under the next food's corridor, and rise into it (loads the food).

Every leg is a straight segment inside one convex piece of a region, so the
expert never spills. ``act`` also accepts a batch (obs ``(N, 2)`` and the
vector env's ``infos``; build the expert on
``venv.unwrapped.env``).
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np

from steer_envs.data.experts.control import positions, sensor_rows, step_toward
from steer_envs.envs.cooking import DARK, FOODS, SENSORS, WHITE, CookingEnv

#: how far inside a region a waypoint sits (so the transition happens before it is reached).
MARGIN = 0.5
#: the white lane below the corridors that the empty spoon travels along.
LANE_GAP = 0.7
#: horizontal tolerance for "below the corridor's entry".
ALIGN_TOL = 0.3
Order = Literal["cb", "bc"]
Route = Literal["white", "direct"]


class CookingExpert:
    """Closed-loop scripted expert of :class:`CookingEnv` (also batched); see the module docstring.

    Args:
        env: the unwrapped env.
        order: ``"cb"`` chicken first (phi_cb, default) or ``"bc"`` broccoli first (phi_bc).
        route: how to get from the pot to the second food: ``"white"`` (via
            the white gap under the pot, default) or ``"direct"`` (pot ->
            corridor).
    """

    def __init__(self, env: CookingEnv, order: Order = "cb", route: Route = "white") -> None:
        if not isinstance(env, CookingEnv):
            raise TypeError(f"env must be a CookingEnv (env.unwrapped), got {type(env).__name__}")
        if order not in ("cb", "bc"):
            raise ValueError(f"order must be 'cb' (chicken first) or 'bc' (broccoli first), got {order!r}")
        if route not in ("white", "direct"):
            raise ValueError(f"route must be 'white' or 'direct', got {route!r}")
        self.env, self.order, self.route = env, order, route
        model = env.model
        foods = ["chicken", "broccoli"] if order == "cb" else ["broccoli", "chicken"]
        self._foods = [FOODS[f] for f in foods]  # (region, content, pot slot) in order
        self._rects = {name: model.rects[name] for name in model.rects}
        self._names = {FOODS["chicken"][0]: "yellow", FOODS["broccoli"][0]: "green"}  # region label -> rect
        self._col = {ap: i for i, ap in enumerate(SENSORS)}

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Nothing to reset: the expert is memoryless."""

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Velocity command(s): ``(2,)`` for one env, ``(N, 2)`` for a batch."""
        pos, single = positions(obs)
        sensors = sensor_rows(info, SENSORS)
        if len(sensors) != len(pos):
            raise ValueError(f"info['sensors'] must have one row per observation ({len(pos)}), got {len(sensors)}")
        return step_toward(self.env, pos, self._targets(pos, sensors), single)

    # ------------------------------------------------------------ planning
    def _targets(self, pos: np.ndarray, sensors: np.ndarray) -> np.ndarray:
        x, y = pos[:, 0], pos[:, 1]
        col = self._col
        in_pot = np.stack([sensors[:, col["ch"]], sensors[:, col["br"]]], axis=1)
        holding = {FOODS["chicken"][1]: sensors[:, col["hc"]], FOODS["broccoli"][1]: sensors[:, col["hb"]]}
        # the next food to fetch: the first of `order` not in the pot (region label per agent)
        first, second = self._foods
        need_first = ~in_pot[:, first[2] - 1]
        need_region = np.where(need_first, first[0], second[0])
        done = in_pot.all(axis=1)
        region = self.env.model.regions(pos)
        px0, py0, px1, _ = self._rects["dark"]
        target = pos.copy()

        # empty spoon outside the pot: lane below the corridors, then up into the needed one
        empty = ~done & ~holding[1] & ~holding[2] & (region != DARK)
        for label, name in self._names.items():
            cx0, cy0, cx1, _ = self._rects[name]
            centre, lane = (cx0 + cx1) / 2.0, cy0 - LANE_GAP
            mine = empty & (need_region == label)
            aligned = (np.abs(x - centre) <= ALIGN_TOL) & (y < cy0) & (region == WHITE)
            rise, descend = mine & aligned, mine & ~aligned & (y >= cy0 - 0.1)
            slide = mine & ~aligned & ~descend
            target[rise] = np.stack([np.full_like(x, centre), np.full_like(y, cy0 + MARGIN)], axis=1)[rise]
            target[descend] = np.stack([x, np.full_like(y, lane)], axis=1)[descend]
            target[slide] = np.stack([np.full_like(x, centre), np.full_like(y, lane)], axis=1)[slide]

        # holding food: up the corridor to the pot's height, then sideways into the pot
        for content, name in ((FOODS["chicken"][1], "yellow"), (FOODS["broccoli"][1], "green")):
            mine = ~done & holding[content]
            low = mine & (y < py0 + MARGIN)
            target[low] = np.stack([x, np.full_like(y, (py0 + self._rects[name][3]) / 2.0)], axis=1)[low]
            side = mine & ~low
            entry_x = px0 + MARGIN if self._rects[name][0] < px0 else px1 - MARGIN
            target[side] = np.stack([np.full_like(x, entry_x), np.clip(y, py0 + MARGIN, None)], axis=1)[side]

        # in the pot with food still missing: leave down into the white gap, or sideways into the corridor
        leave = ~done & (region == DARK)
        if self.route == "white":
            gap = np.array([(px0 + px1) / 2.0, py0 - MARGIN])
            target[leave] = gap
        else:
            for label, name in self._names.items():
                mine = leave & (need_region == label)
                exit_x = px0 - MARGIN if self._rects[name][0] < px0 else px1 + MARGIN
                target[mine] = np.stack([np.full_like(x, exit_x), np.clip(y, py0 + MARGIN, None)], axis=1)[mine]
        return target


__all__ = ["CookingExpert"]
