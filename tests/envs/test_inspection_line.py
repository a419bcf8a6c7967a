"""InspectionLine-v0: checkers, the line physics (entry, drop, release, uninspected release), the expert."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from kinematic_helpers import walk
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import steer_envs  # noqa: F401
from steer_envs.data.demos import collect_demonstrations
from steer_envs.envs.inspection_line import INSPECTION_TASK, InspectionLineEnv
from steer_envs.utils.env_checker import check_steer_env

ENV_ID = "steer_envs/InspectionLine-v0"


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_checkers_pass() -> None:
    env = gym.make(ENV_ID)
    check_steer_env(env)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)
    env.close()


def test_inspection_then_release_succeeds() -> None:
    env = InspectionLineEnv()
    env.reset(options={"state": np.array([-6.0, -6.0])})
    infos = walk(env, (-4.5, 0.0), (5.0, 0.0))
    modes = [i["mode_name"] for i in infos]
    assert modes[-1] == "released" and infos[-1]["success"]
    assert "inspect" in modes and not any(i["constraint_violation"] for i in infos)


def test_release_without_inspection_is_a_violation_not_a_success() -> None:
    env = InspectionLineEnv()
    env.reset(options={"state": np.array([5.0, -6.0])})
    infos = walk(env, (5.5, 0.0))
    assert not infos[-1]["success"] and infos[-1]["mode_name"] == "reach_entry" and infos[-1]["sensors"]["r"]
    assert sum(i["constraint_violation"] for i in infos) == 1


def test_leaving_the_line_drops_the_object_and_entering_mid_track_does_not_count() -> None:
    env = InspectionLineEnv()
    env.reset(options={"state": np.array([0.0, 3.0])})
    assert walk(env, (0.0, 0.0))[-1]["mode_name"] == "reach_entry"  # onto the track, not at the entry
    env.reset(options={"state": np.array([-4.5, 0.0])})
    assert env.perturb(to=[-4.5, 0.0])["mode_name"] == "inspect"
    infos = walk(env, (0.0, 0.0), (0.0, 2.0))
    assert infos[-1]["mode_name"] == "reach_entry" and any(i["constraint_violation"] for i in infos)
    assert INSPECTION_TASK.mode_of(infos[-1]["sensors"]) == infos[-1]["mode_name"]


def test_expert_demonstrations_visit_the_modes_in_order() -> None:
    for demo in collect_demonstrations(ENV_ID, 2, seed=0):
        assert demo.success and list(dict.fromkeys(demo.modes.tolist())) == [0, 1, 2]
