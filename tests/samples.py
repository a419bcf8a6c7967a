"""Small sample objects several test modules build the same way (importable: pytest's ``pythonpath``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from steer_envs.data.counterfactual_dataset import KINDS, CounterfactualDataset
from steer_envs.data.maze_random_walk import generate_random_walk
from steer_envs.data.trajectories import TrajectoryDataset


def tiny_counterfactual(scale: float = 1.0) -> CounterfactualDataset:
    """Two trajectories of three 2-D states (a demo and a failed segment replay), states times ``scale``."""
    return CounterfactualDataset(
        states=np.arange(12, dtype=np.float32).reshape(6, 2) * np.float32(scale),
        modes=np.zeros(6, np.int16),
        offsets=np.array([0, 3, 6], np.int64),
        success=np.array([True, False]),
        kind=np.array([KINDS.index("demo"), KINDS.index("segment")], np.int8),
        source=np.zeros(2, np.int32),
        window=np.zeros((2, 2), np.int32),
        target=np.full((2, 2), np.nan, np.float32),
        violation_step=np.array([-1, 1], np.int32),
        meta={"env_id": "x"},
    )


def maze_walk_fixture(seed: int) -> Callable[[], TrajectoryDataset]:
    """A module-scoped fixture: the training view of a 20k-step Maze2D-Large random walk (5k samples) of ``seed``."""

    @pytest.fixture(scope="module")
    def walk() -> TrajectoryDataset:
        return generate_random_walk("large", 20_000, seed=seed, progress=False).to_trajectories()

    return walk
