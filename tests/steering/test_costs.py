"""Plan costs: the region and safety costs, user costs, their values and gradients in normalized space."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.core.regions import Boxes
from steer_envs.core.task import TaskSpec
from steer_envs.steering.costs import WeightedCosts, check_costs, region_cost, safety_cost


class Scaled:
    """A policy's normalization only: env = 2 * x + 1."""

    def unnormalize(self, x: torch.Tensor) -> torch.Tensor:
        return 2 * x + 1


def test_region_cost_values_and_gradient_point_out_of_the_box() -> None:
    cost = region_cost([Boxes([[0.0, 0.0]], [[1.0, 1.0]])])
    plans = torch.tensor([[[0.2, 0.5], [0.5, 0.5]], [[3.0, 3.0], [4.0, 4.0]]], requires_grad=True)
    values = cost(plans)
    torch.testing.assert_close(values, torch.tensor([0.35, 0.0]))
    values.sum().backward()
    assert plans.grad is not None
    torch.testing.assert_close(plans.grad[0, 0], torch.tensor([0.5, 0.0]))  # deeper -> toward the face x = 0
    assert torch.all(plans.grad[1] == 0)


def test_weighted_costs_rank_and_guide_in_normalized_space() -> None:
    wall = region_cost([Boxes([[0.0, 0.0]], [[2.0, 2.0]])])
    costs = WeightedCosts([(wall, 4.0), lambda p: p[..., 0].mean(dim=-1)])
    plans = np.array([[[1.0, 1.0], [5.0, 5.0]]])
    np.testing.assert_allclose(costs.values(plans), [4.0 * 0.5 + 3.0])
    x = torch.zeros(1, 2, 2)  # env: all waypoints at (1, 1), in the wall's middle
    grad = costs.grad(Scaled(), x)
    assert grad.shape == x.shape and torch.isfinite(grad).all() and bool(grad.abs().sum() > 0)
    assert not WeightedCosts(None) and np.all(WeightedCosts([]).values(plans) == 0)


def test_safety_cost_of_the_maze_penalises_plans_through_walls() -> None:
    env = gym.make("steer_envs/Maze2D-Large-v0").unwrapped
    cost = safety_cost(env.task)
    free = np.argwhere(~env.grid.walls)[0].astype(float)
    wall = np.argwhere(env.grid.walls)[0].astype(float)
    plans = torch.as_tensor(np.stack([np.repeat(free[None], 4, 0), np.repeat(wall[None], 4, 0)]))
    values = cost(plans)
    assert values[0] == 0 and values[1] > 0.4
    env.close()


def test_bad_costs_are_named() -> None:
    with pytest.raises(TypeError, match="sequence of plan costs"):
        check_costs(region_cost([]))
    with pytest.raises(TypeError, match="plan costs or .cost, weight. pairs"):
        check_costs([(1, 2)])
    with pytest.raises(ValueError, match="weight"):
        check_costs([(region_cost([]), -1.0)])
    with pytest.raises(ValueError, match="declares no forbidden region"):
        safety_cost(TaskSpec("t", ("a",)))
    with pytest.raises(ValueError, match="must return a tensor of shape"):
        WeightedCosts([lambda p: p.sum()]).values(np.zeros((2, 3, 2)))
