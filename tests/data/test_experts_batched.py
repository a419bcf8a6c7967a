"""The Cooking and InspectionLine experts act on a vector env's infos (sensors as a dict of (N,) arrays)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.data.experts import make_expert


@pytest.mark.parametrize("env_id", ["steer_envs/Cooking-v0", "steer_envs/InspectionLine-v0"])
def test_batched_expert_matches_single_env_experts(env_id: str) -> None:
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    obs, info = venv.reset(seed=4)
    expert = make_expert(gym.make(env_id))
    batched = expert.act(obs, info)
    assert batched.shape == (3, 2)
    for i in range(3):
        single = gym.make(env_id)
        single_obs, single_info = single.reset(seed=4 + i)
        assert np.allclose(make_expert(single).act(single_obs, single_info), batched[i])
    venv.close()
