"""SteeringWrapper: interactions as actions, the chosen plan executed in Maze2D, SB3-compatible Box mode."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from stub_policies import Corridor

torch = pytest.importorskip("torch")
diffusers = pytest.importorskip("diffusers")

from steer_envs.core.interaction import Nudge, Point, Sketch  # noqa: E402
from steer_envs.envs.maze2d import Maze2DEnv  # noqa: E402
from steer_envs.steering import (  # noqa: E402
    OutputPerturbation,
    PostHocRanking,
    RandomSampling,
    StochasticSampling,
    policy_observation,
)
from steer_envs.wrappers import SteeringWrapper  # noqa: E402
from steer_envs.wrappers.steering import InteractionSpace  # noqa: E402

START = np.array([3.0, 1.0])  # LARGE_MAZE row 3 is free from column 1 to 6


class CorridorPolicy(Corridor):
    """:class:`Corridor` plans (12 waypoints, 2.2 long) that record every observation they are asked to plan from."""

    def __init__(self) -> None:
        super().__init__()
        self.seen_obs: list[np.ndarray] = []

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        self.seen_obs.append(np.array(obs))
        return super().sample(obs, n, generator=generator)


def make(sampler: Any = None, **kwargs: Any) -> SteeringWrapper:
    env = Maze2DEnv("large", sample_goal=False)
    return SteeringWrapper(env, CorridorPolicy(), sampler or PostHocRanking(), batch=8, **kwargs)


def east_sketch(length: float = 3.0) -> Sketch:
    return Sketch(START + np.linspace(0.0, 1.0, 25)[:, None] * np.array([0.0, length]))


def test_step_executes_the_chosen_plan_and_reports_the_batch() -> None:
    env = make()
    obs, _ = env.reset(seed=0, options={"state": START})
    np.testing.assert_allclose(obs, START, atol=1e-6)
    obs, reward, terminated, truncated, info = env.step(east_sketch())
    plans, chosen = info["plans"], info["chosen"]
    assert plans.shape == (8, 12, 2) and info["costs"].shape == (8,) and info["sampler"] == "PR"
    assert chosen == int(np.argmin(info["costs"]))
    best = plans[chosen]
    assert best[-1, 1] - best[0, 1] > 2.0  # the plan heading east (along the sketch) was chosen
    np.testing.assert_allclose(info["executed"], best[1:].astype(np.float32))  # exec_start = 1
    np.testing.assert_array_equal(info["plan_collides"], env.unwrapped.plan_collides(plans))
    assert not terminated and not truncated and reward == 0.0
    assert np.linalg.norm(obs - best[-1]) < 0.6  # the PD-tracked agent followed the waypoints
    assert obs[1] > START[1] + 1.5 and info["latency_ms"] > 0
    assert info["constraint_violation"] is False and info["perturbed_state"] is None


def test_none_is_unsteered_and_execute_limits_the_chunk() -> None:
    env = make(execute=3)
    env.reset(seed=1, options={"state": START})
    _, _, _, _, info = env.step(None)
    assert info["sampler"] == "RS" and np.all(np.isnan(info["costs"])) and len(info["executed"]) == 3
    np.testing.assert_allclose(info["executed"], info["plans"][info["chosen"]][1:4].astype(np.float32))


def test_policy_gets_its_observation_history() -> None:
    env = make(execute=2)
    obs0, _ = env.reset(seed=0, options={"state": START})
    policy = env.policy
    env.step(None)
    assert policy.seen_obs[0].shape == (2, 2)  # padded after the reset: the agent was at rest
    np.testing.assert_array_equal(policy.seen_obs[0][0], policy.seen_obs[0][1])
    env.step(None)
    assert not np.array_equal(policy.seen_obs[1][0], policy.seen_obs[1][1])  # the last two positions
    assert policy_observation(RandomSampling(), [obs0]) is obs0  # no n_obs_steps: the current observation
    with pytest.raises(ValueError, match="history"):
        policy_observation(policy, [])


def test_output_perturbation_moves_the_real_agent_before_executing() -> None:
    env = make(OutputPerturbation(index=20), execute=1)
    env.reset(seed=0, options={"state": START})
    sketch = Sketch(np.stack([np.full(30, 3.0), np.linspace(1.0, 10.0, 30)], axis=1))  # row 3, into the wall at col 7
    _, _, _, _, info = env.step(sketch)
    wall_at = int(np.argmax(env.unwrapped.is_wall(sketch.points)))
    assert 0 < wall_at < 20  # the wrapper gave OP the env's wall check: it stops before the wall
    np.testing.assert_allclose(info["perturbed_state"], sketch.points[wall_at - 1])
    assert env.policy.seen_obs[-1].shape == (2, 2)
    np.testing.assert_allclose(env.policy.seen_obs[-1][-1], sketch.points[wall_at - 1], atol=0.11)
    assert abs(env.unwrapped.state[1] - sketch.points[wall_at - 1][1]) < 0.5


def test_stochastic_sampling_through_the_wrapper_and_seeded_reproducibility() -> None:
    runs = []
    for _ in range(2):
        env = make(StochasticSampling(), execute=4)
        env.reset(seed=3, options={"state": START})
        obs, _, _, _, info = env.step(east_sketch())
        runs.append((obs, info["plans"]))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    assert runs[0][1][:, -1, 1].mean() > START[1] + 1.5  # the whole batch was steered east


def test_sketch_box_action_space_for_sb3() -> None:
    from stable_baselines3.common.env_checker import check_env

    env = make(sketch_points=6, execute=2)
    box = env.action_space
    assert isinstance(box, gym.spaces.Box) and box.shape == (12,)
    np.testing.assert_array_equal(box.high.reshape(6, 2), np.tile([8.0, 11.0], (6, 1)))
    env.reset(seed=0, options={"state": START})
    flat = np.tile(START, 6).astype(np.float32)
    flat[1::2] += np.linspace(0.0, 3.0, 6, dtype=np.float32)
    sketch = env.interaction(flat)
    assert isinstance(sketch, Sketch) and sketch.points.shape == (6, 2)
    _, _, _, _, info = env.step(flat)
    assert info["plans"][info["chosen"]][-1, 1] > START[1] + 1.5
    with pytest.raises(ValueError, match="flattened sketch"):
        env.step(np.zeros(5, dtype=np.float32))
    check_env(env, warn=False)


def test_interaction_space_and_argument_checks() -> None:
    env = make()
    space = env.action_space
    assert isinstance(space, InteractionSpace) and space.dim == 2
    assert space.contains(None) and space.contains(east_sketch()) and space.contains(Nudge([[1.0, 1.0]]))
    assert not space.contains(Sketch(np.zeros((3, 3)))) and not space.contains(np.zeros(2))
    space.seed(0)
    drawn = space.sample()
    assert isinstance(drawn, Sketch) and space.contains(drawn)
    assert isinstance(InteractionSpace([0, 0], [1, 1], ("point",)).sample(), Point)
    with pytest.raises(ValueError, match="kinds"):
        InteractionSpace([0, 0], [1, 1], ("wave",))
    with pytest.raises(gym.error.ResetNeeded):
        env.step(None)
    env.reset(seed=0, options={"state": START})
    with pytest.raises(TypeError, match="Point, Sketch, Nudge or None"):
        env.step(np.zeros(2))
    with pytest.raises(ValueError, match="dimension 2"):
        env.step(Point([1.0, 2.0, 3.0]))
    base = Maze2DEnv("large")
    with pytest.raises(TypeError, match="TrajectoryPolicy"):
        SteeringWrapper(base, object(), PostHocRanking())  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="Sampler"):
        SteeringWrapper(base, CorridorPolicy(), "PR")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="batch"):
        SteeringWrapper(base, CorridorPolicy(), PostHocRanking(), batch=0)
    with pytest.raises(ValueError, match="sketch_points"):
        SteeringWrapper(base, CorridorPolicy(), PostHocRanking(), sketch_points=1)
    with pytest.raises(ValueError, match="action_space"):
        SteeringWrapper(Maze2DEnv("large", observe_velocity=True).unwrapped, _ThreeD(), PostHocRanking())


class _ThreeD:
    horizon = 4
    action_dim = 3

    def sample(self, obs: Any, n: int, *, generator: Any = None) -> np.ndarray:
        return np.zeros((n, 4, 3))
