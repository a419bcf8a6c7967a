"""A simulated sketching user for Maze2D steering (thesis §2.4.1: "each paired with a user sketch").

ITPS's maze study pairs random agent positions with hand-drawn sketches, some
of which cross walls. :class:`SketchUser` draws such sketches reproducibly:

* ``"follow"`` sketches trace a shortest cell path (4-connected, ``networkx``)
  from the agent to a reachable free cell whose path length lies in
  ``[min_length, max_length]`` cells: the cell centres are jittered by a
  "hand" offset, corners are rounded (one Chaikin pass) and the polyline is
  resampled evenly in arc length (``shapely``), like a mouse drawn at constant
  speed. They stay in free cells.
* ``"through"`` sketches go straight from the agent to a free cell at a
  Euclidean distance in ``[min_length, max_length]`` and cross at least one
  wall cell: the user ignores the maze (constraint-violating input).

A share ``through_wall`` of the sketches is of the second kind. Lengths are in
cells; the defaults match the reach of one 63-waypoint ITPS plan on the
random-walk data. Everything is a pure function of the seed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import networkx as nx
import numpy as np
from shapely.geometry import LineString

from steer_envs.core.interaction import Sketch
from steer_envs.envs.maze2d import MazeGrid, maze_map

__all__ = ["SketchUser", "UserSketch"]

SketchKind = Literal["follow", "through"]


@dataclass(frozen=True)
class UserSketch:
    """One drawn sketch and how it was made.

    Attributes:
        sketch: the path, starting at the agent.
        goal_cell: the free cell the user aimed at.
        kind: ``"follow"`` (along free cells) or ``"through"`` (straight across walls).
        collides: whether a sketch point lies in a wall cell (the ITPS collision rule).
    """

    sketch: Sketch
    goal_cell: tuple[int, int]
    kind: SketchKind
    collides: bool


def _as_grid(maze: Any) -> MazeGrid:
    if isinstance(maze, MazeGrid):
        return maze
    if isinstance(maze, str):
        return MazeGrid(maze_map(maze))
    grid = getattr(getattr(maze, "unwrapped", maze), "grid", None)
    if isinstance(grid, MazeGrid):
        return grid
    raise TypeError(f"`maze` must be a MazeGrid, a maze name or a Maze2DEnv, got {type(maze).__name__}")


class SketchUser:
    """Draws random sketches from the agent's position (seeded; see the module docstring).

    Args:
        maze: a :class:`~steer_envs.envs.maze2d.MazeGrid`, a maze name or a Maze2D env.
        through_wall: probability that a sketch ignores the walls.
        min_length / max_length: sketch length range in cells (path length for
            ``"follow"``, straight distance for ``"through"``).
        points: number of points of every sketch.
        hand_jitter: uniform offset (cells) of each path corner, a shaky hand.
        seed: seed of the user's randomness (or pass ``rng`` to :meth:`draw`).

    >>> user = SketchUser("umaze", seed=0, points=8, min_length=2.0, max_length=4.0)
    >>> drawn = user.draw([1.0, 1.0], kind="through")
    >>> drawn.kind, drawn.collides, drawn.sketch.points.shape
    ('through', True, (8, 2))
    """

    def __init__(
        self,
        maze: Any = "large",
        *,
        through_wall: float = 0.3,
        min_length: float = 4.0,
        max_length: float = 9.0,
        points: int = 64,
        hand_jitter: float = 0.15,
        seed: int | None = None,
    ) -> None:
        self.grid = _as_grid(maze)
        if not (isinstance(through_wall, (int, float)) and 0.0 <= through_wall <= 1.0):
            raise ValueError(f"`through_wall` must be a probability in [0, 1], got {through_wall!r}")
        if not (np.isfinite(min_length) and np.isfinite(max_length) and 0 < min_length <= max_length):
            raise ValueError(f"need 0 < min_length <= max_length (finite), got {min_length!r}, {max_length!r}")
        if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 2:
            raise ValueError(f"`points` must be an integer >= 2, got {points!r}")
        if not (np.isfinite(hand_jitter) and 0.0 <= hand_jitter < 0.5):
            raise ValueError(f"`hand_jitter` must be in [0, 0.5) cells, got {hand_jitter!r}")
        self.through_wall = float(through_wall)
        self.min_length, self.max_length = float(min_length), float(max_length)
        self.points = int(points)
        self.hand_jitter = float(hand_jitter)
        self.rng = np.random.default_rng(seed)
        free = [tuple(int(v) for v in c) for c in self.grid.free_cells]
        graph = nx.grid_2d_graph(*self.grid.shape)
        graph.remove_nodes_from([n for n in list(graph.nodes) if n not in set(free)])
        self.graph: nx.Graph = graph

    # ------------------------------------------------------------------ API
    def draw(self, start: Any, *, kind: SketchKind | None = None, rng: np.random.Generator | None = None) -> UserSketch:
        """A sketch from ``start`` (the agent's xy). ``kind`` forces ``"follow"`` or ``"through"``.

        A ``"through"`` sketch falls back to ``"follow"`` when no free cell in
        range lies behind a wall (e.g. in an open maze); ``ValueError`` when the
        start's cell reaches no cell in range at all.
        """
        rng = self.rng if rng is None else rng
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"`rng` must be a numpy.random.Generator or None, got {type(rng).__name__}")
        xy = np.asarray(start, dtype=np.float64)
        if xy.shape != (2,) or not np.all(np.isfinite(xy)):
            raise ValueError(f"`start` must be a finite xy pair, got {start!r}")
        if kind not in (None, "follow", "through"):
            raise ValueError(f"`kind` must be 'follow', 'through' or None, got {kind!r}")
        if kind is None:
            kind = "through" if rng.random() < self.through_wall else "follow"
        row, col = self.grid.xy_to_cell(xy)
        cell = (int(row), int(col))
        if cell not in self.graph:
            raise ValueError(f"`start` {xy.tolist()} lies in a wall cell {cell}")
        if kind == "through":
            drawn = self._through(xy, cell, rng)
            if drawn is not None:
                return drawn
        return self._follow(xy, cell, rng)

    def draws(self, starts: Any) -> list[UserSketch]:
        """One sketch per start (``(N, 2)``), drawn in order from the user's generator."""
        return [self.draw(s) for s in np.asarray(starts, dtype=np.float64).reshape(-1, 2)]

    # ------------------------------------------------------------ internals
    def _finish(self, corners: np.ndarray, goal: tuple[int, int], kind: SketchKind) -> UserSketch:
        line = LineString(corners)
        dist = np.linspace(0.0, line.length, self.points)
        pts = np.array([line.interpolate(float(s)).coords[0] for s in dist])
        collides = bool(self.grid.is_wall(pts).any())
        return UserSketch(Sketch(pts), goal, kind, collides)

    def _follow(self, xy: np.ndarray, cell: tuple[int, int], rng: np.random.Generator) -> UserSketch:
        depth = nx.single_source_shortest_path_length(self.graph, cell)
        lo, hi = int(np.ceil(self.min_length)), int(np.floor(self.max_length))
        goals = sorted(c for c, d in depth.items() if lo <= d <= hi)
        if not goals:  # a small maze: aim at the farthest cells instead
            far = max(depth.values())
            if far == 0:
                raise ValueError(f"cell {cell} reaches no other free cell")
            goals = sorted(c for c, d in depth.items() if d == far)
        goal = goals[int(rng.integers(len(goals)))]
        path = [goal]
        while path[-1] != cell:  # walk back along a random shortest path
            prev = sorted(p for p in self.graph.neighbors(path[-1]) if depth.get(p) == depth[path[-1]] - 1)
            path.append(prev[int(rng.integers(len(prev)))])
        centres = np.array(path[::-1][1:], dtype=np.float64)
        centres[:-1] += rng.uniform(-self.hand_jitter, self.hand_jitter, size=centres[:-1].shape)
        corners = np.vstack([xy, centres])
        if len(corners) > 2:  # Chaikin corner cutting, endpoints kept
            q = 0.75 * corners[:-1] + 0.25 * corners[1:]
            r = 0.25 * corners[:-1] + 0.75 * corners[1:]
            corners = np.vstack([corners[:1], np.stack([q, r], axis=1).reshape(-1, 2), corners[-1:]])
        return self._finish(corners, goal, "follow")

    def _through(self, xy: np.ndarray, cell: tuple[int, int], rng: np.random.Generator) -> UserSketch | None:
        free = self.grid.free_cells.astype(np.float64)
        dist = np.linalg.norm(free - xy, axis=1)
        ts = np.linspace(0.0, 1.0, 50)[None, :, None]
        candidates = []
        for k in np.flatnonzero((dist >= self.min_length) & (dist <= self.max_length)):
            segment = xy + ts[0] * (free[k] - xy)
            if self.grid.is_wall(segment).any():
                candidates.append(int(k))
        if not candidates:
            return None
        k = candidates[int(rng.integers(len(candidates)))]
        goal = (int(self.grid.free_cells[k][0]), int(self.grid.free_cells[k][1]))
        end = free[k] + rng.uniform(-self.hand_jitter, self.hand_jitter, size=2)
        return self._finish(np.vstack([xy, end]), goal, "through")
