"""SteeringWrapper pins torch threads for its call (default 1) and restores them after."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.core.interaction import Sketch
from steer_envs.steering import PostHocRanking
from steer_envs.wrappers import SteeringWrapper


class ThreadSpy:
    """A stand-in policy that records torch's thread count when it is asked to sample."""

    horizon, action_dim = 8, 2

    def __init__(self) -> None:
        self.seen: list[int] = []

    def sample(self, obs: np.ndarray, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        self.seen.append(torch.get_num_threads())
        assert generator is not None
        return np.repeat(np.linspace(obs[:2], [1.0, 1.0], self.horizon)[None], n, axis=0)


@pytest.mark.parametrize("threads", [1, None])
def test_threads_are_pinned_for_the_call_and_restored(threads: int | None) -> None:
    before = torch.get_num_threads()
    spy = ThreadSpy()
    env = SteeringWrapper(gym.make("steer_envs/Maze2D-Umaze-v0"), spy, PostHocRanking(), batch=2, threads=threads)
    obs, _ = env.reset(seed=0)
    env.step(Sketch([obs, [1.0, 1.0]]))
    assert spy.seen == [1 if threads == 1 else before]
    assert torch.get_num_threads() == before


@pytest.mark.parametrize(("threads", "error"), [(0, ValueError), (1.5, TypeError), (True, TypeError)])
def test_bad_threads_are_refused(threads: object, error: type[Exception]) -> None:
    with pytest.raises(error, match="threads"):
        SteeringWrapper(gym.make("steer_envs/Maze2D-Umaze-v0"), ThreadSpy(), PostHocRanking(), threads=threads)  # type: ignore[arg-type]
