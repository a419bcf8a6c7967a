"""Simulated sketch user: seeded sketches from the agent, along free cells or straight through walls."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest

from steer_envs.core.interaction import Sketch
from steer_envs.envs.maze2d import Maze2DEnv
from steer_envs.envs.maze_grid import MazeGrid, maze_map
from steer_envs.users.sketcher import SketchUser, UserSketch


@pytest.fixture(scope="module")
def grid() -> MazeGrid:
    return MazeGrid(maze_map("large"))


def random_starts(grid: MazeGrid, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    cells = grid.free_cells[rng.integers(len(grid.free_cells), size=n)]
    return cells + rng.uniform(-0.1, 0.1, size=(n, 2))


def cell_path_length(grid: MazeGrid, a: tuple[int, int], b: tuple[int, int]) -> int:
    g = nx.grid_2d_graph(*grid.shape)
    g.remove_nodes_from([tuple(c) for c in np.argwhere(grid.walls).tolist()])
    return int(nx.shortest_path_length(g, a, b))


def test_sketches_start_at_the_agent_and_are_seeded(grid: MazeGrid) -> None:
    starts = random_starts(grid, 20)
    a, b = SketchUser(grid, seed=3).draws(starts), SketchUser(grid, seed=3).draws(starts)
    c = SketchUser(grid, seed=4).draws(starts)
    for x, y, start in zip(a, b, starts, strict=True):
        assert isinstance(x, UserSketch) and isinstance(x.sketch, Sketch)
        assert x.sketch == y.sketch and x.kind == y.kind and x.goal_cell == y.goal_cell
        np.testing.assert_allclose(x.sketch.points[0], start)
        assert len(x.sketch) == 64
    assert any(x.sketch != z.sketch for x, z in zip(a, c, strict=True))


def test_follow_sketches_trace_free_cells_to_a_reachable_goal_in_range(grid: MazeGrid) -> None:
    user = SketchUser(grid, seed=0, min_length=4, max_length=9)
    for start in random_starts(grid, 30, seed=1):
        drawn = user.draw(start, kind="follow")
        assert drawn.kind == "follow" and not drawn.collides
        assert not grid.is_wall(drawn.sketch.points).any()
        start_cell = tuple(int(v) for v in grid.xy_to_cell(start))
        assert 4 <= cell_path_length(grid, start_cell, drawn.goal_cell) <= 9
        end_cell = tuple(int(v) for v in grid.xy_to_cell(drawn.sketch.points[-1]))
        assert end_cell == drawn.goal_cell
        steps = np.linalg.norm(np.diff(drawn.sketch.points, axis=0), axis=1)
        assert steps.max() < 1.5 * steps.mean()  # evenly resampled in arc length, like a steady hand


def test_through_sketches_cross_walls_and_the_share_follows_the_probability(grid: MazeGrid) -> None:
    user = SketchUser(grid, seed=0, through_wall=0.3)
    drawn = user.draws(random_starts(grid, 200, seed=2))
    through = [d for d in drawn if d.kind == "through"]
    assert 0.2 < len(through) / len(drawn) < 0.4
    assert sum(d.collides for d in through) >= 0.9 * len(through)
    for d in through:
        pts = d.sketch.points
        v = pts[-1] - pts[0]
        residual = np.abs((pts[:, 0] - pts[0, 0]) * v[1] - (pts[:, 1] - pts[0, 1]) * v[0]) / np.linalg.norm(v)
        assert residual.max() < 1e-6  # a straight line, ignoring the maze
        assert 4.0 - 0.3 <= np.linalg.norm(v) <= 9.0 + 0.3
    assert all(d.kind == "follow" for d in SketchUser(grid, seed=0, through_wall=0.0).draws(random_starts(grid, 20)))


def test_accepts_envs_names_and_falls_back_in_small_mazes() -> None:
    env = Maze2DEnv("umaze")
    user = SketchUser(env, seed=0, min_length=20, max_length=30)  # longer than any U-maze path
    drawn = user.draw(env.grid.free_cells[0].astype(float), kind="through")
    assert drawn.kind == "follow" and not drawn.collides  # no cell that far: the farthest reachable cell
    assert SketchUser("medium", seed=0).grid.shape == (8, 8)


def test_bad_arguments_are_rejected(grid: MazeGrid) -> None:
    with pytest.raises(TypeError, match="maze"):
        SketchUser(42)
    with pytest.raises(ValueError, match="through_wall"):
        SketchUser(grid, through_wall=1.5)
    with pytest.raises(ValueError, match="min_length"):
        SketchUser(grid, min_length=5, max_length=2)
    with pytest.raises(ValueError, match="points"):
        SketchUser(grid, points=1)
    user = SketchUser(grid, seed=0)
    with pytest.raises(ValueError, match="wall cell"):
        user.draw([0.0, 0.0])
    with pytest.raises(ValueError, match="start"):
        user.draw([1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="kind"):
        user.draw([1.0, 1.0], kind="zigzag")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="rng"):
        user.draw([1.0, 1.0], rng=np.random.RandomState(0))  # type: ignore[arg-type]
