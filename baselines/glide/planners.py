"""Planning over learned modes for GLiDE+Planning: the mode map, a costmap path, RRT and a potential field.

Everything here reads a classifier's labels through :class:`LearnedModeMap`
(the labels on a fine grid, computed once), so a path is "valid" when the
*learned* modes allow it:

* :meth:`LearnedModeMap.shortest_path` -- the cheapest grid path under an
  exposure cost that grows near the learned boundaries of forbidden modes
  (Dijkstra), shortened by string-pulling;
* :func:`rrt` -- a rapidly-exploring random tree with greedy shortcuts (the
  thesis's free-space planner);
* :func:`potential_field` -- attraction to the goal plus repulsion from the
  forbidden modes, the fallback when no path is found.

:class:`PlannerConfig` holds the settings; the policy that uses them is
:class:`~steer_envs.baselines.glide.mode_policies.GlidePlanningPolicy`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse.csgraph import dijkstra

from steer_envs.baselines.glide.modes import ModePredictor
from steer_envs.core.validation import BoundExceeded, integer, real_array, real_scalar

__all__ = ["FREE_SPACE_PLANNERS", "LearnedModeMap", "PlannerConfig", "potential_field", "rrt"]

#: how GLiDE+Planning crosses free space: the exposure-weighted grid path (default) or the thesis's RRT
FREE_SPACE_PLANNERS: tuple[str, ...] = ("costmap", "rrt")
#: the most cells of a :class:`LearnedModeMap` (a finer grid than this cannot be labelled in memory).
MAX_GRID_CELLS = 25_000_000
#: the most RRT iterations (per restart) and restarts (each iteration is bounded work).
MAX_RRT_ITERATIONS = 10_000_000
MAX_RRT_RESTARTS = 1000
#: the most points that check one segment against the map.
MAX_SEGMENT_POINTS = 10_000_000


@dataclass(frozen=True)
class PlannerConfig:
    """GLiDE+Planning settings.

    Args:
        grid_resolution: cell size of the :class:`LearnedModeMap`.
        rrt_iterations, rrt_goal_bias, rrt_step, rrt_tolerance, rrt_restarts: :func:`rrt`
            (``rrt_step`` is larger than the env's step so that the tree crosses the
            workspace within ``rrt_iterations``; paths are still executed in env steps
            of at most ``max_speed``).
        k_att, k_rep, d0: the :func:`potential_field` (attraction gain, repulsion gain and radius).
        check_spacing: spacing of the points that check a segment against the map.
        waypoint_tolerance: a waypoint this close counts as reached.
        clearance: straight paths and RRT nodes keep this distance from the learned
            regions of the modes the agent may not enter (relaxed to the start's and
            the goal's own clearance when those are closer): a learned boundary is only
            as sharp as the classifier, and a path that grazes it can clip a corner
            that the classifier labels as free space.
        free_space_planner: ``"costmap"``: cross free space on
            :meth:`LearnedModeMap.shortest_path` (an exposure cost
            ``1 + exposure_weight (1 - d / exposure_radius)^2`` per unit length at
            distance ``d < exposure_radius`` from a forbidden learned mode); ``"rrt"``:
            the thesis's RRT with the hard ``clearance`` only. The learned boundary is
            least reliable where no data went, and the shortest path hugs it; the
            exposure cost keeps paths away from it where that is cheap.

    >>> PlannerConfig().free_space_planner, PlannerConfig(free_space_planner="rrt").rrt_iterations
    ('costmap', 1000)
    """

    grid_resolution: float = 0.05
    rrt_iterations: int = 1000
    rrt_goal_bias: float = 0.05
    rrt_step: float = 0.5
    rrt_tolerance: float = 0.1
    rrt_restarts: int = 3
    k_att: float = 1.0
    k_rep: float = 10.0
    d0: float = 0.8
    check_spacing: float = 0.02
    waypoint_tolerance: float = 1e-6
    clearance: float = 0.5
    free_space_planner: str = "costmap"
    exposure_weight: float = 10.0
    exposure_radius: float = 2.0

    def __post_init__(self) -> None:
        who = "PlannerConfig"
        if not isinstance(self.free_space_planner, str) or self.free_space_planner not in FREE_SPACE_PLANNERS:
            raise ValueError(
                f"free_space_planner must be one of {FREE_SPACE_PLANNERS}, got {self.free_space_planner!r}"
            )
        for name in ("exposure_weight", "exposure_radius", "k_rep", "clearance"):
            real_scalar(getattr(self, name), name, low=0.0, owner=who)
        for name in ("grid_resolution", "rrt_step", "rrt_tolerance", "k_att", "d0", "check_spacing"):
            real_scalar(getattr(self, name), name, low=0.0, low_inclusive=False, owner=who)
        real_scalar(self.waypoint_tolerance, "waypoint_tolerance", low=0.0, owner=who)
        integer(self.rrt_iterations, "rrt_iterations", low=1, high=MAX_RRT_ITERATIONS, owner=who)
        integer(self.rrt_restarts, "rrt_restarts", low=1, high=MAX_RRT_RESTARTS, owner=who)
        real_scalar(self.rrt_goal_bias, "rrt_goal_bias", low=0.0, high=1.0, owner=who)


class LearnedModeMap:
    """A classifier's mode labels on a grid over ``[low, high]``: O(1) mode look-ups, distance fields, paths.

    Args:
        classifier: anything with ``predict(states (N, 2)) -> modes (N,)``, called once on the grid.
        low, high: the workspace corners ``(2,)``.
        resolution: the grid's cell size; a point's mode is that of its nearest grid point.

    >>> import numpy as np
    >>> class LeftRight:  # mode 1 right of x = 0
    ...     def predict(self, s): return (np.asarray(s)[:, 0] > 0).astype(int)
    >>> grid = LearnedModeMap(LeftRight(), np.array([-1.0, -1.0]), np.array([1.0, 1.0]), 0.1)
    >>> grid.mode(np.array([[-0.5, 0.0], [0.5, 0.0]])).tolist()
    [0, 1]
    >>> path = grid.shortest_path(np.array([-0.8, -0.8]), np.array([-0.8, 0.8]), frozenset({0}), 10.0, 0.5, 0.02)
    >>> np.allclose(path[-1], [-0.8, 0.8]), bool(grid.inside(np.array(path), frozenset({0})).all())
    (True, True)
    """

    def __init__(self, classifier: ModePredictor, low: np.ndarray, high: np.ndarray, resolution: float) -> None:
        resolution = real_scalar(resolution, "resolution", low=0.0, low_inclusive=False, owner="LearnedModeMap")
        if not callable(getattr(classifier, "predict", None)):
            raise TypeError(
                f"LearnedModeMap: classifier must have predict(states) -> modes, got {type(classifier).__name__}"
            )
        self.low = real_array(low, "low", shape=(2,), owner="LearnedModeMap")
        self.high = real_array(high, "high", shape=(2,), owner="LearnedModeMap")
        if not np.all(self.low < self.high):
            raise ValueError(f"LearnedModeMap: need low < high, got {self.low.tolist()}, {self.high.tolist()}")
        self.resolution = float(resolution)
        cells = np.prod([np.ceil((h - lo) / self.resolution) + 1 for lo, h in zip(self.low, self.high, strict=True)])
        if cells > MAX_GRID_CELLS:
            raise ValueError(
                f"LearnedModeMap: resolution={self.resolution!r} over [{self.low.tolist()}, {self.high.tolist()}] "
                f"needs {cells:.3g} cells, more than {MAX_GRID_CELLS}"
            )
        self.shape = tuple(
            int(np.ceil((h - lo) / self.resolution)) + 1 for lo, h in zip(self.low, self.high, strict=True)
        )
        xs = [self.low[i] + self.resolution * np.arange(self.shape[i]) for i in range(2)]
        gx, gy = np.meshgrid(xs[0], xs[1], indexing="ij")
        pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
        self.labels = np.asarray(classifier.predict(pts), dtype=np.int64).reshape(self.shape)
        self._fields: dict[frozenset[int], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._paths: dict[tuple[int, frozenset[int], float, float], tuple[np.ndarray, np.ndarray, int]] = {}
        self._exposures: dict[tuple[frozenset[int], float, float], np.ndarray] = {}

    def index(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Grid indices ``(i, j)`` of the nearest grid point of each point (clipped to the grid)."""
        ij = np.rint((np.asarray(points, dtype=np.float64) - self.low) / self.resolution).astype(np.int64)
        ij = np.clip(ij, 0, np.array(self.shape) - 1)
        return ij[..., 0], ij[..., 1]

    def mode(self, points: np.ndarray) -> np.ndarray:
        """The learned mode of each point ``(N, 2) -> (N,)``."""
        i, j = self.index(points)
        return self.labels[i, j]

    def inside(self, points: np.ndarray, allowed: frozenset[int]) -> np.ndarray:
        """Whether each point's learned mode is in ``allowed`` ``(N,)``."""
        return np.isin(self.mode(points), list(allowed))

    def clearance(self, points: np.ndarray, allowed: frozenset[int]) -> np.ndarray:
        """Distance of each point to the nearest grid cell outside ``allowed`` (0 outside)."""
        dist = self.distance_field(allowed)[0]
        i, j = self.index(points)
        return dist[i, j]

    def segment_ok(
        self, a: np.ndarray, b: np.ndarray, allowed: frozenset[int], spacing: float, min_clearance: float = 0.0
    ) -> bool:
        """Whether the segment ``a -> b`` stays in ``allowed`` at least ``min_clearance`` from its outside."""
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / spacing)) + 1)
        if n > MAX_SEGMENT_POINTS:
            raise ValueError(
                f"LearnedModeMap.segment_ok: spacing={spacing!r} needs {n} points on a segment of length "
                f"{np.linalg.norm(b - a):.3g}, more than {MAX_SEGMENT_POINTS}"
            )
        t = np.linspace(0.0, 1.0, n)[:, None]
        pts = a + t * (b - a)
        if min_clearance <= 0:
            return bool(np.all(self.inside(pts, allowed)))
        return bool(np.all(self.clearance(pts, allowed) >= min_clearance))

    def nearest_in(self, point: np.ndarray, mode: int) -> np.ndarray:
        """``point`` if the map labels it ``mode``, else the nearest grid point labelled ``mode``
        (``point`` itself when no cell has that label)."""
        p = np.asarray(point, dtype=np.float64)
        if self.mode(p[None])[0] == mode:
            return p
        cells = np.argwhere(self.labels == mode)
        if len(cells) == 0:
            return p
        pts = self.low + self.resolution * cells
        return pts[int(np.argmin(np.sum((pts - p) ** 2, axis=1)))]

    def distance_field(self, allowed: frozenset[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance to the nearest cell outside ``allowed`` and its gradient (cached)."""
        if allowed not in self._fields:
            inside = np.isin(self.labels, list(allowed))
            dist = ndimage.distance_transform_edt(inside) * self.resolution
            gi, gj = np.gradient(dist, self.resolution)
            self._fields[allowed] = (dist, gi, gj)
        return self._fields[allowed]

    def exposure(self, allowed: frozenset[int], weight: float, radius: float) -> np.ndarray:
        """Per-cell cost factor ``1 + weight * max(0, 1 - d / radius)^2``, ``d`` the distance to leaving ``allowed``.

        A classifier's boundary is least trustworthy where no data went (cut corners, the far side of a
        polygon): a path that keeps its distance from forbidden modes where it costs little to do so is
        robust to such errors, a path that grazes them (the shortest one) is not. Cached.
        """
        key = (allowed, float(weight), float(radius))
        if key not in self._exposures:
            dist = self.distance_field(allowed)[0]
            if radius <= 0 or weight <= 0:
                self._exposures[key] = np.ones_like(dist)
            else:
                self._exposures[key] = 1.0 + weight * np.clip(1.0 - dist / radius, 0.0, None) ** 2
        return self._exposures[key]

    def cost_to_go(
        self, goal: np.ndarray, allowed: frozenset[int], weight: float, radius: float
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """Exposure-weighted shortest-path distances from every cell of ``allowed`` to ``goal``'s cell.

        Dijkstra (``scipy.sparse.csgraph``) on the 8-connected grid of the cells labelled ``allowed``,
        an edge costing its length times the mean :meth:`exposure` of its two cells. Returns the
        flat ``(distance, predecessor, goal_cell)`` arrays (predecessors point toward the goal);
        cached per (goal cell, allowed, weight, radius).
        """
        gi, gj = self.index(np.asarray(goal, dtype=np.float64)[None])
        h, w = self.shape
        source = int(gi[0] * w + gj[0])
        key = (source, allowed, float(weight), float(radius))
        if key not in self._paths:
            cost = self.exposure(allowed, weight, radius).ravel()
            ok = np.isin(self.labels, list(allowed)).ravel()
            idx = np.arange(h * w).reshape(h, w)
            rows, cols, vals = [], [], []
            for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
                a = idx[: h - di, max(0, -dj) : w - max(0, dj)].ravel()
                b = idx[di:, max(0, dj) : w - max(0, -dj)].ravel()
                keep = ok[a] & ok[b]
                a, b = a[keep], b[keep]
                rows.append(a)
                cols.append(b)
                vals.append(np.hypot(di, dj) * self.resolution * 0.5 * (cost[a] + cost[b]))
            graph = sparse.csr_matrix(
                (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(h * w, h * w)
            )
            dist, pred = dijkstra(graph, directed=False, indices=source, return_predecessors=True)
            self._paths[key] = (dist, pred, source)
        return self._paths[key]

    def shortest_path(
        self, start: np.ndarray, goal: np.ndarray, allowed: frozenset[int], weight: float, radius: float, spacing: float
    ) -> list[np.ndarray] | None:
        """The exposure-weighted shortest path ``start -> goal`` inside ``allowed`` (None: not connected).

        The grid path is shortened by string-pulling: from each point it jumps to the farthest later
        point whose straight segment stays inside ``allowed`` and is nowhere more exposed than the
        grid path between them, so the result is short without cutting closer to a forbidden mode.
        Returns the points after ``start``, ending with ``goal``.
        """
        dist, pred, source = self.cost_to_go(goal, allowed, weight, radius)
        w = self.shape[1]
        si, sj = self.index(np.asarray(start, dtype=np.float64)[None])
        cell = int(si[0] * w + sj[0])
        if not np.isfinite(dist[cell]):
            return None
        cells: list[int] = []
        for _ in range(len(pred)):  # a predecessor chain visits every cell at most once
            if cell == source:
                break
            cell = int(pred[cell])
            if cell < 0:
                raise BoundExceeded(
                    f"LearnedModeMap.shortest_path: the predecessor chain broke off at cell {cells[-1:]}"
                )
            cells.append(cell)
        else:
            if cell != source:
                raise BoundExceeded(
                    f"LearnedModeMap.shortest_path: no way back to the goal cell within {len(pred)} predecessor steps"
                )
        # every 4th cell is enough to pull the string through (and 16x fewer segment checks)
        cells_ij = np.stack(np.divmod(np.asarray(cells[:-1][::4], dtype=np.int64), w), axis=1)
        ends = np.asarray([start, goal], dtype=np.float64)
        path = np.vstack([ends[:1], self.low + self.resolution * cells_ij, ends[1:]])
        exposure = self.exposure(allowed, weight, radius)

        def exposure_at(points: np.ndarray) -> np.ndarray:
            i, j = self.index(points)
            return exposure[i, j]

        along = exposure_at(path)
        out: list[np.ndarray] = []
        i = 0
        while i < len(path) - 1:
            j = len(path) - 1
            while j > i + 1:
                n = max(2, int(np.ceil(np.linalg.norm(path[j] - path[i]) / spacing)) + 1)
                points = path[i] + np.linspace(0.0, 1.0, n)[:, None] * (path[j] - path[i])
                if self.inside(points, allowed).all() and exposure_at(points).max() <= along[i : j + 1].max() + 1e-9:
                    break
                j -= 1
            out.append(path[j])
            i = j
        return out


def rrt(
    start: np.ndarray,
    goal: np.ndarray,
    valid_point: Callable[[np.ndarray], bool],
    valid_segment: Callable[[np.ndarray, np.ndarray], bool],
    low: np.ndarray,
    high: np.ndarray,
    rng: np.random.Generator,
    *,
    iterations: int = 1000,
    goal_bias: float = 0.05,
    step: float = 0.5,
    tolerance: float = 0.1,
) -> list[np.ndarray] | None:
    """Rapidly-exploring random tree from ``start`` to within ``tolerance`` of ``goal`` (None if not found).

    ``valid_point(p)`` and ``valid_segment(a, b)`` say where the tree may grow;
    samples are uniform in ``[low, high]`` (the goal itself with probability
    ``goal_bias``) and each new node lies at most ``step`` from its parent.
    Returns the path ``[start, ..., goal]`` after greedy shortcutting.

    >>> import numpy as np
    >>> def free(p): return not (abs(p[0]) < 1 and p[1] > -3)  # a wall open below y = -3
    >>> def seg(a, b): return all(free(a + t * (b - a)) for t in np.linspace(0, 1, 60))
    >>> path = rrt(np.array([-3.0, 2.0]), np.array([3.0, 2.0]), free, seg, np.full(2, -5.0), np.full(2, 5.0),
    ...            np.random.default_rng(0), iterations=3000)
    >>> path[-1].tolist(), min(p[1] for p in path) < -3
    ([3.0, 2.0], True)
    """
    start = real_array(start, "start", ndim=1, owner="rrt")
    goal = real_array(goal, "goal", shape=start.shape, owner="rrt")
    iterations = integer(iterations, "iterations", low=1, high=MAX_RRT_ITERATIONS, owner="rrt")
    goal_bias = real_scalar(goal_bias, "goal_bias", low=0.0, high=1.0, owner="rrt")
    step = real_scalar(step, "step", low=0.0, low_inclusive=False, owner="rrt")
    tolerance = real_scalar(tolerance, "tolerance", low=0.0, owner="rrt")
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rrt: rng must be a numpy Generator, got {type(rng).__name__}")
    origin = np.asarray(start, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    if valid_segment(origin, goal):
        return [origin, goal]
    path = _tree_path(
        origin, goal, valid_point, valid_segment, (low, high), rng, iterations, goal_bias, step, tolerance
    )
    return None if path is None else _shortcut(path, valid_segment)


def _tree_path(
    start: np.ndarray,
    goal: np.ndarray,
    valid_point: Callable[[np.ndarray], bool],
    valid_segment: Callable[[np.ndarray, np.ndarray], bool],
    bounds: tuple[np.ndarray, np.ndarray],
    rng: np.random.Generator,
    iterations: int,
    goal_bias: float,
    step: float,
    tolerance: float,
) -> list[np.ndarray] | None:
    """Grow :func:`rrt`'s tree from ``start`` until a node reaches ``goal``: the path ``[start, ..., goal]`` or None."""
    nodes = [start]
    parents = [-1]
    pts = np.empty((iterations + 1, len(start)))
    pts[0] = nodes[0]
    found = -1
    for _ in range(iterations):
        target = goal if rng.random() < goal_bias else rng.uniform(*bounds)
        near = int(np.argmin(np.sum((pts[: len(nodes)] - target) ** 2, axis=1)))
        delta = target - nodes[near]
        dist = float(np.linalg.norm(delta))
        if dist < 1e-9:
            continue
        new = nodes[near] + delta * min(1.0, step / dist)
        if not (valid_point(new) and valid_segment(nodes[near], new)):
            continue
        pts[len(nodes)] = new
        nodes.append(new)
        parents.append(near)
        if np.linalg.norm(new - goal) <= tolerance or valid_segment(new, goal):
            found = len(nodes) - 1
            break
    if found < 0:
        return None
    path = [goal]
    k = found
    while k >= 0:
        path.append(nodes[k])
        k = parents[k]
    path.reverse()
    return path


def _shortcut(path: list[np.ndarray], valid_segment: Callable[[np.ndarray, np.ndarray], bool]) -> list[np.ndarray]:
    """Greedy shortcut: from each point jump to the farthest one directly reachable."""
    short = [path[0]]
    i = 0
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1 and not valid_segment(path[i], path[j]):
            j -= 1
        short.append(path[j])
        i = j
    return short


def potential_field(
    mode_map: LearnedModeMap,
    x: np.ndarray,
    goal: np.ndarray,
    allowed: frozenset[int],
    *,
    k_att: float,
    k_rep: float,
    d0: float,
) -> np.ndarray:
    """The force at ``x`` ``(2,)``: ``k_att (goal - x)`` plus a repulsion from the modes outside ``allowed``.

    Within ``d0`` of leaving ``allowed`` (distance ``d`` on ``mode_map``), the
    classic repulsion ``k_rep (1/d - 1/d0) / d^2`` acts along the gradient of
    ``d`` (away from the boundary).

    >>> import numpy as np
    >>> class LeftRight:
    ...     def predict(self, s): return (np.asarray(s)[:, 0] > 0).astype(int)
    >>> grid = LearnedModeMap(LeftRight(), np.array([-1.0, -1.0]), np.array([1.0, 1.0]), 0.1)
    >>> x, goal = np.array([-0.1, 0.0]), np.array([-0.1, 0.5])
    >>> f = potential_field(grid, x, goal, frozenset({0}), k_att=1.0, k_rep=1.0, d0=0.5)
    >>> bool(f[0] < 0), bool(f[1] > 0)  # pushed away from mode 1, pulled toward the goal
    (True, True)
    """
    dist, gi, gj = mode_map.distance_field(allowed)
    i, j = mode_map.index(x[None, :])
    d = float(dist[i[0], j[0]])
    grad = np.array([gi[i[0], j[0]], gj[i[0], j[0]]])
    force = k_att * (goal - x)
    if 0 < d < d0:
        force += k_rep * (1.0 / d - 1.0 / d0) / d**2 * grad
    return np.asarray(force, dtype=np.float64)
