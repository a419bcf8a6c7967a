"""Where PolygonNav demonstrations start: the env's reset, or spread evenly around the workspace edge.

``"uniform"`` (the default) starts every demo where ``env.reset(seed=...)``
puts the agent: uniform in free space. A handful of demos from uniform
starts often come from a few directions only, and a behaviour-cloned policy
started from a direction no demo covers walks into the polygon chain
through a polygon other than the first (an invalid transition). The public
GLiDE demos are paths drawn by hand (the public code's
``data_gen/polygon_{2,3,4}/data.csv``: 7, 7 and 6 paths of 100 points), and
every one starts near the workspace edge (4.7 to 7.1 from the centre in the
max-norm) with the starts spread around the centre (no gap over 90 degrees):
they approach the chain from every side. ``"spread"``
(:func:`spread_start`) gives demos that do: ``n`` starts at evenly spaced
angles about the workspace centre (a random phase from the seed),
:data:`EDGE_INSET` inside the workspace edge, each moved along the edge until
it is :data:`START_CLEARANCE` clear of every polygon.

On layout 0 with 3 modes (10 training seeds x 300 rollouts) BC from 7
spread demos succeeds in 0.937 of the episodes (0.880 with the evaluation
perturbations) against 0.825 (0.728) from 7 uniform ones; thesis Table 4.1:
0.967 (0.908).

>>> import gymnasium as gym
>>> import steer_envs
>>> env = gym.make("steer_envs/PolygonNav-3Mode-v0", layout_seed=0)
>>> start = spread_start(env, 0, 7, phase=0.0)
>>> start.round(2).tolist(), int(env.unwrapped.model.mode_of(start[None])[0])
([6.5, 0.0], 0)
"""

from __future__ import annotations

from typing import Any

import numpy as np
from shapely.geometry import Point

from steer_envs.core.validation import integer, one_of, real_scalar
from steer_envs.envs.polygon_nav import WORKSPACE_HALF_WIDTH, PolygonNavEnv

__all__ = ["DEMO_STARTS", "EDGE_INSET", "START_CLEARANCE", "check_demo_starts", "spread_phase", "spread_start"]

#: how demos start (module docstring); the first is the default.
DEMO_STARTS = ("uniform", "spread")
#: spread starts lie this far (workspace units) inside the workspace edge.
EDGE_INSET = 1.5
#: a spread start is at least this far from every polygon (the expert's free-space clearance is 0.15).
START_CLEARANCE = 0.3
#: a start on a polygon moves along the edge in steps of this angle (rad), alternating sides.
_SLIDE = 0.01


def check_demo_starts(demo_starts: Any, owner: str) -> str:
    """``demo_starts`` if it is one of :data:`DEMO_STARTS`; ``ValueError`` naming ``owner`` and the argument."""
    return one_of(demo_starts, "demo_starts", DEMO_STARTS, owner=owner)


def spread_phase(seed: int) -> float:
    """The ring's random phase (rad) for demo seed ``seed``: one draw of ``default_rng(seed)``."""
    return float(np.random.default_rng(integer(seed, "seed", low=0, owner="spread_phase")).uniform(0, 2 * np.pi))


def _ring_point(angle: float, half: float) -> np.ndarray:
    """The point at ``angle`` on the square of half-width ``half`` about the origin."""
    d = np.array([np.cos(angle), np.sin(angle)])
    return np.asarray(d * half / np.max(np.abs(d)))


def spread_start(env: Any, attempt: int, n: int, *, phase: float) -> np.ndarray:
    """Start ``attempt`` of ``n`` spread starts on ``env``'s layout (a PolygonNav env or a wrapper of one).

    Attempt ``a`` sits at angle ``phase + 2 pi (a + r / 2) / n`` with ``r = a // n``: the first ``n``
    attempts are the ring, a further round (after failed demos) is turned by half a step. The point
    is :data:`EDGE_INSET` inside the edge; on or near a polygon it slides along the edge, alternating
    sides, to the nearest angle :data:`START_CLEARANCE` clear of them all.
    """
    owner = "spread_start"
    base = getattr(env, "unwrapped", env)
    if not isinstance(base, PolygonNavEnv):
        raise TypeError(f"{owner}: `env` must be a PolygonNav env (or wrap one), got {type(env).__name__}")
    attempt = integer(attempt, "attempt", low=0, owner=owner)
    n = integer(n, "n", low=1, owner=owner)
    phase = real_scalar(phase, "phase", owner=owner)
    union = base.model.union
    half = WORKSPACE_HALF_WIDTH - EDGE_INSET
    angle = phase + 2 * np.pi * (attempt + (attempt // n) / 2) / n
    for k in range(int(np.pi / _SLIDE) * 2 + 1):
        shift = (k + 1) // 2 * _SLIDE * (1 if k % 2 else -1)
        point = _ring_point(angle + shift, half)
        if union.distance(Point(point)) >= START_CLEARANCE:
            return point
    raise ValueError(f"{owner}: no point of the ring lies {START_CLEARANCE} clear of the polygons")  # pragma: no cover
