"""Every wrapper records its constructor arguments, so ``env.spec`` shows (and can rebuild) the stack."""

from __future__ import annotations

import inspect
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import steer_envs  # noqa: F401  (registers the ids)
import steer_envs.wrappers as wrappers
from steer_envs.steering import PostHocRanking
from steer_envs.wrappers import DSModulationWrapper, LTLReplanWrapper, SteeringWrapper

SOUP = "steer_envs/SoupScoop-v0"


def _wrapper_classes() -> list[type]:
    found = []
    for name in wrappers.__all__:
        value = getattr(wrappers, name)
        if inspect.isclass(value) and issubclass(value, gym.Wrapper):
            found.append(value)
    return found


def test_every_exported_wrapper_records_its_constructor_arguments() -> None:
    classes = _wrapper_classes()
    assert {c.__name__ for c in classes} == {
        "SteeringWrapper",
        "LTLReplanWrapper",
        "DSModulationWrapper",
        "ArmPerturbationWrapper",
    }
    for cls in classes:
        assert issubclass(cls, gym.utils.RecordConstructorArgs), cls.__name__


def test_the_spec_shows_the_stack_and_rebuilds_it() -> None:
    env = DSModulationWrapper(LTLReplanWrapper(gym.make(SOUP), "public"), attractor=[4.75, 5.99], margin=0.3)
    stack = env.spec.additional_wrappers
    assert [w.name for w in stack] == ["LTLReplanWrapper", "DSModulationWrapper"]
    assert stack[0].entry_point == "steer_envs.wrappers.ltl_replan:LTLReplanWrapper"
    assert stack[0].kwargs == {"spec": "public", "task": None}
    assert stack[1].kwargs["margin"] == 0.3 and stack[1].kwargs["attractor"] == [4.75, 5.99]
    rebuilt = gym.make(env.spec)
    assert isinstance(rebuilt, DSModulationWrapper) and isinstance(rebuilt.env, LTLReplanWrapper)
    assert rebuilt.margin == 0.3
    _, info = rebuilt.reset(seed=0)
    assert info["plan"] == ["a", "b", "c", "d"]


def test_recorded_cuts_are_the_ones_given_not_the_ones_learned() -> None:
    from steer_envs.baselines.lpv_ds import CutSet

    cuts = {0: CutSet(np.zeros(2))}
    env = DSModulationWrapper(gym.make("steer_envs/ConvexMode-v0"), attractor=[0.0, 0.0], cuts=cuts)
    recorded = env.spec.additional_wrappers[0].kwargs["cuts"]
    assert recorded is not cuts and len(recorded[0]) == 0
    assert env.cut_sets[0] is cuts[0]  # the wrapper still works on the given objects


class _Straight:
    horizon, action_dim = 4, 2

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        return np.repeat(np.linspace(obs[:2], [1.0, 1.0], self.horizon)[None], n, axis=0)


def test_steering_wrapper_records_its_policy_by_reference() -> None:
    policy, sampler = _Straight(), PostHocRanking()
    env = SteeringWrapper(gym.make("steer_envs/Maze2D-Umaze-v0"), policy, sampler, batch=3, execute=2)
    (spec,) = env.spec.additional_wrappers
    assert spec.name == "SteeringWrapper"
    assert spec.kwargs["policy"] is policy and spec.kwargs["sampler"] is sampler
    assert spec.kwargs["batch"] == 3 and spec.kwargs["execute"] == 2 and spec.kwargs["sketch_points"] is None


@pytest.mark.parametrize("name", ["CounterfactualPerturbationWrapper", "CounterfactualReplayer"])
def test_the_counterfactual_generator_is_not_a_wrapper(name: str) -> None:
    with pytest.raises(AttributeError):
        getattr(wrappers, name)
    from steer_envs.data.counterfactual import CounterfactualReplayer

    assert not issubclass(CounterfactualReplayer, gym.Wrapper)
