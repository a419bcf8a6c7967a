"""The SB3 training loop of steer_envs.baselines.sb3: argument checks, env options, run folders, reset seeds."""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from steer_envs.baselines import sb3
from steer_envs.baselines.sb3 import (
    EVAL_SEED_OFFSET,
    Sb3Settings,
    env_options,
    evaluate_success,
    make_env,
    run_folder,
    train_and_evaluate,
)


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


def test_the_ids_run_as_registered_unless_an_option_is_set() -> None:
    env_id = "steer_envs/PolygonNav-3ModeDense-v0"
    default = Sb3Settings(timesteps=5)
    assert env_options(env_id, default) == {}
    env = make_env(env_id, "sac", default)
    sensors = len(env.unwrapped.task.sensors)  # observed, as the id registers
    assert env.observation_space.shape == (2 + sensors,) and env.action_space.high.tolist() == [1.0, 1.0]
    raw = Sb3Settings(timesteps=5, observe_sensors=False, normalize_actions=False)
    assert env_options(env_id, raw) == {"normalize_actions": False, "observe_sensors": False}
    assert make_env(env_id, "ppo", raw).observation_space.shape == (2,)
    # Maze2D: observe_sensors is not passed (its at_goal bit would contradict HER's relabelled goals)
    assert env_options("steer_envs/Maze2D-UmazeDense-v0", Sb3Settings(timesteps=5, observe_sensors=True)) == {}
    # sac and ppo flatten a goal id's Dict observation for their MlpPolicy
    assert make_env("steer_envs/Maze2D-UmazeGoalDense-v0", "ppo", default).observation_space.shape == (8,)
    with pytest.raises(TypeError, match=r"observe_sensors must be None .* or a bool"):
        Sb3Settings(timesteps=5, observe_sensors="yes")  # type: ignore[arg-type]


def test_seeds_and_evaluation_arguments_are_checked(tmp_path: Path) -> None:
    from steer_envs.envs.polygon_nav import PolygonNavEnv

    settings = Sb3Settings(timesteps=5, cache=tmp_path)
    for bad in (-1, EVAL_SEED_OFFSET):  # training seeds stay below the evaluation seeds
        with pytest.raises(ValueError, match="seed"):
            train_and_evaluate("steer_envs/SoupScoopDense-v0", "sac", bad, settings)
    with pytest.raises(TypeError, match="seed"):
        train_and_evaluate("steer_envs/SoupScoopDense-v0", "sac", "1", settings)  # type: ignore[arg-type]
    env = make_env("steer_envs/SoupScoopDense-v0", "sac", settings)
    with pytest.raises(ValueError, match="episodes"):
        evaluate_success(None, [env], 0)
    with pytest.raises(ValueError, match="at least one env"):
        evaluate_success(None, [], 2)
    with pytest.raises(ValueError, match="step limit"):  # it could run forever
        evaluate_success(None, [PolygonNavEnv(num_modes=3)], 2)


class _Resets(gym.Wrapper):  # type: ignore[type-arg]
    """Records the seed of every reset of the env it wraps (``made`` counts the envs a run made)."""

    log: ClassVar[list[tuple[int, int | None]]] = []
    made = 0

    def __init__(self, env: gym.Env) -> None:  # type: ignore[type-arg]
        super().__init__(env)
        self.index = _Resets.made
        _Resets.made += 1

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        _Resets.log.append((self.index, seed))
        return self.env.reset(seed=seed, options=options)


def test_training_and_evaluation_reset_seeds_are_disjoint(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    made = sb3.make_env
    monkeypatch.setattr(sb3, "make_env", lambda *args: _Resets(made(*args)))
    env_id = "steer_envs/PolygonNav-3ModeDense-v0"
    for timesteps in (40, 60):  # the second run resumes the first at step 40
        _Resets.log.clear()
        _Resets.made = 0
        options = {"eval_every": 20, "eval_episodes": 5, "max_episode_steps": 10, "cache": tmp_path}
        run = train_and_evaluate(env_id, "sac", 3, Sb3Settings(timesteps=timesteps, **options))
        train = [seed for env, seed in _Resets.log if env == 0]  # the run makes its training env first
        evaluation = [seed for env, seed in _Resets.log if env > 0]
        # the training env: its first reset seeded (by SB3's seed=), its later episodes continue its generator
        assert train[0] == (3 if run.resumed_from == 0 else 3 + run.resumed_from) and set(train[1:]) == {None}
        # every evaluation of this run: episode i from EVAL_SEED_OFFSET + i, whatever the run's seed
        evaluations = sum(1 for step, _ in run.curve if step > run.resumed_from or run.resumed_from == 0)
        assert sorted(evaluation) == sorted(list(range(EVAL_SEED_OFFSET, EVAL_SEED_OFFSET + 5)) * evaluations)
    assert run.resumed_from == 40 and [p[0] for p in run.curve] == [0, 20, 40, 60]
