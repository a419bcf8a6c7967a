"""Shortest-path distance to a target point around convex polygonal obstacles (a visibility graph).

PolygonNav's dense reward measures the way to polygon 1 from free space with
it: a straight-line distance would pull the agent into a later polygon that
stands in the way, a local optimum that a greedy or value-based learner stalls
in. The shortest path around convex obstacles bends only at their corners, so
the distance from a point is the minimum, over the graph nodes it sees, of the
straight segment plus the node's precomputed distance to the target.

>>> import numpy as np
>>> square = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
>>> field = GeodesicDistance([square], target=np.array([0.0, 3.0]), clearance=0.0)
>>> float(field(np.array([[0.0, 2.0]]))[0]), round(float(field(np.array([[0.0, -3.0]]))[0]), 3)
(1.0, 6.472)
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

from steer_envs.envs.convex_mode import convex_halfspaces

__all__ = ["GeodesicDistance"]

#: obstacles are shrunk by this much for the visibility test, so a path may run along an edge or through a corner
_TOUCH_TOL = 1e-7


class GeodesicDistance:
    """Distance from points to ``target`` along the shortest path that avoids the obstacles' interiors.

    Args:
        obstacles: convex polygons, each a ``(V, 2)`` counter-clockwise vertex array (the same V for all).
        target: ``(2,)`` the point distances are measured to.
        clearance: the path's corners sit this far outside the obstacles' union (its mitred offset), so a
            path hugging a corner does not graze it.

    Calling it on ``(N, 2)`` points returns ``(N,)`` distances; a point that sees
    no node (inside an obstacle) gets its straight-line distance.
    """

    def __init__(self, obstacles: Sequence[np.ndarray], target: np.ndarray, clearance: float = 0.05) -> None:
        self.target = np.asarray(target, dtype=np.float64).reshape(2)
        halfspaces = [convex_halfspaces(np.asarray(v, dtype=np.float64)) for v in obstacles]
        self._A = np.stack([h[0] for h in halfspaces]) if halfspaces else np.zeros((0, 0, 2))
        self._b = np.stack([h[1] for h in halfspaces]) - _TOUCH_TOL if halfspaces else np.zeros((0, 0))
        corners = [self.target[None]]
        union = unary_union([Polygon(v) for v in obstacles])
        if obstacles:
            grown = union.buffer(clearance, join_style="mitre").simplify(0)  # no collinear corners
            parts = getattr(grown, "geoms", [grown])  # a Polygon or a MultiPolygon
            rings = [g.exterior for g in parts] + [hole for g in parts for hole in g.interiors]
            corners += [np.asarray(r.coords, dtype=np.float64)[:-1] for r in rings]
        #: graph nodes: the target first, then the corners of the grown obstacles
        self.nodes = np.concatenate(corners)
        m = len(self.nodes)
        # node to node against the union: a segment along the edge two touching obstacles share runs
        # through the union's interior though through neither obstacle's (the per-polygon test below)
        dist = np.full((m, m), np.inf)
        for i, j in itertools.combinations(range(m), 2):
            line = LineString([self.nodes[i], self.nodes[j]])
            if union.is_empty or not line.relate_pattern(union, "T********"):
                dist[i, j] = dist[j, i] = line.length
        np.fill_diagonal(dist, 0.0)
        for k in range(m):  # Floyd-Warshall: a few dozen nodes
            dist = np.minimum(dist, dist[:, k : k + 1] + dist[k : k + 1, :])
        #: each node's shortest-path distance to the target
        self.node_distance = dist[:, 0]

    def _visible(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Whether each segment ``p[i] -> q[i]`` misses every obstacle's interior (Cyrus-Beck clipping)."""
        if not len(self._A):
            return np.ones(len(p), dtype=bool)
        normals = self._A.reshape(-1, 2).T  # (2, O * V): one matrix product per term
        num = (self._b.reshape(-1) - p @ normals).reshape(len(p), *self._b.shape)  # (N, O, V): b - a.p
        den = ((q - p) @ normals).reshape(num.shape)  # a.d
        with np.errstate(divide="ignore", invalid="ignore"):
            t = num / den
        enter = np.max(np.where(den < 0, t, 0.0), axis=2, initial=0.0)
        leave = np.min(np.where(den > 0, t, 1.0), axis=2, initial=1.0)
        parallel_outside = np.any((den == 0) & (num < 0), axis=2)
        return ~np.any((enter < leave) & ~parallel_outside, axis=1)

    def __call__(self, pos: np.ndarray) -> np.ndarray:
        p = np.asarray(pos, dtype=np.float64).reshape(-1, 2)
        n, m = len(p), len(self.nodes)
        seen = self._visible(np.repeat(p, m, axis=0), np.tile(self.nodes, (n, 1))).reshape(n, m)
        via = np.linalg.norm(p[:, None, :] - self.nodes[None], axis=2) + self.node_distance[None]
        best = np.min(np.where(seen, via, np.inf), axis=1)
        return np.where(np.isfinite(best), best, np.linalg.norm(p - self.target, axis=1))
