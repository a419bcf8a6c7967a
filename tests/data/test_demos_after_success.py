"""Opt-in demos that go on past the goal (GLiDE on PolygonNav needs the goal polygon's interior)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import steer_envs  # noqa: F401  (registers the envs)
from steer_envs.core.validation import BoundExceeded
from steer_envs.data.demos import collect_demonstrations, rollout_expert
from steer_envs.data.experts import make_expert

ENV_ID = "steer_envs/PolygonNav-5Mode-v0"


def _pair(seed: int = 0) -> tuple:
    plain = collect_demonstrations(ENV_ID, 1, seed=seed, layout_seed=1)[0]
    longer = collect_demonstrations(
        ENV_ID, 1, seed=seed, layout_seed=1, steps_after_success=40, expert_kwargs={"final_target": "centroid"}
    )[0]
    return plain, longer


def test_default_demo_ends_on_first_success() -> None:
    plain, _ = _pair()
    assert plain.success
    assert plain.modes[-1] == 4 and np.all(plain.modes[:-1] != 4)


def test_demo_goes_on_to_the_goal_centroid_and_keeps_its_prefix() -> None:
    plain, longer = _pair()
    n = len(plain)
    assert longer.success
    np.testing.assert_allclose(longer.states[:n], plain.states)  # the same demo up to the first success
    assert len(longer) > n
    assert np.all(longer.modes[n - 1 :] == 4)  # it stays in the goal polygon
    env = gym.make(ENV_ID, layout_seed=1)
    centroid = np.asarray(env.unwrapped.model.polygons[-1].centroid.coords[0])
    env.close()
    assert np.linalg.norm(longer.states[-1] - centroid) < 1e-6  # reached and stopped there (< 40 steps)
    assert longer.actions.shape == (len(longer) - 1, 2)
    assert np.all(np.linalg.norm(np.diff(longer.states, axis=0), axis=1) <= 0.1 + 1e-6)


def test_steps_after_success_caps_the_tail() -> None:
    env = gym.make(ENV_ID, layout_seed=1)
    try:
        plain = rollout_expert(env, 0)
        capped = rollout_expert(env, 0, steps_after_success=3, expert_kwargs={"final_target": "centroid"})
        # the default expert stops just behind the goal's entry edge: the tail ends early there
        still = rollout_expert(env, 0, steps_after_success=20)
    finally:
        env.close()
    assert len(capped) == len(plain) + 3
    assert len(plain) <= len(still) < len(plain) + 20
    assert np.all(still.modes[len(plain) - 1 :] == 4)


@pytest.mark.parametrize("bad", [-1, 1.5, True])
def test_steps_after_success_is_validated(bad: object) -> None:
    env = gym.make(ENV_ID, layout_seed=1)
    try:
        with pytest.raises((TypeError, ValueError), match="steps_after_success"):
            rollout_expert(env, 0, steps_after_success=bad)  # type: ignore[arg-type]
    finally:
        env.close()


def test_expert_rejects_unknown_final_target() -> None:
    env = gym.make(ENV_ID, layout_seed=1)
    try:
        with pytest.raises(ValueError, match="final_target"):
            make_expert(env, final_target="middle")
    finally:
        env.close()


# ------------------------------------------------------------------ bounds and arguments
def test_an_expert_that_never_succeeds_hits_a_named_bound() -> None:
    with pytest.raises(BoundExceeded, match=r"succeeded only 1 times in 20 episodes.*max_steps=3"):
        collect_demonstrations("steer_envs/ConvexMode-v0", 2, seed=0, max_episode_steps=3)  # 3 steps are too few
    env = gym.make("steer_envs/ConvexMode-v0").unwrapped  # no step limit: the default bound applies
    demo = rollout_expert(env, 0, max_steps=4)
    assert not demo.success and len(demo) == 5  # the documented "timed out" demo
    at_goal = rollout_expert(env, 10)  # seed 10 starts inside the success radius: a demo of one state
    assert at_goal.success and at_goal.states.shape == (1, 2) and at_goal.actions.shape == (0, 2)


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"max_steps": float("inf")}, TypeError),  # would never stop for an expert that never succeeds
        ({"max_steps": "100"}, TypeError),
        ({"max_steps": 0}, ValueError),
        ({"seed": "0"}, TypeError),
        ({"expert_kwargs": ["final_target"]}, TypeError),
    ],
)
def test_rollout_expert_arguments_are_validated(kwargs: dict, error: type) -> None:
    env = gym.make(ENV_ID, layout_seed=1)
    try:
        with pytest.raises(error, match=next(iter(kwargs))):
            rollout_expert(env, **{"seed": 0, **kwargs})
    finally:
        env.close()


def test_collect_demonstrations_arguments_are_validated() -> None:
    with pytest.raises(TypeError, match="n must be an int"):
        collect_demonstrations(ENV_ID, 2.0, layout_seed=1)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="only_successful"):
        collect_demonstrations(ENV_ID, 1, only_successful="no", layout_seed=1)  # type: ignore[arg-type]
