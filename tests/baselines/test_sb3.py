"""The SB3 training loop of steer_envs.baselines.sb3: argument checks, env options, run folders."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from steer_envs.baselines.sb3 import Sb3Settings, make_env, run_folder, train_and_evaluate


def test_run_arguments_are_checked(tmp_path: Path) -> None:
    settings = Sb3Settings(timesteps=5, cache=tmp_path)
    with pytest.raises(ValueError, match="does not run on env"):
        train_and_evaluate("steer_envs/SoupScoopDense-v0", "sac-her", 0, settings)
    with pytest.raises(TypeError, match="settings"):
        train_and_evaluate("steer_envs/SoupScoopDense-v0", "sac", 0, {"timesteps": 5})  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="eval_every"):
        Sb3Settings(timesteps=5, eval_every=0)
    with pytest.raises(TypeError, match="checkpoint"):
        Sb3Settings(timesteps=5, checkpoint="yes")  # type: ignore[arg-type]


def test_max_episode_steps_truncates_and_keeps_default_folders(tmp_path: Path) -> None:
    env_id = "steer_envs/Maze2D-UmazeDense-v0"
    short = Sb3Settings(timesteps=100, max_episode_steps=7, cache=tmp_path)
    env = make_env(env_id, "sac", short)
    assert env.spec is not None and env.spec.max_episode_steps == 7
    env.reset(seed=0)
    # a fixed waypoint (the maze's centre) from a seeded start: deterministic, and it never reaches the goal
    # (random actions sometimes did, which ends the episode at the limit's step both ways)
    centre = np.zeros(env.action_space.shape, dtype=env.action_space.dtype)
    for step in range(1, 8):
        _, _, terminated, truncated, _ = env.step(centre)
        assert not terminated and truncated == (step == 7), step
    default = Sb3Settings(timesteps=100, cache=tmp_path)
    assert run_folder(env_id, "sac", 0, short) != run_folder(env_id, "sac", 0, default)
    assert make_env(env_id, "sac", default).spec.max_episode_steps == 150  # UmazeDense's registered limit
    # the folder name hashes the recipe, not the budget: a longer run continues a shorter one
    longer = Sb3Settings(timesteps=10_000, cache=tmp_path)
    assert run_folder(env_id, "sac", 0, longer) == run_folder(env_id, "sac", 0, default)
