"""Shared by the interop tests: Maze2D random-walk data as a LeRobotDataset, and a LeRobot DP trained on it.

The policy is trained by LeRobot's own ``lerobot-train`` (a subprocess, as a
user runs it) on the dataset :func:`~steer_envs.data.lerobot_dataset.to_lerobot`
exported: a small U-Net (down_dims (32, 64), horizon 32, 2 observation
steps), ``INTEROP_TRAIN_STEPS`` steps on one CPU thread (about 4 minutes).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("lerobot", reason="the interop tests run in scripts/test_interop.sh's environment")

from steer_envs.data.lerobot_dataset import to_lerobot
from steer_envs.data.maze_random_walk import generate_random_walk
from steer_envs.data.trajectories import TrajectoryDataset

#: optimizer steps of the LeRobot DP (batch 64)
TRAIN_STEPS = int(os.environ.get("INTEROP_TRAIN_STEPS", "1000"))


@pytest.fixture(scope="session")
def maze_trajectories() -> TrajectoryDataset:
    """25 000 samples of the Large maze random walk (100 000 raw steps)."""
    return generate_random_walk("large", 100_000, seed=0, progress=False).to_trajectories()


@pytest.fixture(scope="session")
def lerobot_root(tmp_path_factory: pytest.TempPathFactory, maze_trajectories: TrajectoryDataset) -> Path:
    return to_lerobot(maze_trajectories, tmp_path_factory.mktemp("lerobot") / "maze2d_large", repo_id="steer/maze2d")


@pytest.fixture(scope="session")
def trained_lerobot(tmp_path_factory: pytest.TempPathFactory, lerobot_root: Path) -> tuple[Path, list[float]]:
    """``(pretrained_model folder, logged losses)`` of ``lerobot-train`` on the exported dataset."""
    out = tmp_path_factory.mktemp("train") / "dp"
    command = [
        str(Path(sys.executable).with_name("lerobot-train")),
        "--dataset.repo_id=steer/maze2d",
        f"--dataset.root={lerobot_root}",
        "--policy.type=diffusion",
        "--policy.down_dims=[32,64]",
        "--policy.horizon=32",
        "--policy.n_obs_steps=2",
        "--policy.n_action_steps=8",
        "--policy.device=cpu",
        "--policy.push_to_hub=false",
        f"--steps={TRAIN_STEPS}",
        "--batch_size=64",
        f"--save_freq={TRAIN_STEPS}",
        f"--log_freq={max(TRAIN_STEPS // 10, 1)}",
        "--num_workers=0",
        "--wandb.enable=false",
        f"--output_dir={out}",
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "HF_HUB_OFFLINE": "1"}
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=1800)
    log = done.stdout + done.stderr
    assert done.returncode == 0, log[-3000:]
    losses = [float(v) for v in re.findall(r"\bloss:([0-9.]+)", log)]
    return out / "checkpoints" / "last" / "pretrained_model", losses
