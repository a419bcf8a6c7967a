"""ArmPerturbationWrapper: the "+p" schedule (never in the quiet steps, at most N, seeded) and its arguments."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import steer_envs  # noqa: F401 - registers the ids

pytest.importorskip("robosuite")

from steer_envs.wrappers import ArmPerturbationWrapper
from steer_envs.wrappers.arm_perturbation import PUBLIC_CODE_SETTINGS

LIFT = "steer_envs/Lift-v0"


@pytest.fixture(scope="module")
def lift() -> Iterator[gym.Env[Any, Any]]:
    env = gym.make(LIFT)
    yield env
    env.close()


def _run(env: ArmPerturbationWrapper, seed: int, steps: int, gripper: float = -1.0) -> list[dict[str, Any]]:
    """``steps`` steps holding the arm still (gripper command ``gripper``); the infos."""
    _, info = env.reset(seed=seed)
    infos = [info]
    action = np.zeros(7, dtype=np.float32)
    action[6] = gripper
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(action)
        infos.append(info)
        if terminated or truncated:
            break
    return infos


def test_never_in_the_quiet_steps_and_at_most_the_maximum(lift: gym.Env[Any, Any]) -> None:
    env = ArmPerturbationWrapper(lift, probability=0.6, max_perturbations=2, quiet_steps=10, max_episode_steps=24)
    for seed in (0, 1, 2):
        infos = _run(env, seed, 24)
        assert 1 <= len(env.log) <= 2
        for step, kind, value in env.log:
            assert 1 <= step < 24 - 10
            if kind == "gripper":
                assert step + value <= 24 - 10  # the opening is over before the quiet steps
        assert infos[-1]["perturbation_count"] == len(env.log)
        assert not any(i["perturbed"] for i in infos[-10:])


def test_pushes_move_the_eef_and_are_reported(lift: gym.Env[Any, Any]) -> None:
    env = ArmPerturbationWrapper(lift, probability=1.0, max_perturbations=1, gripper_fraction=0.0)
    obs, _ = env.reset(seed=3)
    floor = float(env.arm.object_pos[2])
    obs, _, _, _, info = env.step(np.zeros(7, dtype=np.float32))
    assert info["perturbation"] == "push" and info["perturbed"] and info["perturbation_count"] == 1
    assert info["is_success"] is info["success"]  # the merged step + push info keeps stable-baselines3's key in step
    ((step, kind, delta),) = env.log
    assert (step, kind) == (1, "push") and 0.05 <= float(np.linalg.norm(delta)) <= 0.1
    np.testing.assert_allclose(obs[:3], env.arm.state, atol=1e-6)  # the observation is the pushed state
    assert env.arm.state[2] >= floor - 1e-6
    _, _, _, _, info = env.step(np.zeros(7, dtype=np.float32))
    assert info["perturbation"] is None and not info["perturbed"]


def test_gripper_openings_force_the_gripper_open(lift: gym.Env[Any, Any]) -> None:
    env = ArmPerturbationWrapper(lift, probability=1.0, max_perturbations=1, gripper_fraction=1.0, gripper_steps=(6, 6))
    infos = _run(env, 0, 12, gripper=1.0)
    assert env.log == [(1, "gripper", 6)]
    forced = [bool(i.get("gripper_forced")) for i in infos[1:]]
    assert forced == [False] + [True] * 6 + [False] * 5
    assert infos[1]["perturbation"] == "gripper" and not infos[1]["perturbed"]


def test_drive_pushes_steer_the_action_for_push_steps(lift: gym.Env[Any, Any]) -> None:
    kwargs = {"probability": 1.0, "max_perturbations": 1, "gripper_fraction": 0.0}
    env = ArmPerturbationWrapper(lift, push_style="drive", push_steps=4, **kwargs)
    _, info = env.reset(seed=3)
    start = env.arm.state.copy()
    _, _, _, _, info = env.step(np.zeros(7, dtype=np.float32))
    assert info["perturbation"] == "push" and not info["perturbed"]  # it starts now and drives the next steps
    ((step, kind, target),) = env.log
    assert (step, kind) == (1, "push") and target[2] >= 0.5 and np.all(np.abs(target) <= 1.0)
    np.testing.assert_allclose(env.arm.state, start, atol=0.01)  # nothing was moved on the spot
    before = env.arm.state.copy()
    perturbed = []
    for _ in range(6):
        _, _, _, _, info = env.step(np.zeros(7, dtype=np.float32))
        perturbed.append(info["perturbed"])
    assert perturbed == [True] * 4 + [False] * 2
    moved = env.arm.state - before
    assert float(np.linalg.norm(moved)) > 0.03  # four steps at full speed toward the target (the OSC lags)
    assert float(moved @ (target / np.linalg.norm(target))) > 0.8 * float(np.linalg.norm(moved))  # ... along it


def test_public_code_settings(lift: gym.Env[Any, Any]) -> None:
    env = ArmPerturbationWrapper(lift, **PUBLIC_CODE_SETTINGS)
    counts = []
    for seed in range(4):
        infos = _run(env, seed, 60)
        assert {kind for _, kind, _ in env.log} <= {"push"} and len(env.log) <= 2
        steps = [t for t, _, _ in env.log]
        assert all(b - a >= 10 for a, b in itertools.pairwise(steps))  # one push at a time
        counts.append(sum(i["perturbed"] for i in infos))
    assert max(counts) > 10  # two 10-step pushes in 60 steps happen at probability 0.1 a step


def test_a_seed_replays_the_same_perturbations(lift: gym.Env[Any, Any]) -> None:
    env = ArmPerturbationWrapper(lift, probability=0.3, max_episode_steps=30)
    _run(env, 7, 30)
    first = [(s, k, np.asarray(v).tolist()) for s, k, v in env.log]
    _run(env, 8, 30)
    _run(env, 7, 30)
    again = [(s, k, np.asarray(v).tolist()) for s, k, v in env.log]
    assert first == again and first


def test_after_mode_change_waits_until_the_arm_leaves_its_first_mode(lift: gym.Env[Any, Any]) -> None:
    from steer_envs.data.experts.robosuite import LiftExpert

    kwargs = {"probability": 1.0, "max_perturbations": 1, "gripper_fraction": 1.0, "gripper_steps": (3, 3)}
    env = ArmPerturbationWrapper(lift, after_mode_change=True, **kwargs)
    infos = _run(env, 0, 20)  # the arm held still never leaves reach
    assert env.log == [] and {i["mode"] for i in infos} == {infos[0]["mode"]}
    obs, info = env.reset(seed=0)
    expert = LiftExpert(env.arm)
    expert.reset(obs, info)
    modes = [info["mode"]]
    while not env.log:
        obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
        modes.append(info["mode"])
        assert not (terminated or truncated)
    ((step, kind, _),) = env.log
    changed = next(t for t, m in enumerate(modes) if m != modes[0])
    assert kind == "gripper" and step == changed  # starts on the first step after the change


def test_the_spec_records_the_arguments(lift: gym.Env[Any, Any]) -> None:
    env = ArmPerturbationWrapper(lift, probability=0.2)
    (spec,) = env.spec.additional_wrappers
    assert spec.name == "ArmPerturbationWrapper" and spec.kwargs["probability"] == 0.2
    assert env.max_episode_steps == 200  # the registry's Lift limit


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"probability": 1.5}, ValueError),
        ({"probability": -0.1}, ValueError),
        ({"probability": "0.1"}, TypeError),
        ({"max_perturbations": -1}, ValueError),
        ({"max_perturbations": 2.0}, TypeError),
        ({"quiet_steps": -1}, ValueError),
        ({"push_range": (0.1, 0.05)}, ValueError),
        ({"push_range": (-0.1, 0.1)}, ValueError),
        ({"push_range": 0.1}, TypeError),
        ({"gripper_fraction": 2.0}, ValueError),
        ({"gripper_steps": (0, 5)}, ValueError),
        ({"gripper_steps": (9, 5)}, ValueError),
        ({"gripper_steps": (5.0, 9)}, TypeError),
        ({"max_episode_steps": 0}, ValueError),
        ({"after_mode_change": 1}, TypeError),
        ({"push_style": "shove"}, ValueError),
        ({"push_steps": 0}, ValueError),
    ],
)
def test_bad_arguments_are_refused(lift: gym.Env[Any, Any], kwargs: dict[str, Any], error: type) -> None:
    with pytest.raises(error):
        ArmPerturbationWrapper(lift, **kwargs)


def test_only_robosuite_envs_and_a_step_limit() -> None:
    with pytest.raises(TypeError, match="RobosuiteEnv"):
        ArmPerturbationWrapper(gym.make("steer_envs/SoupScoop-v0"))
    from steer_envs.envs.robosuite.adapter import RobosuiteEnv

    raw = RobosuiteEnv("lift")
    try:
        with pytest.raises(ValueError, match="step limit"):
            ArmPerturbationWrapper(raw)
        assert ArmPerturbationWrapper(raw, max_episode_steps=50).max_episode_steps == 50
    finally:
        raw.close()


def test_pushes_near_the_workspace_edge_stay_inside_it(lift: gym.Env[Any, Any]) -> None:
    env = ArmPerturbationWrapper(
        lift, probability=1.0, max_perturbations=8, gripper_fraction=0.0, push_range=(0.08, 0.1), quiet_steps=0
    )
    space = env.arm.perturb_workspace
    out = np.array([1.0, 0.0, -0.3]) / np.linalg.norm([1.0, 0.0, -0.3])
    edge = np.asarray(space.centre) + (space.reach - 0.02) * out  # 2 cm inside the arm's reach
    for seed in (0, 1):
        env.reset(seed=seed)
        env.arm.perturb(to=edge)
        action = np.zeros(7, dtype=np.float32)
        for _ in range(8):  # every step starts a push; none may be refused
            env.step(action)
            assert space.contains(env.arm.state[:3])
        assert len(env.log) == 8
