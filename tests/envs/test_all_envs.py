"""Conventions every registered steer-envs environment follows (ARCHITECTURE.md)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import steer_envs
from steer_envs.data.demos import collect_demonstrations
from steer_envs.data.experts import has_expert
from steer_envs.envs.registry import entry

ENV_IDS = steer_envs.env_ids()
KINEMATIC_IDS = steer_envs.env_ids(kinematic_only=True)


def _rollout(env_id: str, seed: int, steps: int = 50) -> tuple[np.ndarray, list[dict]]:
    env = gym.make(env_id)
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    observations, infos = [obs], [info]
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(env.action_space.sample())
        observations.append(obs)
        infos.append(info)
        if terminated or truncated:
            obs, info = env.reset()
    env.close()
    return np.asarray(observations), infos


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_and_sb3_env_checkers_pass(env_id: str) -> None:
    env = gym.make(env_id)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_same_seed_gives_identical_trajectories(env_id: str) -> None:
    obs_a, infos_a = _rollout(env_id, seed=11)
    obs_b, infos_b = _rollout(env_id, seed=11)
    np.testing.assert_array_equal(obs_a, obs_b)
    assert [i["mode"] for i in infos_a] == [i["mode"] for i in infos_b]
    obs_c, _ = _rollout(env_id, seed=12)
    assert not np.array_equal(obs_a, obs_c)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_info_carries_mode_sensors_success_and_violation(env_id: str) -> None:
    env = gym.make(env_id)
    task = env.unwrapped.task
    _, info = env.reset(seed=0)
    _, _, _, _, step_info = env.step(env.action_space.sample())
    for i in (info, step_info):
        assert isinstance(i["mode"], int) and 0 <= i["mode"] < task.num_modes
        assert set(i["sensors"]) == set(task.sensors)
        assert all(isinstance(v, bool) for v in i["sensors"].values())
        assert isinstance(i["success"], bool)
        assert isinstance(i["constraint_violation"], bool)
    assert set(env.unwrapped.interaction_kinds) <= {"point", "sketch", "nudge"}
    env.close()


@pytest.mark.parametrize("env_id", KINEMATIC_IDS)
def test_perturb_moves_the_state_and_rejects_bad_arguments(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=3)
    base = env.unwrapped
    before = base.state
    info = base.perturb(delta=np.array([0.05, -0.05]))
    assert info["perturbed"] is True
    np.testing.assert_allclose(base.state, np.clip(before + np.array([0.05, -0.05]), base.model.low, base.model.high))
    with pytest.raises(ValueError, match="delta"):
        base.perturb(delta=np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="shape"):
        base.perturb(delta=np.zeros(3))
    with pytest.raises(ValueError, match="exactly one"):
        base.perturb()
    with pytest.raises(ValueError, match="exactly one"):
        base.perturb(delta=np.zeros(2), to=np.zeros(2))
    with pytest.raises(TypeError, match="to"):
        base.perturb(to="left")
    with pytest.raises(ValueError, match="action"):
        env.step(np.zeros(3, dtype=np.float32))
    env.close()


@pytest.mark.parametrize("env_id", KINEMATIC_IDS)
def test_rgb_render_draws_the_scene(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) >= 3  # regions + agent at least
    env.close()


@pytest.mark.parametrize("env_id", KINEMATIC_IDS)
def test_vector_path_matches_single_envs(env_id: str) -> None:
    num = 4
    venv = gym.make_vec(env_id, num_envs=num, vectorization_mode="vector_entry_point")
    venv.reset(seed=5)
    singles = [gym.make(env_id) for _ in range(num)]
    for k, env in enumerate(singles):
        env.reset(options={"state": venv.unwrapped._pos[k]})  # the exact float64 start
    rng = np.random.default_rng(0)
    finished = np.zeros(num, dtype=bool)
    for _ in range(20):
        actions = (rng.uniform(-1, 1, size=(num, 2)) * singles[0].unwrapped.max_speed).astype(np.float32)
        vobs, _, vterm, _, vinfo = venv.step(actions)
        for k, env in enumerate(singles):
            sobs, _, sterm, _, sinfo = env.step(actions[k])
            if finished[k]:
                continue
            finished[k] = vterm[k]
            assert vterm[k] == sterm
            np.testing.assert_allclose(vobs[k], sobs, atol=1e-5)
            assert vinfo["mode"][k] == sinfo["mode"]
    venv.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_has_a_scripted_expert_that_succeeds(env_id: str) -> None:
    assert has_expert(env_id)
    demos = collect_demonstrations(env_id, n=3, seed=0, only_successful=False)
    assert sum(d.success for d in demos) == 3
    for d in demos:
        assert d.states.shape == (len(d), 2)
        assert d.actions.shape[0] == len(d) - 1
        assert entry(env_id).id == d.env_id


def test_make_from_a_fresh_interpreter_registers_the_namespace() -> None:
    import subprocess
    import sys

    code = "import gymnasium as gym, steer_envs; gym.make('steer_envs/PolygonNav-4Mode-v0').reset(seed=0)"
    subprocess.run([sys.executable, "-c", code], check=True)
