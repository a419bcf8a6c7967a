"""Conventions every registered steer-envs environment follows (checked by check_steer_env) and domain extras."""

from __future__ import annotations

import csv

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import steer_envs
from steer_envs.data.demos import rollout_expert
from steer_envs.data.experts import has_expert, make_expert
from steer_envs.envs.registry import entry
from steer_envs.utils.env_checker import check_steer_env

ENV_IDS = steer_envs.env_ids(variants=True)  # the Dense / Goal variants follow every convention too
KINEMATIC_IDS = steer_envs.env_ids(kinematic_only=True, variants=True)


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


class _SuccessLog(gym.Wrapper):
    """Records ``(info["success"], info["is_success"])`` of every reset and step."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.flags: list[tuple[object, object]] = []

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self.flags.append((info["success"], info.get("is_success")))
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.flags.append((info["success"], info.get("is_success")))
        return obs, reward, terminated, truncated, info


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_has_a_scripted_expert_that_succeeds(env_id: str) -> None:
    """The expert reaches the goal; on the way ``is_success`` (stable-baselines3's key) is ``success``."""
    assert has_expert(env_id)
    n = 1 if entry(env_id).entry_point.startswith("steer_envs.envs.robosuite") else 3  # arm episodes cost seconds
    env = _SuccessLog(gym.make(env_id))
    if isinstance(env.observation_space, gym.spaces.Dict):  # goal-conditioned: demos record Box observations only
        expert = make_expert(env)
        for seed in range(n):
            obs, info = env.reset(seed=seed)
            expert.reset(obs, info)
            terminated = truncated = False
            while not (terminated or truncated):
                obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
            assert info["success"] and terminated
        assert all(type(is_success) is bool and is_success == success for success, is_success in env.flags)
        return
    demos = [rollout_expert(env, seed=s) for s in range(n)]
    assert sum(d.success for d in demos) == n
    obs_dim = env.observation_space.shape[0]  # demonstration states are the observations
    for d in demos:
        assert d.states.shape == (len(d), obs_dim)
        assert d.actions.shape[0] == len(d) - 1
        assert entry(env_id).id == d.env_id
    assert all(type(is_success) is bool and is_success == success for success, is_success in env.flags)
    assert sum(success for success, _ in env.flags) == n  # each episode ends on its first success
    env.close()


@pytest.mark.parametrize("env_id", KINEMATIC_IDS)
def test_vector_infos_carry_is_success_like_a_sync_vector_env(env_id: str) -> None:
    """The numpy vector env has the info keys a sync vector env of the single envs has for them."""
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    sync = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync")
    for env in (venv, sync):
        _, infos = env.reset(seed=0)
        assert {"success", "is_success"} <= set(infos)
        np.testing.assert_array_equal(infos["is_success"], infos["success"])
        _, _, _, _, infos = env.step(np.zeros((2, 2), dtype=np.float32))
        assert {"success", "is_success"} <= set(infos)
        assert infos["is_success"].dtype == bool
        np.testing.assert_array_equal(infos["is_success"], infos["success"])
        env.close()
    # the expert's actions, replayed in the vector env, reach success there too
    single = gym.make(env_id)
    expert = make_expert(single)
    obs, info = single.reset(seed=0)
    start = single.unwrapped.state
    expert.reset(obs, info)
    actions = []
    while not info["success"]:
        actions.append(np.asarray(expert.act(obs, info), dtype=np.float32))
        obs, _, _, truncated, info = single.step(actions[-1])
        assert not truncated
    _, infos = venv.reset(options={"state": np.stack([start, start])})
    for action in actions:
        _, _, terminated, _, infos = venv.step(np.stack([action, action]))
        np.testing.assert_array_equal(infos["is_success"], infos["success"])
    assert terminated.all() and infos["is_success"].all()
    venv.close()


def test_stable_baselines3_monitor_reads_is_success(tmp_path) -> None:
    """SB3's Monitor logs ``is_success`` of an expert episode; a DummyVecEnv hands it to ``ep_success_buffer``."""
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    env = Monitor(gym.make("steer_envs/ConvexMode-v0"), str(tmp_path / "run"), info_keywords=("is_success",))
    venv = DummyVecEnv([lambda: env])
    expert = make_expert(env)
    venv.seed(0)
    obs = venv.reset()
    info = venv.reset_infos[0]
    expert.reset(obs[0], info)
    for _ in range(env.spec.max_episode_steps):
        obs, _, dones, infos = venv.step(np.asarray(expert.act(obs[0], info))[None, :])
        info = infos[0]
        if dones[0]:
            break
    assert dones[0] and info["is_success"] is True  # what BaseAlgorithm._update_info_buffer appends
    assert info["episode"]["is_success"] is True
    lines = (tmp_path / "run.monitor.csv").read_text().splitlines()  # a JSON comment, then the CSV
    rows = list(csv.DictReader(lines[1:]))
    assert [row["is_success"] for row in rows] == ["True"]
    venv.close()


def test_make_from_a_fresh_interpreter_registers_the_namespace() -> None:
    import subprocess
    import sys

    code = "import gymnasium as gym, steer_envs; gym.make('steer_envs/PolygonNav-4Mode-v0').reset(seed=0)"
    subprocess.run([sys.executable, "-c", code], check=True)
