"""LTLReplanWrapper end to end: soup scooping under perturbation, cooking re-tasked four ways."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.core.task import TaskSpec
from steer_envs.envs.cooking import TRANSITION_ATTRACTORS
from steer_envs.ltl import specs
from steer_envs.wrappers import LTLReplanWrapper


def _towards(env: gym.Env, target: np.ndarray | tuple[float, float]) -> np.ndarray:
    base = env.unwrapped
    velocity = (np.asarray(target, dtype=np.float64) - base.state) / base.dt
    speed = np.linalg.norm(velocity)
    if speed > base.max_speed:
        velocity *= base.max_speed / speed
    return velocity.astype(np.float32)


def _collapse(modes: list[str]) -> list[str]:
    out: list[str] = []
    for m in modes:
        if not out or out[-1] != m:
            out.append(m)
    return out


# ------------------------------------------------------------ soup scooping
_SOUP_TARGETS = {"a": (-5.0, -6.0), "b": (-5.0, -6.0), "c": (3.5, -5.0), "d": (4.69, 6.03)}


def _soup_policy(env: LTLReplanWrapper, obs: dict[str, Any]) -> np.ndarray:
    """Any policy works: this one heads for the region of the planned next mode (deep in the soup for b)."""
    return _towards(env, _SOUP_TARGETS[env.modes[int(obs["next_mode"])]])


def test_observation_and_info() -> None:
    env = LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"))
    obs, info = env.reset(seed=0)
    assert isinstance(env.observation_space, spaces.Dict)
    assert env.observation_space.contains(obs)
    assert env.modes == ("a", "b", "c", "d") and env.observation_space["next_mode"].n == 4
    assert info["plan"] == ["a", "b", "c", "d"] and info["ltl_mode"] == "a" and info["next_mode_name"] == "b"
    assert env.modes[int(obs["next_mode"])] == "b"
    assert not info["ltl_unexpected"] and not info["ltl_unknown_reading"] and not info["ltl_stuck"]
    env.close()


def test_soup_scoop_rollout_follows_the_plan() -> None:
    env = LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"))
    obs, info = env.reset(seed=1)
    visited = [info["ltl_mode"]]
    for _ in range(1000):
        obs, _, terminated, truncated, info = env.step(_soup_policy(env, obs))
        visited.append(info["ltl_mode"])
        assert info["plan"][0] == info["ltl_mode"] == info["mode_name"]
        if terminated or truncated:
            break
    assert info["success"] and _collapse(visited) == ["a", "b", "c", "d"]
    env.close()


def test_soup_scoop_perturbation_from_c_into_a_replans_a_b_c_d() -> None:
    env = LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"))
    obs, info = env.reset(seed=2)
    perturbed = False
    visited = [info["ltl_mode"]]
    for _ in range(3000):
        if info["ltl_mode"] == "c" and not perturbed:
            # push the spoon out of the transport region: the soup spills (c -> a)
            pinfo = env.unwrapped.perturb(to=np.array([-1.0, 0.0]))
            update = env.sync(pinfo)
            assert update["ltl_mode"] == "a" and update["plan"] == ["a", "b", "c", "d"]
            assert env.modes[int(update["next_mode"])] == "b"
            obs = {"observation": env.unwrapped.state.astype(np.float32), "next_mode": update["next_mode"]}
            perturbed = True
            visited.append("a")
        obs, _, terminated, truncated, info = env.step(_soup_policy(env, obs))
        visited.append(info["ltl_mode"])
        if terminated or truncated:
            break
    assert perturbed and info["success"]
    assert _collapse(visited) == ["a", "b", "c", "a", "b", "c", "d"]
    env.close()


# ------------------------------------------------------------------ cooking
_COOKING_INTERIOR = {"w": (0.0, -2.0), "y": (-4.5, 5.0), "g": (4.5, 5.0), "d": (0.0, 6.0)}


class _CookingPolicy:
    """Re-uses one motion per region transition (thesis Fig. (b)): settle inside the current region, then
    head for the attractor of the transition to the planned next mode (``w->y``, ``y->d``, ``d->g``, ...)."""

    def __init__(self) -> None:
        self.mode = ""
        self.settled = False

    def __call__(self, env: LTLReplanWrapper, info: dict[str, Any]) -> np.ndarray:
        current, nxt = info["ltl_mode"][0], info["next_mode_name"][0]  # w1 -> w, d2 -> d
        if info["ltl_mode"] != self.mode:
            self.mode, self.settled = info["ltl_mode"], False
        if not self.settled:
            interior = np.asarray(_COOKING_INTERIOR[current])
            self.settled = bool(np.linalg.norm(env.unwrapped.state - interior) < 0.3)
            if not self.settled:
                return _towards(env, interior)
        if current == nxt:
            return np.zeros(2, dtype=np.float32)
        return _towards(env, TRANSITION_ATTRACTORS[f"{current}->{nxt}"])


def _run_cooking(variant: str, steps: int, perturb_in: str | None = None) -> tuple[list[str], dict[str, Any]]:
    env = LTLReplanWrapper(gym.make("steer_envs/Cooking-v0"), variant)
    _, info = env.reset(seed=0)
    policy = _CookingPolicy()
    visited = [info["ltl_mode"]]
    for _ in range(steps):
        if perturb_in is not None and info["ltl_mode"] == perturb_in:
            info = {**info, **env.sync(env.unwrapped.perturb(to=np.array([-4.5, -3.0])))}  # into white: spill
            visited.append(info["ltl_mode"])
            perturb_in = None
        _, _, terminated, truncated, info = env.step(policy(env, info))
        visited.append(info["ltl_mode"])
        if terminated or truncated:
            break
    env.close()
    return _collapse(visited), info


@pytest.mark.parametrize(
    ("variant", "steps", "behaviour", "success"),
    [
        ("phi_cb", 2000, ["w1", "y", "d1", "g", "d2"], True),  # (c) chicken, then broccoli
        ("phi_bc", 2000, ["w1", "g", "d1", "y", "d2"], True),  # (d) broccoli, then chicken
        ("phi_c", 600, ["w", "y", "d"], False),  # (e) chicken only
        ("phi_cc", 900, ["w", "y", "d", "w", "y", "d", "w", "y", "d"], False),  # (f) chicken again and again
    ],
)
def test_cooking_same_regions_four_behaviours(variant: str, steps: int, behaviour: list[str], success: bool) -> None:
    visited, info = _run_cooking(variant, steps)
    assert visited[: len(behaviour)] == behaviour
    if variant == "phi_c":
        assert visited == behaviour  # stays in the pot
    assert info["success"] is success


def test_cooking_recovers_from_a_spill_by_replanning() -> None:
    visited, info = _run_cooking("phi_cb", 3000, perturb_in="y")
    assert visited == ["w1", "y", "w1", "y", "d1", "g", "d2"] and info["success"]


# ------------------------------------------------------------------- checks
@pytest.mark.filterwarnings("ignore::UserWarning")  # the checker's advice on wrappers and action scaling
@pytest.mark.parametrize(("env_id", "variant"), [("steer_envs/SoupScoop-v0", None), ("steer_envs/Cooking-v0", "phi_c")])
def test_passes_gymnasium_env_checker(env_id: str, variant: str | None) -> None:
    env = LTLReplanWrapper(gym.make(env_id).unwrapped, variant)
    check_env(env, skip_render_check=True)


class _NoSensors(gym.Env):
    observation_space = spaces.Box(-1, 1, (1,))
    action_space = spaces.Discrete(2)
    task = TaskSpec(name="soup", modes=("a", "b", "c", "d"), sensors=("r", "s", "t"))

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple:
        super().reset(seed=seed)
        return np.zeros(1, dtype=np.float32), {}

    def step(self, action: int) -> tuple:
        return np.zeros(1, dtype=np.float32), 0.0, False, False, {}


def test_errors() -> None:
    with pytest.raises(KeyError, match="sensors"):
        LTLReplanWrapper(_NoSensors(), specs.soup_scoop()).reset()
    with pytest.raises(TypeError, match="spec"):
        LTLReplanWrapper(_NoSensors(), 3)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="task"):
        LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"), specs.soup_scoop(), task="soup")  # type: ignore[arg-type]


def test_unknown_readings_keep_the_plan() -> None:
    env = LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"), "thesis")  # the env reports the public d = 011
    env.reset(seed=0)
    update = env.sync({"sensors": {"r": False, "s": True, "t": True}})
    assert update["ltl_unknown_reading"] and update["ltl_mode"] == "a" and update["plan"] == ["a", "b", "c", "d"]
    env.close()
