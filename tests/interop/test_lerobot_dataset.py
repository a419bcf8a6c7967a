"""steer-envs -> LeRobotDataset -> steer-envs, through LeRobot's own writer and reader."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from steer_envs.data.datasets import load_dataset
from steer_envs.data.lerobot_dataset import ENV_STATE, STATE, from_lerobot, to_lerobot
from steer_envs.data.trajectories import TrajectoryDataset


def test_round_trip_keeps_every_array(tmp_path: Path, maze_trajectories: TrajectoryDataset) -> None:
    part = maze_trajectories
    ds = TrajectoryDataset(
        part.observations[:600],
        part.actions[:600],
        [0, 150, 420],
        obs_indices=part.obs_indices,
        action_obs_indices=part.action_obs_indices,
        meta=part.meta,
    )
    root = to_lerobot(ds, tmp_path / "ds", fps=25)
    for back in (from_lerobot(root), load_dataset(f"lerobot:{root}")):
        np.testing.assert_array_equal(back.observations, ds.observations)
        np.testing.assert_array_equal(back.actions, ds.actions)
        np.testing.assert_array_equal(back.episode_starts, ds.episode_starts)
        declared = (back.obs_indices, back.action_obs_indices, back.meta)
        assert declared == (ds.obs_indices, ds.action_obs_indices, ds.meta)


def test_lerobot_reads_the_export_as_its_own(lerobot_root: Path, maze_trajectories: TrajectoryDataset) -> None:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    fps = 25
    ds = LeRobotDataset("steer/maze2d", root=lerobot_root, delta_timestamps={"action": [i / fps for i in range(4)]})
    assert ds.fps == fps and ds.num_frames == len(maze_trajectories) and ds.num_episodes == 1
    item = ds[10]
    np.testing.assert_array_equal(item[STATE].numpy(), maze_trajectories.observations[10])
    np.testing.assert_array_equal(item[ENV_STATE].numpy(), maze_trajectories.observations[10])
    np.testing.assert_array_equal(item["action"].numpy(), maze_trajectories.actions[10:14])
    assert {"mean", "std", "min", "max"} <= set(ds.meta.stats["action"])


def test_export_refuses_what_it_cannot_write(tmp_path: Path, maze_trajectories: TrajectoryDataset) -> None:
    bare = TrajectoryDataset(maze_trajectories.observations[:10], maze_trajectories.actions[:10], [0])
    with pytest.raises(ValueError, match="`fps` is needed"):
        to_lerobot(bare, tmp_path / "x")
    to_lerobot(bare, tmp_path / "x", fps=10)
    with pytest.raises(FileExistsError):
        to_lerobot(bare, tmp_path / "x", fps=10)


def test_the_training_entry_point_reads_a_lerobot_dataset(tmp_path: Path, lerobot_root: Path) -> None:
    import subprocess
    import sys

    out = tmp_path / "dp.safetensors"
    command = [sys.executable, "-m", "steer_envs.baselines.training", "--policy", "dp", "--dataset",
               f"lerobot:{lerobot_root}", "--steps", "3", "--model", "down_dims=[16,32]", "--out", str(out),
               "--no-progress"]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert out.is_file() and out.with_suffix(".json").is_file()
