"""ArmScoop-v0: the beads' physics (load, spill, dip, deliver), velocity tracking on the arm, pushes, bad input."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import steer_envs  # noqa: F401
from steer_envs.data.experts.arm_scoop import ArmScoopExpert
from steer_envs.envs.robosuite.arm_scoop import (
    BOWL_X,
    PITCH_HIGH,
    SOUP_SURFACE,
    SOUP_Y,
    TARGET_Y,
    WORKSPACE,
    ArmScoopEnv,
    arm_scoop_task,
)
from steer_envs.envs.soup_scoop import SOUP_TASK
from steer_envs.utils.env_checker import check_steer_env

IN_SOUP = np.array([SOUP_Y, SOUP_SURFACE - 0.03, 0.1])


@pytest.fixture(scope="module")
def env() -> Iterator[Any]:
    e = gym.make("steer_envs/ArmScoop-v0")
    yield e
    e.close()


def _lift(base: ArmScoopEnv, pitch_rate: float = 0.0, steps: int = 12) -> dict[str, Any]:
    info: dict[str, Any] = {}
    for _ in range(steps):
        _, _, _, _, info = base.step(np.array([0.0, 0.15, pitch_rate], dtype=np.float32))
    return info


def test_task_is_the_soup_scoop_task_of_the_2d_env() -> None:
    task = arm_scoop_task()
    assert task.name == "ArmScoop" and task.modes == SOUP_TASK.modes and task.labels == SOUP_TASK.labels
    assert task.sensor_modes == SOUP_TASK.sensor_modes and task.transitions == SOUP_TASK.transitions


def test_contract_and_start_state(env: Any) -> None:
    check_steer_env(env)
    obs, info = env.reset(seed=3)
    base = env.unwrapped
    np.testing.assert_allclose(obs, base.state, atol=1e-6)
    assert info["mode_name"] == "a" and not info["sensors"]["s"] and abs(base.eef_pos[0] - BOWL_X) < 1e-6


def test_scooping_level_loads_beads_and_tilting_spills_them(env: Any) -> None:
    base = env.unwrapped
    env.reset(seed=0)
    info = base.perturb(to=IN_SOUP)
    assert info["sensors"]["r"] and info["mode_name"] == "b" and not info["constraint_violation"]
    info = _lift(base)
    assert base.state[1] > SOUP_SURFACE and info["mode_name"] == "c" and base.beads_on_spoon
    assert not info["constraint_violation"]
    for _ in range(40):  # tip the spoon back past the holding range: the beads fall off
        _, _, _, _, info = env.step(np.array([0.0, 0.0, 2.0], dtype=np.float32))
        if info["mode_name"] != "c":
            break
    assert info["mode_name"] == "a" and info["constraint_violation"] and base.state[2] > PITCH_HIGH


def test_lifting_out_tipped_down_scoops_nothing(env: Any) -> None:
    base = env.unwrapped
    env.reset(seed=0)
    base.perturb(to=np.array([SOUP_Y, SOUP_SURFACE - 0.02, -0.9]))
    info = _lift(base)
    assert base.state[1] > SOUP_SURFACE and info["mode_name"] == "a" and not base.beads_on_spoon


def test_dipping_back_into_the_soup_returns_the_beads_and_a_push_never_is_a_violation(env: Any) -> None:
    base = env.unwrapped
    env.reset(seed=0)
    base.perturb(to=IN_SOUP)
    _lift(base)
    assert base.beads_on_spoon
    info = base.perturb(delta=np.array([0.0, -0.06, 0.0]))  # pushed back into the soup
    assert info["mode_name"] == "b" and info["perturbed"] and not info["constraint_violation"]
    _lift(base)
    info = base.perturb(delta=np.array([0.0, 0.0, 1.0]))  # a push tilting the spoon: spilled, not the policy's fault
    assert info["mode_name"] == "a" and not info["constraint_violation"]


def test_carrying_the_beads_above_the_target_delivers_them(env: Any) -> None:
    base = env.unwrapped
    env.reset(seed=0)
    base.perturb(to=IN_SOUP)
    _lift(base)
    base.perturb(to=np.array([TARGET_Y - 0.08, SOUP_SURFACE + 0.05, 0.0]))
    for _ in range(40):
        _, reward, terminated, _, info = env.step(np.array([0.15, 0.0, 0.0], dtype=np.float32))
        if terminated:
            break
    assert terminated and info["success"] and reward == 1.0 and info["mode_name"] == "d"
    assert info["sensors"] == {"r": False, "s": True, "t": True}


def test_velocity_commands_move_the_spoon_and_hold_x(env: Any) -> None:
    base = env.unwrapped
    env.reset(seed=0, options={"state": [-0.25, 0.98, 0.0]})
    start = base.state
    for _ in range(20):  # 1 s at (0.1 m/s, -0.05 m/s, 0.5 rad/s)
        env.step(np.array([0.1, -0.05, 0.5], dtype=np.float32))
    moved = base.state - start
    assert np.all(np.abs(moved - [0.1, -0.05, 0.5]) <= [0.02, 0.02, 0.1]), moved  # the OSC lags a step or two
    assert abs(base.eef_pos[0] - BOWL_X) < 0.005


def test_the_raw_sim_takes_the_velocity_as_a_delta_osc_command(env: Any) -> None:
    """robosuite's own step accepts the env's 3-D action (the smoke suite times raw steps with it)."""
    base = env.unwrapped
    env.reset(seed=0)
    y0 = base.state[0]
    for _ in range(5):
        base.rs_env.step(np.array([0.2, 0.0, 0.0]))
    assert base.state[0] > y0 + 0.005


def test_pushes_are_exact_and_clipped_to_the_workspace(env: Any) -> None:
    base = env.unwrapped
    env.reset(seed=1)
    base.perturb(to=np.array([0.0, 0.95, 0.3]))
    np.testing.assert_allclose(base.state, [0.0, 0.95, 0.3], atol=1e-7)
    base.perturb(to=np.array([5.0, -5.0, 9.0]))
    np.testing.assert_allclose(base.state, [WORKSPACE[1][0], WORKSPACE[0][1], WORKSPACE[1][2]], atol=1e-6)


def test_expert_scoops_and_delivers_from_a_reset(env: Any) -> None:
    expert = ArmScoopExpert(env.unwrapped)
    obs, info = env.reset(seed=7)
    modes = [info["mode_name"]]
    for _ in range(300):
        obs, _, terminated, _, info = env.step(expert.act(obs, info))
        if info["mode_name"] != modes[-1]:
            modes.append(info["mode_name"])
        if terminated:
            break
    assert info["success"] and modes == ["a", "b", "c", "d"]


def test_bad_input_names_the_argument(env: Any) -> None:
    base = env.unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match="delta"):
        base.perturb(delta=np.zeros(2))
    with pytest.raises(ValueError, match="exactly one"):
        base.perturb()
    with pytest.raises(ValueError, match="state"):
        env.reset(options={"state": [0.0, np.nan, 0.0]})
    with pytest.raises(ValueError, match="options"):
        env.reset(options={"goal": 1})
    with pytest.raises(TypeError, match="ArmScoopEnv"):
        ArmScoopExpert(gym.make("steer_envs/SoupScoop-v0").unwrapped)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="render_size"):
        ArmScoopEnv(render_size=4)


def test_render_shows_the_scene() -> None:
    env = gym.make("steer_envs/ArmScoop-v0", render_mode="rgb_array", render_size=64, fast_render=True)
    env.reset(seed=0)
    frame = np.asarray(env.render())
    assert frame.shape == (64, 64, 3) and frame.dtype == np.uint8 and len(np.unique(frame.reshape(-1, 3), axis=0)) > 20
    env.close()
