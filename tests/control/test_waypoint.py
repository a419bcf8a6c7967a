"""The Maze2D waypoint controller: Q-iteration paths, waypoint jitter, the goal test."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest

from steer_envs.control.waypoint import WaypointController, cell_path, q_iteration
from steer_envs.envs.maze_grid import MazeGrid, maze_map

LARGE = MazeGrid(maze_map("large"))


def test_q_iteration_paths_are_shortest_grid_paths() -> None:
    graph = nx.grid_2d_graph(*LARGE.shape)
    graph.remove_nodes_from([tuple(c) for c in np.argwhere(LARGE.walls).tolist()])
    rng = np.random.default_rng(0)
    free = [tuple(c) for c in LARGE.free_cells.tolist()]
    for _ in range(25):
        a, b = (free[i] for i in rng.choice(len(free), size=2, replace=False))
        path = cell_path(LARGE, a, b)
        assert path[-1] == b and len(path) == nx.shortest_path_length(graph, a, b)
        steps = np.abs(np.diff(np.array([a, *path]), axis=0)).sum(axis=1)
        assert np.all(steps == 1) and not LARGE.walls[tuple(np.array(path).T)].any()
    q = q_iteration(LARGE.walls, (1, 1), iters=3)
    assert q[(7, 10)].max() == 0.0  # beyond the sweep horizon nothing is known (D4RL's 50-sweep limit)
    with pytest.raises(ValueError, match="target"):
        q_iteration(LARGE.walls, (0, 0))


def test_controller_jitters_every_waypoint_but_the_goal() -> None:
    ctrl = WaypointController(LARGE, np.random.default_rng(0))
    ctrl.plan(np.array([1.0, 1.0]), np.array([7.04, 9.97]))
    wps = np.array(ctrl.waypoints)
    offsets = np.round(wps[:-1]) - wps[:-1]
    assert np.all((offsets >= 0) & (offsets <= 0.2)) and offsets.std() > 0
    np.testing.assert_array_equal(wps[-1], [7.0, 10.0])
    with pytest.raises(RuntimeError, match="plan"):
        WaypointController(LARGE).update(1.0, 1.0)
