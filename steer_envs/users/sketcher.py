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
from steer_envs.core.validation import describe, integer, one_of, real_array, real_scalar
from steer_envs.envs.maze_grid import MazeGrid, maze_map

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


#: most points of one sketch (each is a shapely interpolation).
MAX_POINTS = 100_000


def _check_seed(seed: Any, owner: str) -> Any:
    """None, an int >= 0, or a numpy SeedSequence / BitGenerator (what ``default_rng`` reads without guessing)."""
    if seed is None or isinstance(seed, (np.random.SeedSequence, np.random.BitGenerator)):
        return seed
    return integer(seed, "`seed`", low=0, owner=owner)


def _as_grid(maze: Any) -> MazeGrid:
    if isinstance(maze, MazeGrid):
        return maze
    if isinstance(maze, str):
        return MazeGrid(maze_map(maze))
    grid = getattr(getattr(maze, "unwrapped", maze), "grid", None)
    if isinstance(grid, MazeGrid):
        return grid
    raise TypeError(f"`maze` must be a MazeGrid, a maze name or a Maze2DEnv, got {describe(maze)}")


class SketchUser:
    """Draws random sketches from the agent's position (seeded; see the module docstring).

    Args:
        maze: a :class:`~steer_envs.envs.maze_grid.MazeGrid`, a maze name or a Maze2D env.
        through_wall: probability that a sketch ignores the walls.
        min_length / max_length: sketch length range in cells (path length for
            ``"follow"``, straight distance for ``"through"``).
        points: number of points of every sketch.
        hand_jitter: uniform offset (cells) of each path corner, a shaky hand.
        seed: seed of the user's randomness (or pass ``rng`` to :meth:`draw`):
            None, an int >= 0, or a ``numpy.random.SeedSequence`` / ``BitGenerator``.

    Numbers must be real numbers (``through_wall`` in [0, 1], ``0 < min_length
    <= max_length`` finite, ``points`` an int in [2, MAX_POINTS], ``hand_jitter``
    in [0, 0.5)); strings and bools are refused with a ``TypeError`` naming
    the argument.

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
        owner = "SketchUser"
        self.grid = _as_grid(maze)
        self.through_wall = real_scalar(through_wall, "`through_wall`", low=0.0, high=1.0, owner=owner)
        self.min_length = real_scalar(min_length, "`min_length`", low=0.0, low_inclusive=False, owner=owner)
        self.max_length = real_scalar(max_length, "`max_length`", owner=owner)
        if not self.min_length <= self.max_length:
            raise ValueError(f"{owner}: need 0 < min_length <= max_length (finite), got {min_length!r}, {max_length!r}")
        self.points = integer(points, "`points`", low=2, high=MAX_POINTS, owner=owner)
        self.hand_jitter = real_scalar(
            hand_jitter, "`hand_jitter`", low=0.0, high=0.5, high_inclusive=False, owner=owner
        )
        self.rng = np.random.default_rng(_check_seed(seed, owner))
        free = [tuple(int(v) for v in c) for c in self.grid.free_cells]
        graph = nx.grid_2d_graph(*self.grid.shape)
        graph.remove_nodes_from([n for n in list(graph.nodes) if n not in set(free)])
        self.graph: nx.Graph = graph

    # ------------------------------------------------------------------ API
    def draw(self, start: Any, *, kind: SketchKind | None = None, rng: np.random.Generator | None = None) -> UserSketch:
        """A sketch from ``start`` (the agent's xy). ``kind`` forces ``"follow"`` or ``"through"``.

        A ``"through"`` sketch falls back to ``"follow"`` when no free cell in
        range lies behind a wall (e.g. in an open maze); ``ValueError`` when the
        start's cell reaches no cell in range at all. ``start`` is 2 finite reals.
        """
        owner = "SketchUser.draw"
        rng = self.rng if rng is None else rng
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"{owner}: `rng` must be a numpy.random.Generator or None, got {describe(rng)}")
        xy = real_array(start, "`start`", shape=(2,), owner=owner)
        if kind is not None:
            one_of(kind, "`kind`", ("follow", "through"), owner=owner)
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
        """One sketch per start (``(N, 2)`` finite reals, or one ``(2,)``), drawn in order from the user's generator."""
        arr = real_array(starts, "`starts`", owner="SketchUser.draws")
        if arr.shape != (2,) and (arr.ndim != 2 or arr.shape[1] != 2):
            raise ValueError(f"SketchUser.draws: `starts` must have shape (N, 2), got {arr.shape}")
        return [self.draw(s) for s in arr.reshape(-1, 2)]

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
        for _ in range(depth[goal]):  # walk back along a random shortest path: one cell closer per step
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
