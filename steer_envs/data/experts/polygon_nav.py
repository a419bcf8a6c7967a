"""Scripted expert of PolygonNav: free-space shortest path into polygon 1, then along the chain.

From free space the expert follows a shortest path of a visibility graph
(networkx) around the polygons, inflated by a clearance, to an *approach
point* just outside an exposed edge of polygon 1, and crosses that edge
perpendicularly. Inside polygon ``j`` it walks straight (the polygon is convex)
to a point just before the midpoint of the edge shared with polygon ``j+1``
and crosses it perpendicularly, until it reaches the last polygon. Every
transition it makes is allowed. It re-plans from the true state whenever the
state is not where its last action should have put it (``perturb``).

By default it stops on entering the last polygon (where the env ends the
episode). With ``final_target="centroid"`` it then walks on, straight (the
polygon is convex), to the last polygon's centroid and stays there: demos that
go on past the goal (see ``rollout_expert(steps_after_success=...)``) then
show the goal polygon's interior, not only a point behind its entry edge.
"""

from __future__ import annotations

from typing import Any, Literal

import networkx as nx
import numpy as np
import shapely
from shapely.geometry import LineString, Point
from shapely.ops import nearest_points
from shapely.prepared import prep

from steer_envs.core.validation import real_scalar
from steer_envs.envs.convex_mode import in_halfspaces
from steer_envs.envs.polygon_nav import PolygonNavEnv

_GOAL = "goal"
#: re-plan when the state is farther than this from where the last action led.
_REPLAN_TOL = 1e-6
#: a waypoint closer than this counts as reached.
_REACHED_TOL = 1e-7
#: where the expert goes once it is in the last polygon (see the module docstring).
FINAL_TARGETS: tuple[str, ...] = ("entry", "centroid")


