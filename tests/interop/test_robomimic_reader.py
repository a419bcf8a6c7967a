"""robomimic's own ``SequenceDataset`` reads what :func:`~steer_envs.data.robomimic_hdf5.to_robomimic` writes."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from steer_envs.data.robomimic_hdf5 import from_robomimic, to_robomimic
from steer_envs.data.trajectories import TrajectoryDataset


def test_sequence_dataset_reads_the_export(tmp_path: Path, maze_trajectories: TrajectoryDataset) -> None:
    import robomimic.utils.obs_utils as obs_utils
    from robomimic.utils.dataset import SequenceDataset

    ds = TrajectoryDataset(maze_trajectories.observations[:300], maze_trajectories.actions[:300], [0, 100])
    path = to_robomimic(ds, tmp_path / "maze.hdf5")
    obs_utils.initialize_obs_utils_with_obs_specs({"obs": {"low_dim": ["state"]}})
    seq = SequenceDataset(
        hdf5_path=str(path),
        obs_keys=("state",),
        dataset_keys=("actions", "rewards", "dones"),
        seq_length=4,
        hdf5_cache_mode="all",
        hdf5_use_swmr=False,
    )
    assert seq.n_demos == 2 and seq.total_num_sequences == 300
    item = seq[105]  # the 6th step of demo_1
    np.testing.assert_array_equal(item["obs"]["state"][0], ds.observations[105])
    np.testing.assert_array_equal(item["actions"], ds.actions[105:109])
    back = from_robomimic(path)
    np.testing.assert_array_equal(back.observations, ds.observations)
    np.testing.assert_array_equal(back.episode_starts, ds.episode_starts)
