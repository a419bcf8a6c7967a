"""Every writer of datasets and checkpoints: normal file modes, and a SIGKILL mid-write loses nothing.

Each writer writes an old version, then a forked child is killed (SIGKILL) after
writing a new version's data but before the rename: the old version must load
unchanged, and the next write must remove the child's leftover.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from kills import kill_mid_write
from samples import tiny_counterfactual

from steer_envs.baselines.bc import BCConfig, BCPolicy
from steer_envs.baselines.diffusion import DiffusionConfig, DiffusionPolicy
from steer_envs.baselines.glide.classifier import ModeClassifier
from steer_envs.data.counterfactual_dataset import CounterfactualDataset
from steer_envs.data.maze_random_walk import (
    RandomWalkDataset,
    generate_random_walk,
    goal_episodes,
    load_random_walk,
    save_random_walk,
    to_minari,
)
from steer_envs.data.trajectories import TrajectoryDataset, load_trajectories, save_trajectories


def _temps(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def _walk(scale: float) -> RandomWalkDataset:
    walk = generate_random_walk("umaze", 40, seed=0, progress=False)
    walk.observations = walk.observations * np.float32(scale)
    return walk


def _dp(seed: int) -> DiffusionPolicy:
    cfg = DiffusionConfig(obs_dim=2, action_dim=2, horizon=8, down_dims=(8, 16), obs_embed_dim=8, step_embed_dim=8)
    return DiffusionPolicy(cfg, seed=seed)


def _state(model: torch.nn.Module) -> list[float]:
    return [float(v.double().sum()) for v in model.state_dict().values()]


#: name -> (file name, make version k, write it, read a comparable summary)
WRITERS: dict[str, tuple[str, Callable[[int], Any], Callable[[Any, Path], Any], Callable[[Path], Any]]] = {
    "trajectories": (
        "t.npz",
        lambda k: TrajectoryDataset(np.full((5, 2), k, np.float32), np.ones((5, 2))),
        lambda d, p: save_trajectories(d, p),
        lambda p: load_trajectories(p).observations.tolist(),
    ),
    "random_walk": (
        "w.npz",
        lambda k: _walk(k + 1.0),
        lambda d, p: save_random_walk(d, p),
        lambda p: load_random_walk(p).observations.tolist(),
    ),
    "counterfactual": (
        "c.npz",
        lambda k: tiny_counterfactual(k + 1.0),
        lambda d, p: d.save(p),
        lambda p: CounterfactualDataset.load(p).states.tolist(),
    ),
    "policy_checkpoint": (
        "dp.safetensors",
        _dp,
        lambda d, p: d.save(p),
        lambda p: _state(DiffusionPolicy.load(p).model),
    ),
    "bc_checkpoint": (
        "bc.safetensors",
        lambda k: BCPolicy(BCConfig(hidden=(4,), epochs=1), seed=k),
        lambda d, p: d.save(p),
        lambda p: _state(BCPolicy.load(p).net),
    ),
    "glide_classifier": (
        "clf.safetensors",
        lambda k: ModeClassifier(2, 3, hidden=4, seed=k),
        lambda d, p: d.save(p),
        lambda p: _state(ModeClassifier.load(p)),
    ),
}


@pytest.mark.parametrize("name", sorted(WRITERS))
def test_writer_survives_a_kill_and_cleans_up(name: str, tmp_path: Path) -> None:
    filename, make, write, read = WRITERS[name]
    path = tmp_path / filename
    old, new = make(0), make(1)
    mask = os.umask(0o022)
    try:
        write(old, path)
    finally:
        os.umask(mask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644  # not mkstemp's 0o600
    before = read(path)
    kill_mid_write(lambda _: write(new, path))
    assert read(path) == before, "the old version must survive the kill"
    assert len(_temps(tmp_path)) == 1
    write(new, path)
    assert _temps(tmp_path) == [] and read(path) != before


def test_minari_export_killed_leaves_no_dataset_and_the_rerun_succeeds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("minari")
    pytest.importorskip("h5py")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    walk = generate_random_walk("umaze", 80, seed=0, progress=False)
    kill_mid_write(lambda _: to_minari(walk, "steer/walk-v0"))
    assert not (tmp_path / "steer" / "walk-v0").exists()
    assert len(_temps(tmp_path / "steer")) == 1
    data = to_minari(walk, "steer/walk-v0")  # the re-run works and removes the leftover
    episodes = goal_episodes(walk)
    assert data.total_episodes == len(episodes) and data.total_steps == sum(len(e) for e in episodes)
    assert _temps(tmp_path / "steer") == []
    with pytest.raises(FileExistsError, match="already exists"):
        to_minari(walk, "steer/walk-v0")


def test_minari_export_replaces_a_torn_export_of_an_earlier_version(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("minari")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    torn = tmp_path / "walk-v0" / "data"
    torn.mkdir(parents=True)
    (torn / "metadata.json").write_text('{"total_episodes": 0, "author": ["steer-envs (x)"]}')
    walk = generate_random_walk("umaze", 80, seed=0, progress=False)
    assert to_minari(walk, "walk-v0").total_episodes == len(goal_episodes(walk))
    foreign = tmp_path / "theirs-v0" / "data"
    foreign.mkdir(parents=True)
    (foreign / "metadata.json").write_text('{"total_episodes": 0, "author": "someone else"}')
    with pytest.raises(FileExistsError):
        to_minari(walk, "theirs-v0")
    with pytest.raises(ValueError, match="dataset_id"):
        to_minari(walk, "../escape")
