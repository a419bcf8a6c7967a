"""steer-envs trajectories through robomimic HDF5 and Minari and back, and ``load_dataset``'s ``KIND:WHERE`` names.

The LeRobotDataset round trip needs LeRobot, whose pins clash with this
environment's: it runs in ``scripts/test_interop.sh`` (tests/interop).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from steer_envs.data.datasets import canonical_dataset, load_dataset
from steer_envs.data.maze_random_walk import generate_random_walk
from steer_envs.data.minari_trajectories import from_minari, trajectories_to_minari
from steer_envs.data.robomimic_hdf5 import from_robomimic, to_robomimic
from steer_envs.data.trajectories import TrajectoryDataset
from steer_envs.io import DatasetError


@pytest.fixture(scope="module")
def trajectories() -> TrajectoryDataset:
    """A Maze2D walk's trajectories cut into three episodes of unequal length, with its declarations."""
    walk = generate_random_walk("umaze", 1200, seed=3, progress=False).to_trajectories()
    return TrajectoryDataset(
        walk.observations,
        walk.actions,
        [0, 70, 190],
        obs_indices=walk.obs_indices,
        action_obs_indices=walk.action_obs_indices,
        meta=walk.meta,
    )


def assert_same(back: TrajectoryDataset, ds: TrajectoryDataset) -> None:
    np.testing.assert_array_equal(back.observations, ds.observations)
    np.testing.assert_array_equal(back.actions, ds.actions)
    np.testing.assert_array_equal(back.episode_starts, ds.episode_starts)
    assert back.observations.dtype == ds.observations.dtype and back.actions.dtype == ds.actions.dtype
    assert (back.obs_indices, back.action_obs_indices, back.meta) == (ds.obs_indices, ds.action_obs_indices, ds.meta)


def test_robomimic_round_trip_keeps_every_array(tmp_path: Path, trajectories: TrajectoryDataset) -> None:
    path = to_robomimic(trajectories, tmp_path / "maze.hdf5")
    assert_same(from_robomimic(path), trajectories)
    assert_same(load_dataset(f"robomimic:{path}"), trajectories)


def test_robomimic_layout_is_the_documented_one(tmp_path: Path, trajectories: TrajectoryDataset) -> None:
    import h5py

    with h5py.File(to_robomimic(trajectories, tmp_path / "maze.hdf5", obs_key="xy"), "r") as f:
        assert sorted(f["data"]) == ["demo_0", "demo_1", "demo_2"]
        assert f["data"].attrs["total"] == len(trajectories)
        demo = f["data/demo_1"]
        assert demo.attrs["num_samples"] == 120 and demo["obs/xy"].shape == (120, 2)
        assert demo["actions"].shape == (120, 2) and demo["dones"][-1] == 1 and demo["dones"][:-1].sum() == 0
        np.testing.assert_array_equal(demo["next_obs/xy"][:-1], demo["obs/xy"][1:])


def test_bad_robomimic_files_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="no robomimic dataset file"):
        from_robomimic(tmp_path / "missing.hdf5")
    (tmp_path / "junk.hdf5").write_bytes(b"not hdf5")
    with pytest.raises(DatasetError, match=r"junk\.hdf5 is not an HDF5 file"):
        load_dataset(f"robomimic:{tmp_path / 'junk.hdf5'}")


def test_minari_round_trip_keeps_every_array(tmp_path: Path, trajectories: TrajectoryDataset) -> None:
    stored = trajectories_to_minari(
        trajectories, "steer/bridge-v0", env_id="steer_envs/Maze2D-Umaze-v0", root=tmp_path / "minari"
    )
    assert stored.total_episodes == 3 and stored.total_steps == len(trajectories)
    assert_same(from_minari(stored), trajectories)
    assert_same(from_minari("steer/bridge-v0", root=tmp_path / "minari"), trajectories)


def test_minari_ids_load_through_load_dataset(tmp_path: Path, trajectories: TrajectoryDataset, monkeypatch) -> None:
    trajectories_to_minari(trajectories, "steer/bridge-v0", env_id="steer_envs/Maze2D-Umaze-v0", root=tmp_path)
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    assert_same(load_dataset("minari:steer/bridge-v0"), trajectories)
    assert canonical_dataset("minari:steer/bridge-v0") == "minari:steer/bridge-v0"


def test_dataset_names(tmp_path: Path) -> None:
    assert canonical_dataset("robomimic:x.hdf5") == f"robomimic:{Path('x.hdf5').resolve()}"
    assert canonical_dataset("plain.npz") == str(Path("plain.npz").resolve())
    with pytest.raises(DatasetError, match="say where after 'lerobot:'"):
        load_dataset("lerobot:")
    with pytest.raises(DatasetError, match="no LeRobotDataset at"):
        load_dataset(f"lerobot:{tmp_path}")
