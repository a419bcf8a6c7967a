"""BlockStack-v0: checkers, seeding, cube separation, sensors and modes, skills, violations, success, bad input.

One env for the module (robosuite env creation takes seconds); episodes are a
skill or two long.
"""

from __future__ import annotations

import subprocess
import sys
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from robosuite_helpers import ROBOSUITE_MARKS, module_env, refuse_bad_perturb_and_action
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.data.experts import make_expert
from steer_envs.envs.robosuite.blockstack import (
    CUBE_HALF,
    MIN_SEPARATION,
    SKILLS,
    BlockStackEnv,
    blockstack_task,
    skill_transition,
)
from steer_envs.utils.env_checker import check_steer_env

ENV_ID = "steer_envs/BlockStack-v0"

pytestmark = ROBOSUITE_MARKS


env = module_env(ENV_ID)


def run_skill(env: gym.Env[Any, Any], skills: Any, infos: list[dict[str, Any]], limit: int = 400) -> None:
    """Step the started skill to its end, appending every info."""
    for _ in range(limit):
        if skills.done:
            return
        infos.append(env.step(skills.act())[4])
    raise AssertionError(f"skill {skills.skill} still in phase {skills.phase!r} after {limit} steps")


def stand(base: BlockStackEnv, xyz: dict[int, tuple[float, float, float]]) -> None:
    """Teleport cubes (upright, yaw 0) to table-relative centres and settle the sim."""
    rs = base.rs_env
    for i, (x, y, z) in xyz.items():
        pos = np.array([x, y, base.table_z + z]) + np.r_[rs.table_offset[:2], 0.0]
        rs.sim.data.set_joint_qpos(rs.cubes[i].joints[0], np.r_[pos, 1.0, 0.0, 0.0, 0.0])
    rs.sim.forward()


def test_import_does_not_load_robosuite() -> None:
    code = (
        "import sys, steer_envs, steer_envs.envs.robosuite.blockstack, steer_envs.data.experts.blockstack;"
        "assert 'robosuite' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_checkers_pass(env: gym.Env[Any, Any]) -> None:
    check_steer_env(env, steps=8)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)


def test_seeded_resets_replay_and_keep_cubes_apart(env: gym.Env[Any, Any]) -> None:
    a, _ = env.reset(seed=5)
    b, _ = env.reset(seed=5)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (33,) and a.dtype == np.float32
    base = env.unwrapped
    yaws = set()
    for seed in range(8):
        obs, info = env.reset(seed=seed)
        pos = base.cube_pos
        gaps = np.linalg.norm(pos[:, None, :2] - pos[None, :, :2], axis=-1) + np.eye(4)
        assert gaps.min() >= MIN_SEPARATION, f"seed {seed}: {gaps.min():.3f} m"
        np.testing.assert_allclose(obs[5:8], pos[0], atol=1e-6)  # cube 0 follows the eef (3) and gripper (2)
        assert info["mode_name"] == "free" and all(info["sensors"][f"on_table_{i}"] for i in range(4))
        yaws.add(round(float(base.cube_quat[0, 2]), 3))
    assert len(yaws) == 8
    assert not np.allclose(a, env.reset(seed=6)[0])


def test_task_names_the_skills() -> None:
    task = blockstack_task()
    assert task.modes == ("free", "holding_0", "holding_1", "holding_2", "holding_3")
    assert len(SKILLS) == 20 and skill_transition("pick_3") == ("free", "holding_3")
    assert all(task.is_allowed(*skill_transition(s)) for s in SKILLS)
    assert not task.is_allowed("holding_0", "holding_1")
    with pytest.raises(ValueError, match="skill"):
        skill_transition("stack_all")


def test_pick_and_place_on_a_cube_succeeds_without_violation(env: gym.Env[Any, Any]) -> None:
    from steer_envs.data.experts.blockstack import BlockStackSkills

    base = env.unwrapped
    _, info = env.reset(seed=0)
    skills = BlockStackSkills(base)
    infos = [info]
    skills.pick(1)
    run_skill(env, skills, infos)
    assert skills.succeeded() and infos[-1]["mode_name"] == "holding_1" and infos[-1]["sensors"]["held_1"]
    skills.place_on(0)
    run_skill(env, skills, infos)
    assert skills.succeeded() and base.supports[1] == 0
    last = infos[-1]
    assert last["mode_name"] == "free" and last["sensors"]["on_1_0"] and not last["sensors"]["on_table_1"]
    assert not any(i["constraint_violation"] for i in infos)
    assert all(blockstack_task().mode_of(i["sensors"]) == i["mode_name"] for i in infos)
    modes = [infos[0]["mode_name"]]
    for i in infos[1:]:
        if i["mode_name"] != modes[-1]:
            modes.append(i["mode_name"])
    assert modes == ["free", "holding_1", "free"]
    placed = base.cube_pos[1] - base.cube_pos[0]
    assert np.linalg.norm(placed[:2]) < 0.01 and abs(placed[2] - 2 * CUBE_HALF) < 0.005
    # a tower falling: the placed cube pushed off cube 0 (not picked) is a violation
    stand(base, {1: (0.0, -0.2, CUBE_HALF)})
    assert env.step(np.zeros(7, dtype=np.float32))[4]["constraint_violation"]


