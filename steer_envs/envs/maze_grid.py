"""The Maze2D maps and their wall grid: ITPS cell geometry in pure numpy (no simulator).

Coordinates are *cell units* with ``x = row`` and ``y = column``: cell ``(r, c)``
is the square ``[r - 0.5, r + 0.5) x [c - 0.5, c + 0.5)`` centred on ``(r, c)``.
:class:`MazeGrid` answers wall lookups, the ITPS collision rule, clearances and
shortest-path distances; :func:`maze_map` gives gymnasium-robotics' maps.

>>> grid = MazeGrid(maze_map("umaze"))
>>> grid.shape, bool(grid.is_wall([2.0, 1.0])), bool(grid.is_wall([1.0, 1.0]))
((5, 5), True, False)
"""

from __future__ import annotations

import contextlib
import io
from collections import deque
from collections.abc import Sequence
from typing import Any

import numpy as np

from steer_envs.core.validation import describe, real_array, real_scalar
from steer_envs.envs.checks import check_xy

#: the agent's radius (D4RL maze2d's point mass), in cells.
AGENT_RADIUS = 0.1
MAZE_NAMES: tuple[str, ...] = ("umaze", "medium", "large")
#: cells of a map: 1 is a wall; 0 and gymnasium-robotics' markers "r" (reset), "g" (goal), "c" (both) are free.
WALL_CELL, FREE_CELLS = 1, (0, "r", "g", "c")
#: largest accepted map side in cells (the MJCF holds one box per wall cell).
MAX_MAZE_SIDE = 100


def maze_map(name: str) -> list[list[int | str]]:
    """The gymnasium-robotics map of ``name`` (``"umaze"``, ``"medium"`` or ``"large"``)."""
    # imported lazily (the package registers ~100 envs); its import prints an unrelated Adroit-hand notice
    # to stderr, which is silenced here
    with contextlib.redirect_stderr(io.StringIO()):
        from gymnasium_robotics.envs.maze import maps

    table = {"umaze": maps.U_MAZE, "medium": maps.MEDIUM_MAZE, "large": maps.LARGE_MAZE}
    if not isinstance(name, str) or name not in table:
        raise ValueError(f"maze must be one of {MAZE_NAMES} or a 2D map of 0/1 cells, got {describe(name)}")
    return [list(row) for row in table[name]]


