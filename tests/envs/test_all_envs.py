"""Conventions every registered steer-envs environment follows (checked by check_steer_env) and domain extras."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import steer_envs
from steer_envs.data.demos import collect_demonstrations
from steer_envs.data.experts import has_expert
from steer_envs.envs.registry import entry
from steer_envs.utils.env_checker import check_steer_env

ENV_IDS = steer_envs.env_ids()
KINEMATIC_IDS = steer_envs.env_ids(kinematic_only=True)


@pytest.mark.filterwarnings("ignore::UserWarning")  # Gymnasium's advice on non-normalized Box action spaces
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_follows_the_steer_env_contract(env_id: str) -> None:
    """Info keys and types, modes, sensors, interaction kinds, perturb, seeding, Gymnasium's own checker."""
    env = gym.make(env_id)
    check_steer_env(env)
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_stable_baselines3_env_checker_passes(env_id: str) -> None:
    env = gym.make(env_id)
    sb3_check_env(env.unwrapped, warn=False)
    env.close()


@pytest.mark.parametrize("env_id", KINEMATIC_IDS)
def test_kinematic_perturb_clips_to_the_workspace(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=3)
    base = env.unwrapped
    before = base.state
    base.perturb(delta=np.array([0.05, -0.05]))
    np.testing.assert_allclose(base.state, np.clip(before + np.array([0.05, -0.05]), base.model.low, base.model.high))
    base.perturb(to=base.model.high + 1.0)
    np.testing.assert_array_equal(base.state, base.model.high)
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
    n = 1 if entry(env_id).entry_point.startswith("steer_envs.envs.robosuite") else 3  # arm episodes cost seconds
    demos = collect_demonstrations(env_id, n=n, seed=0, only_successful=False)
    assert sum(d.success for d in demos) == n
    obs_dim = gym.make(env_id).observation_space.shape[0]  # demonstration states are the observations
    for d in demos:
        assert d.states.shape == (len(d), obs_dim)
        assert d.actions.shape[0] == len(d) - 1
        assert entry(env_id).id == d.env_id


def test_make_from_a_fresh_interpreter_registers_the_namespace() -> None:
    import subprocess
    import sys

    code = "import gymnasium as gym, steer_envs; gym.make('steer_envs/PolygonNav-4Mode-v0').reset(seed=0)"
    subprocess.run([sys.executable, "-c", code], check=True)