def test_dropping_a_held_cube_from_height_is_a_violation(env: gym.Env[Any, Any]) -> None:
    from steer_envs.data.experts.blockstack import BlockStackSkills

    base = env.unwrapped
    _, info = env.reset(seed=1)
    skills = BlockStackSkills(base)
    infos: list[dict[str, Any]] = []
    skills.pick(2)
    run_skill(env, skills, infos)
    assert infos[-1]["mode_name"] == "holding_2" and base.cube_pos[2, 2] > base.table_z + 0.1
    assert not any(i["constraint_violation"] for i in infos)
    flags = []
    for _ in range(40):
        info = env.step(np.array([0, 0, 0, 0, 0, 0, -1], dtype=np.float32))[4]
        flags.append(info["constraint_violation"])
    assert info["mode_name"] == "free" and sum(flags) == 1


def test_success_needs_the_goal_tower(env: gym.Env[Any, Any]) -> None:
    base = env.unwrapped
    tower = {c: (0.1, 0.1, CUBE_HALF * (1 + 2 * k)) for k, c in enumerate((2, 0, 3, 1))}
    for goal, expected in ((None, True), ((2, 0, 3, 1), True), ((0, 1, 2, 3), False)):
        env.reset(seed=0, options={"goal_order": goal})
        stand(base, tower)
        for _ in range(3):
            _, reward, terminated, _, info = env.step(np.zeros(7, dtype=np.float32))
        assert info["success"] is expected and terminated is expected and reward == float(expected)
        assert info["sensors"]["on_table_2"] and info["sensors"]["on_1_3"]
    assert base.goal_order == (0, 1, 2, 3)


def test_registered_expert_is_the_blockstack_expert(env: gym.Env[Any, Any]) -> None:
    from steer_envs.data.experts.blockstack import BlockStackExpert, RandomTowerPlanner

    assert isinstance(make_expert(env), BlockStackExpert)
    plans = []
    for _ in range(2):
        env.reset(seed=3)
        planner = RandomTowerPlanner(seed=4)
        plans.append([planner.next_skill(env.unwrapped).name for _ in range(3)])
    assert plans[0] == plans[1] and plans[0][0].startswith("pick_")


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"goal_order": [0, 1, 2]}, ValueError, "goal_order"),
        ({"goal_order": [0, 1, 1, 2]}, ValueError, "goal_order"),
        ({"goal_order": [0, 1, 2, 4]}, ValueError, "goal_order"),
        ({"goal_order": "0123"}, TypeError, "goal_order"),
        ({"goal_order": [0.0, 1, 2, 3]}, TypeError, "goal_order"),
        ({"render_size": 0}, ValueError, "render_size"),
        ({"render_mode": "human"}, ValueError, "render_mode"),
        ({"fast_render": 1}, TypeError, "fast_render"),
    ],
)
def test_bad_constructor_arguments_are_refused(kwargs: dict[str, Any], error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        BlockStackEnv(**kwargs)


def test_bad_perturb_action_and_options_are_refused(env: gym.Env[Any, Any]) -> None:
    env.reset(seed=0)
    base = env.unwrapped
    before = refuse_bad_perturb_and_action(env)
    with pytest.raises(ValueError, match="goal_order"):
        env.reset(options={"goal_order": [3, 3, 1, 0]})
    with pytest.raises(ValueError, match="options"):
        env.reset(options={"goal": [0, 1, 2, 3]})
    np.testing.assert_array_equal(base.state, before)
    info = base.perturb(delta=[0.0, 0.0, 0.03])
    assert info["perturbed"] and not info["constraint_violation"]
    np.testing.assert_allclose(base.state, before + np.array([0.0, 0.0, 0.03]), atol=1e-6)


def test_rgb_array_render() -> None:
    env = gym.make(ENV_ID, render_mode="rgb_array", render_size=64, fast_render=True)
    env.reset(seed=0)
    frame = env.render()
    env.close()
    assert frame.shape == (64, 64, 3) and frame.dtype == np.uint8 and frame.std() > 0
