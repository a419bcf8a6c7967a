"""Trajectory datasets: validation, pooled statistics, windows, file round trip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from steer_envs.data.trajectories import PlanWindows, TrajectoryDataset, load_trajectories, save_trajectories


def _two_episodes(n: int = 30) -> TrajectoryDataset:
    xy = np.stack([np.arange(n, dtype=np.float32), np.zeros(n, dtype=np.float32)], 1)
    actions = xy + np.array([1.0, 0.0], dtype=np.float32)  # each step moves one unit along x
    return TrajectoryDataset(xy, actions, episode_starts=[0, 12])


def test_plan_windows_follow_the_layouts_and_respect_episodes() -> None:
    ds = _two_episodes()
    windows = PlanWindows(ds, n_obs=2, horizon=5)
    # episode [0, 12): t in 1..7 (plan actions[t .. t+4] ends at 11); episode [12, 30): t in 13..25
    assert windows.steps.tolist() == [*range(1, 8), *range(13, 26)]
    obs, plan = windows[0]
    np.testing.assert_array_equal(obs[:, 0], [0, 1])
    np.testing.assert_array_equal(plan[:, 0], [2, 3, 4, 5, 6])  # the next 5 positions
    lerobot = PlanWindows(ds, n_obs=2, horizon=5, action_start=-1)
    obs, plan = lerobot[0]
    np.testing.assert_array_equal(plan[:, 0], [1, 2, 3, 4, 5])  # starts at the current position
    batch_obs, batch_plans = windows.gather(np.arange(len(windows)))
    assert batch_obs.shape == (20, 2, 2) and batch_plans.shape == (20, 5, 2)
    assert np.all(np.diff(batch_plans[..., 0], axis=1) == 1)  # never crosses the episode boundary
    sizes = [len(p) for _, p in windows.batches(8, np.random.default_rng(0))]
    assert sizes == [8, 8, 4]
    with pytest.raises(IndexError):
        windows[20]
    with pytest.raises(ValueError, match="action_start"):
        PlanWindows(ds, n_obs=2, action_start=-2)
    with pytest.raises(TypeError, match="TrajectoryDataset"):
        PlanWindows({"observations": []})  # type: ignore[arg-type]


def test_windows_of_any_width() -> None:
    rng = np.random.default_rng(0)
    ds = TrajectoryDataset(rng.normal(size=(40, 7)), rng.normal(size=(40, 4)), episode_starts=[0, 25])
    obs, plans = PlanWindows(ds, n_obs=3, horizon=6).gather(np.arange(4))
    assert obs.shape == (4, 3, 7) and plans.shape == (4, 6, 4)
    np.testing.assert_array_equal(obs[0], ds.observations[0:3])


def test_statistics_are_per_feature_unless_actions_set_observation_entries() -> None:
    rng = np.random.default_rng(1)
    obs, act = rng.normal(size=(50, 5)), rng.normal(size=(50, 2)) * 3
    plain = TrajectoryDataset(obs, act).stats()
    as_stored = obs.astype(np.float32).astype(np.float64)  # the dataset keeps float32, statistics are float64
    np.testing.assert_array_equal(plain["observation"]["mean"], as_stored.mean(axis=0))
    np.testing.assert_array_equal(plain["action"]["max"], act.astype(np.float32).max(axis=0))
    pooled = TrajectoryDataset(obs, act, action_obs_indices=(4, 1)).stats()
    both = np.concatenate([obs[:, [4, 1]], act]).astype(np.float32).astype(np.float64)
    for key in ("min", "max", "mean", "std"):
        np.testing.assert_array_equal(pooled["action"][key], getattr(np, key)(both, axis=0))
        np.testing.assert_array_equal(pooled["observation"][key][[4, 1]], pooled["action"][key])
        np.testing.assert_array_equal(pooled["observation"][key][[0, 2, 3]], plain["observation"][key][[0, 2, 3]])


def test_round_trip_keeps_arrays_declarations_and_meta(tmp_path: Path) -> None:
    ds = TrajectoryDataset(
        np.arange(24.0).reshape(6, 4),
        np.ones((6, 2)),
        episode_starts=[0, 3],
        obs_indices=(2, 0, 1, 3),
        action_obs_indices=(0, 1),
        meta={"seed": 2, "robot": "panda", "nested": {"a": 1}},
    )
    path = save_trajectories(ds, tmp_path / "sub" / "d.npz")
    assert [p.name for p in path.parent.iterdir()] == ["d.npz"]  # atomic: no temp file left
    loaded = load_trajectories(path)
    np.testing.assert_array_equal(loaded.observations, ds.observations)
    np.testing.assert_array_equal(loaded.episode_starts, [0, 3])
    assert (loaded.obs_indices, loaded.action_obs_indices, loaded.meta) == ((2, 0, 1, 3), (0, 1), ds.meta)
    assert loaded.provenance() == {"seed": 2, "robot": "panda"}
    with pytest.raises(ValueError, match="npz"):
        save_trajectories(ds, tmp_path / "d.h5")
    with pytest.raises(ValueError, match="no dataset"):
        load_trajectories(tmp_path / "absent.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(ValueError, match="not a trajectory dataset"):
        load_trajectories(tmp_path / "other.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(ValueError, match=r"junk\.npz"):
        load_trajectories(tmp_path / "junk.npz")


def test_bad_datasets_raise() -> None:
    with pytest.raises(ValueError, match="observations"):
        TrajectoryDataset(np.zeros(5), np.zeros((5, 2)))
    with pytest.raises(ValueError, match="actions"):
        TrajectoryDataset(np.zeros((5, 3)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="finite"):
        TrajectoryDataset(np.full((5, 3), np.nan), np.zeros((5, 2)))
    with pytest.raises(ValueError, match="episode_starts"):
        TrajectoryDataset(np.zeros((5, 3)), np.zeros((5, 2)), episode_starts=[1, 3])
    with pytest.raises(ValueError, match="obs_indices"):
        TrajectoryDataset(np.zeros((5, 3)), np.zeros((5, 2)), obs_indices=(0, 1))
    with pytest.raises(ValueError, match="action_obs_indices"):
        TrajectoryDataset(np.zeros((5, 3)), np.zeros((5, 2)), action_obs_indices=(0, 3))
    with pytest.raises(ValueError, match="action_obs_indices"):
        TrajectoryDataset(np.zeros((5, 3)), np.zeros((5, 2)), action_obs_indices=(1, 1))