class MazeGrid:
    """Wall grid and the ITPS geometry helpers (pure numpy, no simulator).

    ``walls[r, c]`` is True for wall cells. Points outside the grid are
    clipped onto it before lookup, so everything beyond the border counts as
    the border's cells (walls in every shipped map).

    A layout is a non-empty rectangular sequence of rows (at most
    :data:`MAX_MAZE_SIDE` cells a side) whose cells are the int ``1`` (a wall)
    or ``0`` / ``"r"`` / ``"g"`` / ``"c"`` (free; gymnasium-robotics' reset,
    goal and combined markers). Anything else (the string ``"1"``, ``True``,
    ``1.0``, ``2``) is refused, naming the cell, instead of being read as free.
    """

    def __init__(self, layout: Sequence[Sequence[int | str]]) -> None:
        if isinstance(layout, (str, bytes)) or layout is None:
            raise TypeError(f"maze layout must be a sequence of rows of cells, got {describe(layout)}")
        try:
            rows = [list(r) for r in layout]
        except TypeError:
            raise TypeError(f"maze layout must be a sequence of rows of cells, got {describe(layout)}") from None
        if not rows or not rows[0] or any(len(r) != len(rows[0]) for r in rows):
            raise ValueError("maze layout must be a non-empty rectangular list of rows")
        if len(rows) > MAX_MAZE_SIDE or len(rows[0]) > MAX_MAZE_SIDE:
            raise ValueError(
                f"maze layout may be at most {MAX_MAZE_SIDE} x {MAX_MAZE_SIDE} cells, got {len(rows)} x {len(rows[0])}"
            )
        walls = np.array([[_is_wall_cell(cell, i, j) for j, cell in enumerate(r)] for i, r in enumerate(rows)])
        if walls.all():
            raise ValueError("maze layout has no free cell")
        self.walls: np.ndarray = walls
        self.walls.setflags(write=False)
        self.shape: tuple[int, int] = (walls.shape[0], walls.shape[1])
        self.free_cells: np.ndarray = np.argwhere(~walls).astype(np.int64)  # (K, 2), row-major order
        self.free_cells.setflags(write=False)

    @property
    def extent(self) -> float:
        """Length that normalizes distances: the maze height in cells (ITPS divides by it)."""
        return float(self.shape[0])

    @property
    def low(self) -> np.ndarray:
        """Lowest cell centre, ``(0, 0)``."""
        return np.zeros(2)

    @property
    def high(self) -> np.ndarray:
        """Highest cell centre, ``(rows - 1, cols - 1)``."""
        return np.array([self.shape[0] - 1, self.shape[1] - 1], dtype=np.float64)

    def cell_to_xy(self, cells: np.ndarray) -> np.ndarray:
        """Centres ``(..., 2)`` float of integer cells ``(..., 2)`` (row, col)."""
        return check_points(cells, "cells")

    def xy_to_cell(self, xy: np.ndarray) -> np.ndarray:
        """The cell ``(..., 2)`` int64 holding each point: clip to the grid, round to nearest (half up)."""
        arr = check_points(xy, "xy")
        return np.floor(np.clip(arr, self.low, self.high) + 0.5).astype(np.int64)

    def is_wall(self, xy: np.ndarray) -> np.ndarray:
        """Whether each point ``(..., 2)`` lies in a wall cell (the ITPS rule), bool ``(...)``."""
        cells = self.xy_to_cell(xy)
        return self.walls[cells[..., 0], cells[..., 1]]

    def plan_collides(self, plans: np.ndarray) -> np.ndarray:
        """ITPS collision check: a plan ``(..., H, 2)`` collides if any waypoint is in a wall; bool ``(...)``."""
        arr = check_points(plans, "plans")
        if arr.ndim < 2:
            raise ValueError(f"plans must have shape (..., H, 2), got {arr.shape}")
        return self.is_wall(arr).any(axis=-1)

    def clearance(self, xy: np.ndarray) -> np.ndarray:
        """Distance ``(...)`` from each point to the nearest wall box (0 inside a wall)."""
        arr = check_points(xy, "xy")
        centers = np.argwhere(self.walls).astype(np.float64)  # (W, 2)
        if len(centers) == 0:
            return np.full(arr.shape[:-1], np.inf)
        gap = np.maximum(np.abs(arr[..., None, :] - centers) - 0.5, 0.0)
        return np.sqrt((gap**2).sum(-1)).min(-1)

    def project_free(self, xy: np.ndarray, radius: float = AGENT_RADIUS) -> np.ndarray:
        """A position near ``xy`` (2,) where a disc of ``radius`` touches no wall (``xy`` itself if it is one).

        Used to place the agent after a push or a teleport: a point in a wall
        cell goes to the closest point of the nearest free cell, then it is
        pushed off the walls of that cell's 8-neighbourhood. ``radius`` is a real in ``[0, 0.5)``.
        """
        radius = real_scalar(radius, "radius", low=0.0, high=0.5, high_inclusive=False, owner="MazeGrid.project_free")
        p = np.clip(check_xy(xy, "xy", "MazeGrid.project_free"), self.low - 0.5, self.high + 0.5)
        r, c = self.xy_to_cell(p)
        if self.walls[r, c]:
            lo = self.free_cells - 0.5
            nearest = np.clip(p, lo, self.free_cells + 0.5)
            k = int(np.argmin(((nearest - p) ** 2).sum(-1)))
            r, c = self.free_cells[k]
            p = np.clip(nearest[k], self.free_cells[k] - 0.5 + 1e-9, self.free_cells[k] + 0.5 - 1e-9)
        for axis, step in ((0, -1), (0, 1), (1, -1), (1, 1)):
            nb = [r, c]
            nb[axis] += step
            if self._wall_at(*nb):
                bound = (r, c)[axis] + step * (0.5 - radius)
                p[axis] = max(p[axis], bound) if step < 0 else min(p[axis], bound)
        for dr in (-1, 1):
            for dc in (-1, 1):
                if self._wall_at(r + dr, c + dc):
                    corner = np.array([r + 0.5 * dr, c + 0.5 * dc])
                    away = p - corner
                    dist = float(np.hypot(*away))
                    inside_quadrant = away[0] * dr <= 0 and away[1] * dc <= 0
                    if inside_quadrant and dist < radius:
                        direction = away / dist if dist > 1e-12 else -np.array([dr, dc]) / np.sqrt(2.0)
                        p = corner + radius * direction
        return p

    def _wall_at(self, r: int, c: int) -> bool:
        if not (0 <= r < self.shape[0] and 0 <= c < self.shape[1]):
            return True
        return bool(self.walls[r, c])

    def _paths_to(self, goal: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Breadth-first search from free cell ``goal``: steps ``(R, C)`` (-1 where unreachable) and each
        cell's next cell ``(R, C, 2)`` on a shortest path to ``goal`` (cached per goal)."""
        cache: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = self.__dict__.setdefault("_path_cache", {})
        if goal in cache:
            return cache[goal]
        steps = np.full(self.shape, -1, dtype=np.int64)
        nxt = np.zeros((*self.shape, 2), dtype=np.int64)
        steps[goal] = 0
        nxt[goal] = goal
        queue = deque([goal])
        while queue:
            r, c = queue.popleft()
            for nr, nc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
                if not self._wall_at(nr, nc) and steps[nr, nc] < 0:
                    steps[nr, nc] = steps[r, c] + 1
                    nxt[nr, nc] = (r, c)
                    queue.append((nr, nc))
        cache[goal] = (steps, nxt)
        return steps, nxt

    def path_distance(self, xy: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """Distance ``(N,)`` from points ``xy`` to points ``goal`` (both ``(N, 2)``) along the maze.

        In the goal's cell the straight-line distance; otherwise ``s - 1 + |xy - next|``
        with ``s`` the number of cell steps of a shortest path of free cells to the
        goal's cell and ``next`` the centre of the first cell on it (or the goal
        itself when ``s = 1``). Unreachable pairs (a point in a wall cell) get the
        straight-line distance plus the number of cells.
        """
        p = check_points(xy, "xy").reshape(-1, 2)
        g = check_points(goal, "goal").reshape(-1, 2)
        if p.shape != g.shape:
            raise ValueError(f"xy and goal must have the same shape, got {p.shape} and {g.shape}")
        straight = np.linalg.norm(p - g, axis=1)
        out = straight + float(self.walls.size)
        cells, goal_cells = self.xy_to_cell(p), self.xy_to_cell(g)
        for key in {tuple(c) for c in goal_cells.tolist()}:
            if self.walls[key]:
                continue
            steps, nxt = self._paths_to((int(key[0]), int(key[1])))
            rows = np.flatnonzero((goal_cells == key).all(axis=1))
            r, c = cells[rows, 0], cells[rows, 1]
            s = steps[r, c]
            target = np.where((s <= 1)[:, None], g[rows], nxt[r, c].astype(np.float64))
            via = np.maximum(s - 1, 0) + np.linalg.norm(p[rows] - target, axis=1)
            out[rows] = np.where(s >= 0, via, out[rows])
        return out


def _is_wall_cell(cell: Any, row: int, col: int) -> bool:
    """Whether a map cell is a wall: the int 1 is; 0 and the markers "r", "g", "c" are not; else an error."""
    if isinstance(cell, str):
        if cell in FREE_CELLS:
            return False
        raise ValueError(
            f"maze layout cell ({row}, {col}) must be 1 (wall), 0, 'r', 'g' or 'c' (free), got {describe(cell)}"
        )
    if isinstance(cell, (int, np.integer)) and not isinstance(cell, (bool, np.bool_)):
        if cell in (0, 1):
            return bool(cell == WALL_CELL)
        raise ValueError(f"maze layout cell ({row}, {col}) must be 1 (wall) or 0 (free), got {describe(cell)}")
    raise TypeError(
        f"maze layout cell ({row}, {col}) must be the int 1 (wall), 0 or a marker 'r', 'g', 'c' (free), "
        f"got {describe(cell)}"
    )


def check_points(value: Any, name: str) -> np.ndarray:
    """Finite real points of shape ``(..., 2)`` (see :func:`steer_envs.core.validation.real_array`)."""
    arr = real_array(value, name)
    if arr.ndim == 0 or arr.shape[-1] != 2:
        raise ValueError(f"{name} must have shape (..., 2), got {arr.shape}")
    return arr
