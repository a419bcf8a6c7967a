"""Lift's variants: the thesis text's (unchanged) and the public GLiDE fork's (success 0.40 m up, free/lifting/success).

One env per variant for the module; a public-code demo takes about a second.
"""

from __future__ import annotations

import itertools
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from robosuite_helpers import ROBOSUITE_MARKS, module_env

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.data import robosuite_replays as rr
from steer_envs.data.experts import make_expert
from steer_envs.data.experts.robosuite import LiftExpert
from steer_envs.envs.robosuite.tasks import (
    LIFT_VARIANTS,
    PUBLIC_CODE_LIFT_HEIGHT,
    TASKS,
    VARIANTS,
    task_spec,
    task_variant,
)

pytestmark = ROBOSUITE_MARKS


public = module_env("steer_envs.data.robosuite_replays:make_arm_env", "lift", "public_code")
thesis = module_env("steer_envs.data.robosuite_replays:make_arm_env", "lift")


def runs(demo: rr.ArmTrajectory, names: tuple[str, ...]) -> list[tuple[str, int]]:
    """The demo's modes as (name, steps) runs."""
    return [(names[k], len(list(g))) for k, g in itertools.groupby(demo.modes.tolist())]


def test_the_variants_are_data_and_the_thesis_one_is_robosuites() -> None:
    assert LIFT_VARIANTS == tuple(VARIANTS["lift"]) == ("thesis", "public_code")
    assert task_variant("lift") is TASKS["lift"] and task_variant("lift").success_height is None
    public = task_variant("lift", "public_code")
    assert public.modes == ("free", "lifting", "success") and public.success_height == PUBLIC_CODE_LIFT_HEIGHT == 0.4
    spec = task_spec(public)
    assert spec.name == "robosuite-lift-public_code" and task_spec(TASKS["lift"]).name == "robosuite-lift"
    assert spec.mode_of({"held": True, "falling": False, "at_height": False}) == "lifting"
    assert spec.mode_of({"held": True, "falling": True, "at_height": False}) == "free"  # dropped
    assert spec.mode_of({"held": False, "falling": False, "at_height": True}) == "success"
    assert spec.is_allowed("success", "lifting") and not spec.is_allowed("lifting", "free")
    assert not spec.is_allowed("free", "success")  # skipping the lift
    with pytest.raises(ValueError, match="variant"):
        task_variant("can", "public_code")
    with pytest.raises(ValueError, match="task"):
        task_variant("stack")


@pytest.mark.parametrize("seed", [0, 1])
def test_the_expert_lifts_the_cube_to_the_public_height_through_the_forks_modes(
    public: rr.RobosuiteEnv, seed: int
) -> None:
    demo = rr.record_demo(public, seed)
    assert demo.success and demo.violation_step == -1
    assert [name for name, _ in runs(demo, public.task.modes)] == ["free", "lifting", "success"]
    lifting = float(np.mean(demo.modes == 1))
    assert 0.4 <= lifting <= 0.6, lifting  # about half the demo, as in the forks' extended demos
    table = float(public.rs_env.table_offset[2])
    cube_z = demo.features[:, 2]  # block_pos
    s = demo.success_from
    assert cube_z[s] > table + 0.40 and cube_z[s - 1] <= table + 0.40 + 0.01
    assert cube_z[: s - 1].max() < table + 0.40  # robosuite's 4 cm (the thesis success) is passed long before


def test_the_public_expert_is_seeded_and_its_walk_depends_on_the_seed(public: rr.RobosuiteEnv) -> None:
    first, again = rr.record_demo(public, 2), rr.record_demo(public, 2)
    np.testing.assert_array_equal(first.obs, again.obs)
    ends = []
    for expert_seed in (0, 1):
        expert = LiftExpert(public, seed=expert_seed)
        obs, info = public.reset(seed=2)
        expert.reset(obs, info)
        for _ in range(75):  # about 25 steps into the raise
            obs, _, _, _, info = public.step(expert.act(obs, info))
        assert expert.phase == "raise"
        ends.append(public.state[:2].copy())
    assert not np.allclose(ends[0], ends[1], atol=1e-4)  # the xy walk is the expert's seed's


def test_the_thesis_variant_is_unchanged(thesis: rr.RobosuiteEnv) -> None:
    """Lift seed 0 as the scripted expert recorded it before the variants existed (52 steps to success)."""
    demo = rr.record_demo(thesis, 0)
    assert demo.success and demo.success_from == 52 and len(demo) == 63
    assert runs(demo, thesis.task.modes) == [("reach", 47), ("lift", 5), ("reach_height", 11)]


def test_the_variant_is_an_env_option_with_its_own_reward(thesis: rr.RobosuiteEnv) -> None:
    env: Any = gym.make("steer_envs/Lift-v0", variant="public_code")
    try:
        assert env.unwrapped.variant == "public_code" and env.unwrapped.task.modes == ("free", "lifting", "success")
        expert = make_expert(env)
        obs, info = env.reset(seed=0)
        expert.reset(obs, info)
        rewards, thesis_success_seen = [], False
        for _ in range(200):
            obs, reward, terminated, truncated, info = env.step(expert.act(obs, info))
            rewards.append(reward)
            thesis_success_seen |= bool(env.unwrapped.rs_env._check_success())  # robosuite's 4 cm
            if terminated or truncated:
                break
        assert terminated and info["success"] and info["mode_name"] == "success"
        assert rewards[-1] == 1.0 and sum(rewards) == 1.0 and thesis_success_seen  # no reward at 4 cm
    finally:
        env.close()
    with pytest.raises(ValueError, match="variant"):
        gym.make("steer_envs/Can-v0", variant="public_code")
    with pytest.raises(ValueError, match="variant"):
        rr.make_arm_env("lift", "fork")
    assert thesis.variant == "thesis" and thesis.task.modes == ("reach", "lift", "reach_height")


def test_dropping_the_cube_is_a_violation_in_the_public_variant(public: rr.RobosuiteEnv) -> None:
    expert = LiftExpert(public, seed=0)
    obs, info = public.reset(seed=0)
    expert.reset(obs, info)
    while info["mode_name"] != "lifting" or public.object_pos[2] < 0.9:
        obs, _, _, _, info = public.step(expert.act(obs, info))
    modes, violated = [], False
    for _ in range(10):
        action = np.zeros(7)
        action[6] = -1.0  # open: the cube falls
        obs, _, _, _, info = public.step(action)
        modes.append(info["mode_name"])
        violated |= info["constraint_violation"]
    assert "free" in modes and violated
