"""The human-like demonstrator (a sensitivity study): seeded variation around the scripted experts, still successful."""

from __future__ import annotations

import numpy as np
import pytest
from robosuite_helpers import ROBOSUITE_MARKS, module_env

from steer_envs.data import robosuite_replays as rr
from steer_envs.data.experts.human_like import (
    CALIBRATED_SPEED,
    PH_MEAN_LENGTH,
    HumanLikeDemonstrator,
    HumanLikeSettings,
)
from steer_envs.data.experts.robosuite import LiftExpert

pytestmark = ROBOSUITE_MARKS


lift = module_env("steer_envs.data.robosuite_replays:make_arm_env", "lift")


@pytest.mark.parametrize(
    ("bad", "name"),
    [
        ({"idle_steps": (5, 2)}, "idle_steps"),
        ({"idle_steps": 5}, "idle_steps"),
        ({"hesitation_steps": (0, 3)}, "hesitation_steps"),
        ({"dwell_steps": (1.5, 3)}, "dwell_steps"),
        ({"overshoot": (0.03, 0.01)}, "overshoot"),
        ({"waypoint_tolerance": (0.0, 1.0)}, "waypoint_tolerance"),
        ({"speed": 0.0}, "speed"),
        ({"curve": float("nan")}, "curve"),
        ({"hesitation_rate": 1.5}, "hesitation_rate"),
        ({"idle_mean": 30.0}, "idle_mean"),
    ],
)
def test_bad_settings_are_refused_by_name(bad: dict, name: str) -> None:
    with pytest.raises((TypeError, ValueError), match=name):
        HumanLikeSettings(**bad)


def test_the_calibration_covers_every_task() -> None:
    assert set(CALIBRATED_SPEED) == set(PH_MEAN_LENGTH) == {"lift", "can", "square"}
    assert round(PH_MEAN_LENGTH["square"]) == 151  # 30,154 frames over 200 demos


def test_bad_arguments_are_refused(lift: rr.RobosuiteEnv) -> None:
    with pytest.raises(TypeError, match="settings"):
        HumanLikeDemonstrator(LiftExpert(lift), settings={"speed": 2.0})  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="seed"):
        HumanLikeDemonstrator(LiftExpert(lift), seed=-1)
    with pytest.raises(ValueError, match="demos"):
        rr.record_demo(lift, 0, demos="teleop")
    with pytest.raises(TypeError, match="env"):
        rr.demonstrator(object(), 0)  # type: ignore[arg-type]


def test_lift_demos_start_idle_vary_with_the_seed_and_replay(lift: rr.RobosuiteEnv) -> None:
    scripted = rr.record_demo(lift, 0)
    demos = [rr.record_demo(lift, seed, demos="human_like") for seed in (0, 1, 0)]
    assert all(d.success and d.violation_step == -1 for d in demos)
    np.testing.assert_array_equal(demos[0].actions, demos[2].actions)  # seeded
    assert demos[0].actions.shape != demos[1].actions.shape or not np.allclose(demos[0].actions, demos[1].actions)
    assert demos[0].actions.shape != scripted.actions.shape or not np.allclose(demos[0].actions, scripted.actions)
    dem = rr.demonstrator(lift, 0, "human_like")
    dem.reset(*lift.reset(seed=0))  # the episode's draws: demos[0]'s
    assert 3 <= dem.idle <= 20
    idle = demos[0].actions[: dem.idle]
    assert np.all(idle[:, :6] == 0) and np.all(idle[:, 6] == -1)  # no motion, gripper "open"
    assert np.any(demos[0].actions[dem.idle, :3] != 0)  # then it moves
    assert dem.expert.gain == LiftExpert.gain  # the speed is set per step and put back


@pytest.mark.parametrize(("task", "seed"), [("can", 1), ("square", 3)])
def test_can_and_square_demos_succeed(task: str, seed: int) -> None:
    env = rr.make_arm_env(task)
    try:
        demo = rr.record_demo(env, seed, demos="human_like")
    finally:
        env.close()
    assert demo.success and demo.violation_step == -1
    assert sorted(set(demo.modes.tolist())) == list(range(len(env.task.modes)))  # every mode, as the expert's


def test_the_public_code_lift_keeps_its_scripted_raise() -> None:
    env = rr.make_arm_env("lift", "public_code")
    try:
        dem = rr.demonstrator(env, 4, "human_like")
        obs, info = env.reset(seed=4)
        dem.reset(obs, info)
        raise_actions, modes = [], [info["mode_name"]]
        for _ in range(200):
            action = dem.act(obs, info)
            if dem.expert.phase == "raise" and not dem.paused:
                raise_actions.append(action)
            obs, _, done, _, info = env.step(action)
            modes.append(info["mode_name"])
            if done:
                break
    finally:
        env.close()
    assert info["success"] and len(raise_actions) > 30
    assert [m for i, m in enumerate(modes) if i == 0 or m != modes[i - 1]] == ["free", "lifting", "success"]
    assert all(np.all(np.abs(a[:3]) <= 1.0) and a[6] == 1.0 for a in raise_actions)


@pytest.mark.slow
@pytest.mark.parametrize("task", ["lift", "can", "square"])
def test_ten_demos_succeed_at_about_the_proficient_human_length(task: str) -> None:
    env = rr.make_arm_env(task)
    try:
        demos = [rr.record_demo(env, seed, demos="human_like", max_steps=500) for seed in range(10)]
    finally:
        env.close()
    assert sum(d.success for d in demos) >= 9
    median = float(np.median([len(d) for d in demos]))  # Square's long tail is the expert's own retries
    assert 0.8 * PH_MEAN_LENGTH[task] <= median <= 1.5 * PH_MEAN_LENGTH[task], median
