"""Every registered env, as ``gymnasium.make`` builds it, recovers from a refused ``reset`` and refuses use after close.

A refused ``reset`` changes nothing: not the episode (state, random stream),
not the wrappers' bookkeeping (the env checker's first-step check, the
reset-before-step rule, the step limit), so the next valid ``reset`` and
``step`` work. After ``close()``, ``reset``, ``step``, ``perturb`` and
``render`` raise :class:`~steer_envs.core.env.EnvClosedError` naming the env;
``close()`` again is fine.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded

import steer_envs  # noqa: F401
from steer_envs.core.env import ClosableEnv, EnvClosedError
from steer_envs.envs.registry import entry, env_ids

ALL = env_ids(variants=True)


@pytest.fixture(scope="module")
def made() -> Iterator[dict[str, Any]]:
    """id -> the env made for it, shared by this module's tests (each id is made once where the order allows)."""
    envs: dict[str, Any] = {}
    yield envs
    for env in envs.values():
        env.close()


def _fresh(made: dict[str, Any], env_id: str) -> Any:
    if env_id in made:
        made.pop(env_id).close()
    made[env_id] = gym.make(env_id)
    return made[env_id]


def _open(made: dict[str, Any], env_id: str) -> Any:
    env = made.get(env_id)
    if env is None or env.unwrapped.closed:
        env = _fresh(made, env_id)
        env.reset(seed=0)
    return env


def _bad_options(env_id: str, dim: int) -> list[dict[str, Any]]:
    """Options each env refuses: an unknown key, a NaN start; Maze2D a good start with a wall as goal."""
    bad: list[dict[str, Any]] = [{"bogus": 1}, {"state": [math.nan] * dim}]
    if entry(env_id).entry_point.startswith("steer_envs.envs.maze2d:"):
        bad.append({"state": [1.0, 1.0], "goal_cell": (0, 0)})
    return bad


def _rng_state(env: Any) -> dict[str, Any]:
    return env.unwrapped.np_random.bit_generator.state


def _step(env: Any) -> tuple[Any, ...]:
    return env.step(np.zeros(env.action_space.shape, dtype=env.action_space.dtype))


@pytest.mark.parametrize("env_id", ALL)
def test_a_refused_reset_changes_nothing_and_the_next_reset_and_step_work(made: dict[str, Any], env_id: str) -> None:
    env = _fresh(made, env_id)
    with pytest.raises(ValueError, match="bogus"):
        env.reset(seed=3, options={"bogus": 1})  # the first reset, refused
    with pytest.raises(ResetNeeded):  # no reset succeeded yet: the order rule still holds
        _step(env)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs) and "mode" in info
    first = _step(env)
    assert len(first) == 5 and not first[3]

    # a refused reset in mid-episode: the state and the random stream stay, the episode goes on
    state, rng = env.unwrapped.state, _rng_state(env)
    for options in _bad_options(env_id, state.shape[0]):
        with pytest.raises((TypeError, ValueError)):
            env.reset(seed=123, options=options)
        np.testing.assert_array_equal(env.unwrapped.state, state, err_msg=f"{env_id}: moved by refused {options}")
        assert _rng_state(env) == rng, f"{env_id}: reset(seed=123, options={options}) reseeded the env"
    assert len(_step(env)) == 5


def test_a_refused_reset_keeps_the_step_count() -> None:
    env = gym.make("steer_envs/SoupScoop-v0", max_episode_steps=3)
    env.reset(seed=0)
    _step(env)
    with pytest.raises(ValueError, match="bogus"):
        env.reset(options={"bogus": 1})
    truncated = [_step(env)[3] for _ in range(2)]
    assert truncated == [False, True]  # the third step of the episode ends it, refused reset or not
    env.close()


@pytest.mark.parametrize("env_id", ALL)
def test_a_closed_env_refuses_every_call_naming_itself(made: dict[str, Any], env_id: str) -> None:
    env = _open(made, env_id)
    base = env.unwrapped
    assert isinstance(base, ClosableEnv) and not base.closed
    delta = np.zeros_like(base.state)
    env.close()
    assert base.closed
    calls = {
        "reset": lambda: env.reset(seed=0),
        "step": lambda: _step(env),
        "perturb": lambda: base.perturb(delta=delta),
        "render": env.render,
    }
    for name, call in calls.items():
        with pytest.raises(EnvClosedError, match=rf"{env_id} is closed: {name}\(\)") as caught:
            call()
        assert isinstance(caught.value, RuntimeError) and isinstance(caught.value, gym.error.ClosedEnvironmentError)
    env.close()  # again: Gymnasium's convention, nothing happens
    base.close()
    assert base.closed


def test_a_closed_unwrapped_env_names_its_class() -> None:
    from steer_envs.envs.convex_mode import ConvexModeEnv

    env = ConvexModeEnv()
    env.reset(seed=0)
    env.close()
    with pytest.raises(EnvClosedError, match=r"ConvexModeEnv is closed: perturb\(\)"):
        env.perturb(to=[0.0, 0.0])


def test_overrides_of_a_subclass_are_checked_before_their_first_line() -> None:
    from steer_envs.envs.soup_scoop import SoupScoopEnv

    ran: list[str] = []

    class Logged(SoupScoopEnv):
        closed_calls = (*SoupScoopEnv.closed_calls, "probe")

        def step(self, action: Any) -> Any:
            ran.append("step")
            return super().step(action)

        def probe(self) -> str:
            ran.append("probe")
            return "ok"

        def close(self) -> None:
            ran.append("close")
            super().close()

    env = Logged()
    env.reset(seed=0)
    assert env.probe() == "ok"
    env.step([0.0, 0.0])
    env.close()
    env.close()
    for call in (lambda: env.step([0.0, 0.0]), env.probe):
        with pytest.raises(EnvClosedError, match="Logged is closed"):
            call()
    assert ran == ["probe", "step", "close"]  # neither override ran after close; close ran once
