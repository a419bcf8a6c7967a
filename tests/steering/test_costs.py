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
    with pytest.raises(TypeError, match=r"plan costs or \(cost, weight\) pairs"):
        check_costs([(1, 2)])
    with pytest.raises(ValueError, match="weight"):
        check_costs([(region_cost([]), -1.0)])
    with pytest.raises(ValueError, match="declares no forbidden region"):
        safety_cost(TaskSpec("t", ("a",)))
    with pytest.raises(ValueError, match="must return a tensor of shape"):
        WeightedCosts([lambda p: p.sum()]).values(np.zeros((2, 3, 2)))


# --- samplers with costs --------------------------------------------------------------------------
from test_flow_samplers import FlowMixture  # noqa: E402
from test_samplers import OBS, MixturePolicy, sketch_at  # noqa: E402

from steer_envs.steering import make_sampler  # noqa: E402

#: a wall over the far half of the 90-degree mode (plans straight up from the origin, 3 long)
WALL = Boxes([[-0.6, 1.2]], [[0.6, 3.6]])


def in_wall(plans: np.ndarray) -> float:
    return float(WALL.contains(plans).any(axis=-1).mean())


@pytest.mark.parametrize("policy_class", [MixturePolicy, FlowMixture])
@pytest.mark.parametrize("name", ["GD", "SS"])
def test_a_region_cost_keeps_guided_plans_out_of_the_wall(policy_class: type, name: str) -> None:
    policy = policy_class(angles_deg=(0.0, 90.0))
    sketch = sketch_at(45.0)  # both modes align equally well: about half the plans take the walled one
    plain, walled = [], []
    for seed in range(4):
        rng = np.random.default_rng(seed)
        plain.append(in_wall(make_sampler(name)(policy, OBS, sketch, 16, generator=rng).plans))
        safe = make_sampler(name, costs=[(region_cost([WALL]), 2.0)])
        walled.append(in_wall(safe(policy, OBS, sketch, 16, generator=np.random.default_rng(seed)).plans))
    assert np.mean(plain) > 0.3 and np.mean(walled) < 0.5 * np.mean(plain)


def test_rankers_pick_by_alignment_plus_costs_and_rs_refuses_costs() -> None:
    policy = MixturePolicy()
    sketch = sketch_at(45.0)  # the 0- and 90-degree modes align equally well
    heavy = make_sampler("PR", costs=[(region_cost([WALL]), 100.0)])
    result = heavy(policy, OBS, sketch, 32, generator=np.random.default_rng(0))
    assert result.plan_costs is not None and result.plan_costs.shape == (32,)
    assert result.chosen == int(np.argmin(result.costs + result.plan_costs))
    assert not WALL.contains(result.plan).any()
    plain = make_sampler("PR")(policy, OBS, sketch, 32, generator=np.random.default_rng(0))
    assert plain.plan_costs is None and np.array_equal(plain.plans, result.plans)  # same batch, other pick
    with pytest.raises(ValueError, match="picks a random plan"):
        make_sampler("RS", costs=[region_cost([WALL])])
    assert "costs=1" in repr(make_sampler("GD", costs=[region_cost([WALL])]))
