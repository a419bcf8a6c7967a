"""The numpy vector entry points against Gymnasium's sync vector env of the same id, key for key.

Every comparison is exact (``np.array_equal`` and equal dtypes): the vector env runs
the single env's row-wise numpy maths on a batch, and each agent draws its starts
from its own generator seeded as the single env's, so no float tolerance is needed.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.envs.kinematic import sensor_columns
from steer_envs.envs.kinematic_vector import Kinematic2DVectorEnv
from steer_envs.envs.registry import ENTRIES

#: every id with a vector entry point, the ``...Dense-v0`` variants included
VECTOR_IDS = [e.id for e in ENTRIES if e.vector_entry_point is not None]
#: the RL options that change the observation / action spaces
OPTIONS: list[dict[str, Any]] = [{}, {"observe_sensors": True, "normalize_actions": True}]
NUM_ENVS = 4
#: a short horizon, so the comparison covers truncation and the autoreset after it
HORIZON = 25


def assert_same(vec: Any, sync: Any, where: str) -> None:
    """Equal values, dtypes and (for dicts) keys in the same order, recursively."""
    if isinstance(sync, dict):
        assert isinstance(vec, dict), f"{where}: a dict in the sync env, {type(vec).__name__} in the vector env"
        assert list(vec) == list(sync), f"{where}: keys {list(vec)} != sync {list(sync)}"
        for key in sync:
            assert_same(vec[key], sync[key], f"{where}[{key!r}]")
        return
    if isinstance(sync, tuple):  # (obs, infos) of reset
        assert isinstance(vec, tuple) and len(vec) == len(sync), f"{where}: {type(vec).__name__} != sync tuple"
        for k, (a, b) in enumerate(zip(vec, sync, strict=True)):
            assert_same(a, b, f"{where}[{k}]")
        return
    vec, sync = np.asarray(vec), np.asarray(sync)
    assert vec.dtype == sync.dtype, f"{where}: dtype {vec.dtype} != sync {sync.dtype}"
    assert vec.shape == sync.shape and np.array_equal(vec, sync), f"{where}: {vec!r} != sync {sync!r}"


def make_pair(env_id: str, **kwargs: Any) -> tuple[gym.vector.VectorEnv, gym.vector.VectorEnv]:
    """The vector-entry-point env and the sync vector env of ``env_id`` with the same arguments."""
    kwargs = {"max_episode_steps": HORIZON, **kwargs}
    vec = gym.make_vec(env_id, num_envs=NUM_ENVS, vectorization_mode="vector_entry_point", **kwargs)
    sync = gym.make_vec(env_id, num_envs=NUM_ENVS, vectorization_mode="sync", **kwargs)
    assert isinstance(vec.unwrapped, Kinematic2DVectorEnv)
    return vec, sync


def random_actions(space: gym.spaces.Box, rng: np.random.Generator) -> np.ndarray:
    """Random actions, some beyond the bounds (the speed clipping is compared too)."""
    return (rng.uniform(-1.5, 1.5, size=(NUM_ENVS, 2)) * space.high[0]).astype(np.float32)


@pytest.mark.parametrize("options", OPTIONS, ids=["default", "sensors+normalized"])
@pytest.mark.parametrize("env_id", VECTOR_IDS)
def test_vector_env_matches_the_sync_vector_env(env_id: str, options: dict[str, Any]) -> None:
    vec, sync = make_pair(env_id, **options)
    assert vec.observation_space == sync.observation_space and vec.action_space == sync.action_space
    assert vec.metadata["autoreset_mode"] == sync.metadata["autoreset_mode"]
    for env in (vec, sync):
        env.action_space.seed(0)
    rng = np.random.default_rng(1)
    ended = 0
    for episode, seed in enumerate((7, None)):  # seeded, then each agent's generator goes on
        assert_same(vec.reset(seed=seed), sync.reset(seed=seed), f"{env_id} reset {episode}")
        for t in range(2 * HORIZON + 5):
            action = random_actions(vec.single_action_space, rng)
            v, s = vec.step(action), sync.step(action)
            for name, a, b in zip(("obs", "reward", "terminated", "truncated", "infos"), v, s, strict=True):
                assert_same(a, b, f"{env_id} episode {episode} step {t} {name}")
            ended += int(np.sum(s[2] | s[3]))
    assert ended >= NUM_ENVS, "the comparison must cover episode ends and autoresets"
    vec.close()
    sync.close()


@pytest.mark.parametrize("env_id", VECTOR_IDS)
def test_agent_i_starts_where_a_single_env_reset_with_seed_plus_i_starts(env_id: str) -> None:
    vec = gym.make_vec(env_id, num_envs=NUM_ENVS, vectorization_mode="vector_entry_point")
    obs, infos = vec.reset(seed=11)
    for i in range(NUM_ENVS):
        single = gym.make(env_id)
        sobs, sinfo = single.reset(seed=11 + i)
        np.testing.assert_array_equal(obs[i], sobs)
        assert infos["mode_name"][i] == sinfo["mode_name"]
        single.close()
    # a list of seeds, as the sync vector env takes it
    listed, _ = vec.reset(seed=[11 + i for i in range(NUM_ENVS)])
    np.testing.assert_array_equal(listed, obs)
    vec.close()


@pytest.mark.parametrize("env_id", ["steer_envs/PolygonNav-3Mode-v0", "steer_envs/SoupScoop-v0"])
def test_render_and_perturb_match_the_sync_vector_env(env_id: str) -> None:
    vec, sync = make_pair(env_id, render_mode="rgb_array", render_size=64)
    assert vec.render_mode == sync.render_mode == "rgb_array"
    vec.reset(seed=3)
    sync.reset(seed=3)
    rng = np.random.default_rng(2)
    mask = np.array([True, False, True, False])
    for t in range(HORIZON + 3):  # through the autoreset at the horizon: trails restart
        action = random_actions(vec.single_action_space, rng)
        vec.step(action)
        sync.step(action)
        if t == 5:  # a push of agents 0 and 2 (the sync env: each sub-env's own perturb)
            to = rng.uniform(-1.0, 1.0, size=(NUM_ENVS, 2))
            vinfos = vec.unwrapped.perturb(to, mask)  # type: ignore[attr-defined]
            for i in np.flatnonzero(mask):
                sinfo = sync.unwrapped.envs[i].unwrapped.perturb(to=to[i])  # type: ignore[attr-defined]
                assert sinfo["perturbed"] and vinfos["mode_name"][i] == sinfo["mode_name"]
            np.testing.assert_array_equal(vinfos["perturbed"], mask)
        frames, expected = vec.render(), sync.render()
        assert isinstance(frames, tuple) and len(frames) == NUM_ENVS
        for i, (frame, want) in enumerate(zip(frames, expected, strict=True)):
            assert frame.dtype == np.uint8 and frame.shape == (64, 64, 3)
            np.testing.assert_array_equal(frame, want, err_msg=f"step {t} agent {i}")
    vec.close()
    sync.close()


def test_render_without_render_mode_gives_nones_like_the_sync_env() -> None:
    vec, sync = make_pair("steer_envs/ConvexMode-v0")
    vec.reset(seed=0)
    sync.reset(seed=0)
    assert vec.render() == sync.render() == (None,) * NUM_ENVS
    vec.close()
    sync.close()


def test_bad_seeds_and_render_modes_are_refused_naming_the_argument() -> None:
    env_id = "steer_envs/ConvexMode-v0"
    vec = gym.make_vec(env_id, num_envs=NUM_ENVS, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="seed"):
        vec.reset(seed=[1, 2])
    with pytest.raises(TypeError, match="seed"):
        vec.reset(seed="1")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="seed"):
        vec.reset(seed=-1)
    with pytest.raises(TypeError, match="seed"):
        vec.reset(seed=[0, 1, 2, 2.5])  # type: ignore[list-item]
    vec.close()
    with pytest.raises(ValueError, match="render_mode"):
        gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", render_mode="human")


def test_sensor_columns_reads_single_and_vector_infos() -> None:
    single = {"r": True, "s": False}
    batched = {"r": np.array([True, False]), "_r": np.ones(2, bool), "s": np.array([False, True])}
    assert sensor_columns(single, ("s", "r")).tolist() == [[False, True]]
    assert sensor_columns(batched, ("r", "s")).tolist() == [[True, False], [False, True]]
    with pytest.raises(TypeError, match="sensors"):
        sensor_columns(np.zeros((2, 2), bool), ("r", "s"))  # type: ignore[arg-type]
