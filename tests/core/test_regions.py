"""Boxes regions and TaskSpec's regions, forbidden regions and mode regions."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.core.regions import Boxes
from steer_envs.core.task import TaskSpec


def test_boxes_depth_and_contains() -> None:
    boxes = Boxes.cells([[0.0, 0.0], [0.0, 1.0]])  # two unit cells side by side
    pts = np.array([[0.0, 0.0], [0.0, 0.45], [0.3, 1.2], [2.0, 2.0]])
    assert boxes.contains(pts).tolist() == [True, True, True, False]
    np.testing.assert_allclose(boxes.depth(pts), [0.5, 0.05, 0.2, 0.0])
    arm = Boxes([[0.0, 0.0, 0.0]], [[1.0, 1.0, 0.8]], dims=(0, 1, 2))
    assert arm.contains(np.array([[0.5, 0.5, 0.5, 1.0]])).tolist() == [True]  # [x, y, z, gripper]


def test_boxes_refuse_bad_input() -> None:
    with pytest.raises(ValueError, match="both be"):
        Boxes([0.0, 0.0], [1.0, 1.0])
    with pytest.raises(ValueError, match=r"every `high` must be >="):
        Boxes([[1.0]], [[0.0]])
    with pytest.raises(ValueError, match="distinct plan entries"):
        Boxes([[0.0, 0.0]], [[1.0, 1.0]], dims=(0, 0))
    with pytest.raises(ValueError, match="need entries"):
        Boxes([[0.0, 0.0]], [[1.0, 1.0]], dims=(2, 3)).contains(np.zeros((4, 2)))


def test_task_regions_are_checked_and_give_the_unsafe_ones() -> None:
    box = Boxes([[0.0]], [[1.0]])
    with pytest.raises(ValueError, match="unknown regions"):
        TaskSpec("t", ("a",), regions={"r": box}, forbidden=("nope",))
    with pytest.raises(TypeError, match="must map names to Boxes"):
        TaskSpec("t", ("a",), regions={"r": [0, 1]})
    with pytest.raises(ValueError, match="unknown mode or region"):
        TaskSpec("t", ("a",), regions={"r": box}, mode_regions={"z": "r"})
    task = TaskSpec(
        "t",
        ("a", "b", "c"),
        transitions={("a", "b"), ("b", "c")},
        regions={"wall": box, "b": Boxes([[2.0]], [[3.0]]), "c": Boxes([[4.0]], [[5.0]])},
        forbidden=("wall",),
        mode_regions={"b": "b", "c": "c"},
    )
    assert task.unsafe_regions() == [task.regions["wall"]]
    assert task.unsafe_regions("a") == [task.regions["wall"], task.regions["c"]]  # a -> c is not allowed
    assert task.unsafe_regions("b") == [task.regions["wall"]]


def test_the_maze_task_forbids_exactly_its_wall_cells() -> None:
    env = gym.make("steer_envs/Maze2D-Large-v0").unwrapped
    walls = env.task.regions["walls"]
    assert env.task.forbidden == ("walls",)
    # beyond the border too: is_wall clips to the grid, so outside is wall (a safety cost must push back in)
    pts = np.random.default_rng(0).uniform(env.grid.low - 3, env.grid.high + 3, (4000, 2))
    np.testing.assert_array_equal(walls.contains(pts), env.is_wall(pts))
    env.close()
