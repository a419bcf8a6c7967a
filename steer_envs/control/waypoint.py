"""D4RL's maze2d waypoint controller: Q-iteration over grid cells, jittered waypoints, a goal test.

The controller of D4RL's ``generate_maze2d_datasets.py`` on the
:mod:`steer_envs.envs.maze2d` grid: :func:`q_iteration` (50 iterations, gamma
0.99) gives a greedy cell path to the goal (:func:`cell_path`); every waypoint
except the goal cell is jittered by ``-U(0, 0.2)`` per coordinate; the caller
tracks the waypoint :meth:`WaypointController.update` returns (D4RL: the PD law
``clip(10 (wp - pos) - vel, +-1)`` at 100 Hz) and the controller moves to the
next waypoint once within ``solve_thresh`` of it. The Maze2D random walk
(:mod:`steer_envs.data.maze_random_walk`) and the Maze2D expert
(:mod:`steer_envs.data.experts.maze2d`) drive the point mass with it.

>>> import numpy as np
>>> from steer_envs.envs.maze_grid import MazeGrid, maze_map
>>> grid = MazeGrid(maze_map("umaze"))
>>> ctrl = WaypointController(grid, np.random.default_rng(0))
>>> ctrl.plan(np.array([1.0, 1.0]), np.array([3.0, 1.0]))
>>> ctrl.target
(3, 1)
"""

from __future__ import annotations

import math

import numpy as np

from steer_envs.core.validation import real_scalar
from steer_envs.envs.maze_grid import MazeGrid

__all__ = ["WaypointController", "cell_path", "q_iteration"]

#: grid moves in Q-iteration's action order (ties go to the first): stay, -row, +row, -col, +col.
_MOVES = np.array([[0, 0], [-1, 0], [1, 0], [0, -1], [0, 1]], dtype=np.int64)


def q_iteration(walls: np.ndarray, target: tuple[int, int], iters: int = 50, gamma: float = 0.99) -> np.ndarray:
    """Q-values ``(rows, cols, 5)`` of the grid world with reward 1 for entering ``target``.

    Moves into walls or off the grid stay in place. With ``iters`` sweeps a
    cell farther than ``iters`` moves from the target keeps Q = 0 (D4RL).
    """
    walls = np.asarray(walls, dtype=bool)
    rows, cols = walls.shape
    tr, tc = target
    if not (0 <= tr < rows and 0 <= tc < cols) or walls[tr, tc]:
        raise ValueError(f"target {target} must be a free cell of the {walls.shape} grid")
    cells = np.stack(np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"), axis=-1)  # (R, C, 2)
    dest = cells[:, :, None, :] + _MOVES  # (R, C, 5, 2)
    inside = (dest[..., 0] >= 0) & (dest[..., 0] < rows) & (dest[..., 1] >= 0) & (dest[..., 1] < cols)
    dest = np.where(inside[..., None], dest, cells[:, :, None, :])
    blocked = walls[dest[..., 0], dest[..., 1]]
    dest = np.where(blocked[..., None], cells[:, :, None, :], dest)
    reward = ((dest[..., 0] == tr) & (dest[..., 1] == tc)).astype(np.float64)
    q = np.zeros((rows, cols, len(_MOVES)))
    for _ in range(int(iters)):
        v = q.max(axis=-1)
        q = reward + gamma * v[dest[..., 0], dest[..., 1]]
    return q


def cell_path(
    grid: MazeGrid, start: tuple[int, int], target: tuple[int, int], iters: int = 50
) -> list[tuple[int, int]]:
    """Greedy cell path ``start -> target`` (excluding ``start``) from :func:`q_iteration`."""
    if start == target:
        return [target]
    q = q_iteration(grid.walls, target, iters=iters)
    path, cell = [], start
    for _ in range(grid.walls.size):
        move = _MOVES[int(np.argmax(q[cell]))]
        nxt = (cell[0] + int(move[0]), cell[1] + int(move[1]))
        if nxt == cell:
            raise ValueError(f"no path from {start} to {target} within {iters} Q-iterations")
        path.append(nxt)
        cell = nxt
        if cell == target:
            return path
    raise ValueError(f"no path from {start} to {target}")


class WaypointController:
    """D4RL's maze2d waypoint controller, returning the waypoint the PD law tracks.

    Args:
        grid: the maze.
        rng: randomness of the waypoint jitter.
        jitter: waypoints (except the goal cell) are ``cell - U(0, jitter)`` per coordinate.
        solve_thresh: distance at which a waypoint (or the goal) counts as reached.
        vel_thresh: bound on the displacement between two calls for reaching
            (D4RL: 0.1 per 0.01 s step; scale it with the call period).
    """

    def __init__(
        self,
        grid: MazeGrid,
        rng: np.random.Generator | None = None,
        *,
        jitter: float = 0.2,
        solve_thresh: float = 0.1,
        vel_thresh: float = 0.1,
    ) -> None:
        owner = "WaypointController"
        if not isinstance(grid, MazeGrid):
            raise TypeError(f"{owner}: grid must be a MazeGrid, got {type(grid).__name__}")
        if rng is not None and not isinstance(rng, np.random.Generator):
            raise TypeError(f"{owner}: rng must be a numpy Generator or None, got {type(rng).__name__}")
        self.grid = grid
        self.rng = rng if rng is not None else np.random.default_rng()
        self.jitter = real_scalar(jitter, "jitter", low=0.0, owner=owner)
        self.solve_thresh = real_scalar(solve_thresh, "solve_thresh", low=0.0, owner=owner)
        self.vel_thresh = real_scalar(vel_thresh, "vel_thresh", low=0.0, owner=owner)
        self.target: tuple[int, int] | None = None
        self.waypoints: list[tuple[float, float]] = []
        self.index = 0
        self._prev = (0.0, 0.0)

    def plan(self, pos: np.ndarray, goal_xy: np.ndarray) -> None:
        """Waypoints from the cell of ``pos`` to the cell of ``goal_xy``."""
        start = tuple(int(v) for v in self.grid.xy_to_cell(pos))
        target = tuple(int(v) for v in self.grid.xy_to_cell(goal_xy))
        if self.grid.walls[target]:
            raise ValueError(f"goal {np.asarray(goal_xy).tolist()} lies in a wall cell")
        waypoints = []
        for cell in cell_path(self.grid, start, target):  # type: ignore[arg-type]
            wp = np.array(cell, dtype=np.float64)
            if cell != target:
                wp = wp - self.rng.uniform(size=2) * self.jitter
            waypoints.append((float(wp[0]), float(wp[1])))
        self.target = target  # type: ignore[assignment]
        self.waypoints = waypoints
        self.index = 0
        self._prev = (float(pos[0]), float(pos[1]))

    def update(self, x: float, y: float) -> tuple[tuple[float, float], bool]:
        """The waypoint to track from ``(x, y)`` and whether the goal is solved (D4RL ``get_action``)."""
        if self.target is None:
            raise RuntimeError("WaypointController.update called before plan()")
        tx, ty = self.target
        moved = math.hypot(self._prev[0] - x, self._prev[1] - y)
        solved = math.hypot(x - tx, y - ty) < self.solve_thresh and moved < self.vel_thresh
        wp = (float(tx), float(ty)) if solved else self.waypoints[self.index]
        if not solved and math.hypot(x - wp[0], y - wp[1]) < self.solve_thresh and moved < self.vel_thresh:
            self.index = min(self.index + 1, len(self.waypoints) - 1)
        self._prev = (x, y)
        return wp, solved