class PolygonNavExpert:
    """Planner-based expert for :class:`PolygonNavEnv`.

    Args:
        env: the unwrapped :class:`PolygonNavEnv` (ground-truth geometry is read from it).
        clearance: distance kept from the polygons while moving in free space.
        crossing_depth: how far before/after a polygon edge a crossing starts/ends.
        final_target: ``"entry"`` (stop just inside the last polygon) or ``"centroid"``
            (then walk on to its centroid).
    """

    def __init__(
        self,
        env: PolygonNavEnv,
        clearance: float = 0.15,
        crossing_depth: float = 0.15,
        final_target: Literal["entry", "centroid"] = "entry",
    ) -> None:
        if not isinstance(env, PolygonNavEnv):
            raise TypeError(f"env must be an unwrapped PolygonNavEnv, got {type(env).__name__}")
        clearance = real_scalar(
            clearance, "clearance", low=0.0, high=env.model.min_gap / 2, low_inclusive=False, high_inclusive=False
        )
        crossing_depth = real_scalar(crossing_depth, "crossing_depth", low=0.0, high=1.0, low_inclusive=False)
        if final_target not in FINAL_TARGETS:
            raise ValueError(f"final_target must be one of {FINAL_TARGETS}, got {final_target!r}")
        self.env = env
        self.model = env.model
        self.clearance = float(clearance)
        self.crossing_depth = float(crossing_depth)
        self.final_target = final_target
        #: the point the expert walks to inside the last polygon (none: it stops on entry)
        self._goal_tail: list[np.ndarray] = (
            [np.asarray(self.model.polygons[-1].centroid.coords[0], dtype=np.float64)]
            if final_target == "centroid"
            else []
        )
        self._chain = self._chain_crossings()
        self._build_roadmap()
        self._plan: list[np.ndarray] = []
        self._expected: np.ndarray | None = None

    # ---------------------------------------------------------------- setup
    def _inside_strict(self, index: int, point: np.ndarray, margin: float = 1e-3) -> bool:
        """Whether ``point`` is at least ``margin`` inside polygon ``index`` (0-based)."""
        return bool(in_halfspaces(self.model.A[index], self.model.b[index], point[None, :], tol=-margin)[0])

    def _crossing(self, index: int, q: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Points ``q - d n`` (inside polygon ``index``) and ``q + d n`` (beyond the edge)."""
        depth = self.crossing_depth
        for _ in range(12):
            before, after = q - depth * normal, q + depth * normal
            if self._inside_strict(index, before):
                return before, after
            depth /= 2
        return None

    def _chain_crossings(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """For each shared edge j|j+1: a point just inside polygon j and one just inside j+1."""
        out = []
        for j, (p, q) in enumerate(self.model.shared_edges):
            mid = 0.5 * (p + q)
            normal = self.model.A[j, 2]  # outward normal of polygon j's edge (v2, v3)
            depth = self.crossing_depth
            for _ in range(12):
                before, after = mid - depth * normal, mid + depth * normal
                if self._inside_strict(j, before) and self._inside_strict(j + 1, after):
                    break
                depth /= 2
            else:  # pragma: no cover - polygons have area >= 1 and bounded angles
                raise RuntimeError(f"PolygonNavExpert: no crossing of shared edge {j + 1}|{j + 2}")
            out.append((before, after))
        return out

    def _build_roadmap(self) -> None:
        """Visibility graph of free space (inflated polygon corners + approach points of polygon 1)."""
        model, c = self.model, self.clearance
        self._obstacle = model.union.buffer(c, quad_segs=4)
        self._obstacle_prep = prep(self._obstacle)
        outer = model.union.buffer(c + 0.05, quad_segs=2)
        rings = [outer.exterior, *outer.interiors] if outer.geom_type == "Polygon" else []
        if not rings:  # pragma: no cover - the union of the chain is one polygon
            rings = [g.exterior for g in outer.geoms]
        corners = np.vstack([np.asarray(r.coords)[:-1] for r in rings])

        # approach points: outside exposed edges of polygon 1, crossing straight into it
        others = shapely.unary_union(model.polygons[1:]) if model.num_polygons > 1 else None
        entries: list[tuple[np.ndarray, np.ndarray]] = []
        exposed = [0, 1, 3] if model.num_polygons > 1 else [0, 1, 2, 3]
        v = model.vertices[0]
        for e in exposed:
            normal = model.A[0, e]
            for t in (0.5, 0.35, 0.65, 0.2, 0.8):
                q = v[e] + t * (v[(e + 1) % 4] - v[e])
                approach = q + (c + 0.05) * normal
                crossing = self._crossing(0, q, normal)
                if crossing is None:
                    continue
                inside = crossing[0]  # just inside polygon 1, behind the edge point q
                leg = LineString([approach, inside])
                if self._obstacle_prep.contains(Point(approach)) or not self._in_workspace(approach):
                    continue
                if others is not None and leg.distance(others) < c:
                    continue
                entries.append((approach, inside))
        if not entries:  # pragma: no cover
            raise RuntimeError("PolygonNavExpert: polygon 1 has no reachable edge")

        keep = [p for p in corners if self._in_workspace(p) and not self._obstacle_prep.intersects(Point(p))]
        nodes = np.array(keep + [a for a, _ in entries]).reshape(-1, 2)
        n_corner = len(keep)
        graph = nx.Graph()
        graph.add_nodes_from(range(len(nodes)))
        ii, jj = np.triu_indices(len(nodes), k=1)
        segments = shapely.linestrings(np.stack([nodes[ii], nodes[jj]], axis=1))
        blocked = shapely.intersects(segments, self._obstacle)
        for i, j, b in zip(ii, jj, blocked, strict=True):
            if not b:
                graph.add_edge(int(i), int(j), weight=float(np.linalg.norm(nodes[i] - nodes[j])))
        for k, (approach, inside) in enumerate(entries):
            graph.add_edge(n_corner + k, _GOAL, weight=float(np.linalg.norm(inside - approach)))
        self._nodes = nodes
        self._entries = entries
        self._n_corner = n_corner
        self._to_goal, paths = nx.single_source_dijkstra(graph, _GOAL)
        self._paths = {k: p[::-1] for k, p in paths.items()}  # node -> ... -> goal

    def _in_workspace(self, p: np.ndarray) -> bool:
        return bool(np.all(p > self.model.low + 1e-3) and np.all(p < self.model.high - 1e-3))

    # ------------------------------------------------------------- planning
    def _plan_from(self, x: np.ndarray) -> list[np.ndarray]:
        mode = int(self.model.mode_of(x[None, :])[0])
        if mode == self.model.num_modes - 1:
            return list(self._goal_tail)
        if mode >= 1:
            return [p for crossing in self._chain[mode - 1 :] for p in crossing] + self._goal_tail
        # free space: visible roadmap node minimising distance + cost-to-go
        dist = float(self.model.union.distance(Point(x)))
        guard = self.model.union.buffer(min(self.clearance, 0.5 * dist), quad_segs=4) if dist > 0 else None
        candidates = [k for k in self._to_goal if k != _GOAL]
        if not candidates or guard is None:
            return []
        idx = np.array(candidates)
        segs = shapely.linestrings(np.stack([np.broadcast_to(x, (len(idx), 2)), self._nodes[idx]], axis=1))
        visible = ~shapely.intersects(segs, guard)
        if not visible.any():
            return []
        cost = np.linalg.norm(self._nodes[idx] - x, axis=1) + np.array([self._to_goal[k] for k in candidates])
        cost[~visible] = np.inf
        start = int(idx[int(np.argmin(cost))])
        path = self._paths[start]
        waypoints = [self._nodes[k] for k in path if k != _GOAL]
        entry_index = path[-2] - self._n_corner
        waypoints.append(self._entries[entry_index][1])
        return waypoints + [p for crossing in self._chain for p in crossing] + self._goal_tail

    def _escape(self, x: np.ndarray) -> np.ndarray:
        """A step away from the nearest polygon (when no roadmap node is visible)."""
        near = np.asarray(nearest_points(self.model.union, Point(x))[0].coords[0])
        away = x - near
        norm = float(np.linalg.norm(away))
        return away / norm * self.env.max_speed if norm > 0 else np.zeros(2)

    # ----------------------------------------------------------------- API
    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Plan from the episode's start state."""
        self._plan = self._plan_from(self.env.state)
        self._expected = self.env.state

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Step of length <= max_speed * dt toward the next waypoint (re-planning if pushed)."""
        x = self.env.state
        if self._expected is None or np.linalg.norm(x - self._expected) > _REPLAN_TOL:
            self._plan = self._plan_from(x)
        while self._plan and np.linalg.norm(self._plan[0] - x) <= _REACHED_TOL:
            self._plan.pop(0)
        if not self._plan:
            if int(self.model.mode_of(x[None, :])[0]) == 0:
                step = self._escape(x)
                self._expected = None  # re-plan from wherever this leads
                return (step / self.env.dt).astype(np.float32)
            self._expected = x
            return np.zeros(2, dtype=np.float32)
        reach = self.env.max_speed * self.env.dt
        delta = self._plan[0] - x
        norm = float(np.linalg.norm(delta))
        if norm > reach:
            delta = delta * (reach / norm)
        action = (delta / self.env.dt).astype(np.float32)
        self._expected = np.clip(x + self.env.dt * action.astype(np.float64), self.model.low, self.model.high)
        return action
