"""SoupScoop-v0: geometry, scooping physics, sensors, vector path, scripted expert (public TLI code, thesis §3.6)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from kinematic_helpers import (
    check_seeded_start,
    noisy_expert_vector_parity,
    run_expert_batch,
    run_with_one_push,
    walk_from,
)

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.data.experts import make_expert
from steer_envs.data.experts.soup_scoop import SoupScoopExpert
from steer_envs.envs.soup_scoop import SOUP_TASK, SoupScoopEnv

ENV_ID = "steer_envs/SoupScoop-v0"


def _expected_label(p: np.ndarray) -> np.ndarray:
    """The region rule of the public TLI code, written out independently of the module."""
    x, y = p[:, 0], p[:, 1]

    def near(c: tuple[float, float]) -> np.ndarray:
        return np.hypot(x - c[0], y - c[1]) <= 0.4

    label = np.zeros(len(p), dtype=np.int64)
    label[(y <= -4) | near((-6.47, -4.13))] = 1
    label[((x >= 2) & (x <= 6) & (y <= 6)) | near((2.06, -6.98))] = 2
    label[((x >= 2) & (x <= 6) & (y >= 6)) | near((4.69, 6.03))] = 3
    return label


def _run_expert_batch(starts: np.ndarray, steps: int = 1000, noise: float = 0.0, seed: int = 0) -> dict:
    """Roll the expert (plus optional action noise) in the vector env from ``starts``; first episode of each."""
    return run_expert_batch(ENV_ID, SOUP_TASK, SoupScoopExpert, starts, steps=steps, noise=noise, seed=seed)


# ----------------------------------------------------------------- seeding
def test_same_seed_gives_identical_trajectories_and_starts_in_white() -> None:
    check_seeded_start(ENV_ID, "a")


def test_constructor_validates_arguments() -> None:
    with pytest.raises(ValueError, match="sensor_convention"):
        SoupScoopEnv(sensor_convention="matlab")
    with pytest.raises(ValueError, match="dt"):
        SoupScoopEnv(dt=-0.1)
    with pytest.raises(ValueError, match="name"):
        SoupScoopEnv().model.in_region("blue", np.zeros((1, 2)))


# ----------------------------------------------------------------- geometry
def test_region_labels_follow_the_public_rectangles_and_attractor_discs() -> None:
    model = SoupScoopEnv().model
    rng = np.random.default_rng(0)
    pts = np.vstack(
        [
            rng.uniform(-8, 8, size=(4000, 2)),
            rng.normal((-6.47, -4.13), 0.3, size=(300, 2)),  # around the yellow attractor (above the surface)
            rng.normal((2.06, -6.98), 0.3, size=(300, 2)),  # pink disc reaching into yellow
            rng.normal((4.69, 6.03), 0.3, size=(300, 2)),
        ]
    )
    np.testing.assert_array_equal(model.regions(pts), _expected_label(pts))
    # the disc rule matters: these points are outside their rectangles
    assert model.regions(np.array([[-6.47, -3.8], [1.75, -6.98], [4.69, 5.7]])).tolist() == [1, 2, 3]


def test_task_spec_maps_both_sensor_conventions_and_thesis_transitions() -> None:
    assert SOUP_TASK.modes == ("a", "b", "c", "d") and SOUP_TASK.sensors == ("r", "s", "t")
    assert SOUP_TASK.mode_of({"s": True, "t": True}) == "d"  # public automaton table
    assert SOUP_TASK.mode_of({"t": True}) == "d"  # thesis appendix formula
    assert SOUP_TASK.mode_of({"r": True}) == "b" and SOUP_TASK.mode_of({"s": True}) == "c"
    assert SOUP_TASK.shortest_plan("a") == ["a", "b", "c", "d"]
    recoveries = {("b", "a"), ("c", "a"), ("c", "b")}
    assert SOUP_TASK.transitions == {("a", "b"), ("b", "c"), ("c", "d")} | recoveries
    assert gym.make(ENV_ID).unwrapped.task is SOUP_TASK


# ------------------------------------------------------------------ physics
def test_white_to_pink_never_loads_soup() -> None:
    env = SoupScoopEnv()
    infos = walk_from(env, (1.0, 0.0), (3.0, 0.0), (3.0, 5.5), (4.0, 7.0), (4.0, 3.0))
    assert env.model.regions(np.array([[3.0, 0.0], [4.0, 7.0]])).tolist() == [2, 3]
    assert all(i["mode_name"] == "a" for i in infos)  # green without soup is just reaching
    assert not any(i["sensors"]["s"] or i["sensors"]["t"] or i["constraint_violation"] for i in infos)


def test_soup_is_scooped_only_by_moving_from_yellow_into_pink() -> None:
    env = SoupScoopEnv()
    infos = walk_from(env, (-2.0, 0.0), (-2.0, -6.0), (3.0, -6.0))
    names = [i["mode_name"] for i in infos]
    assert names[0] == "a" and "b" in names and names[-1] == "c"
    first_b, first_c = names.index("b"), names.index("c")
    assert set(names[first_b:first_c]) == {"b"} and infos[first_b]["sensors"] == {"r": True, "s": False, "t": False}
    assert infos[-1]["sensors"] == {"r": False, "s": True, "t": False}
    assert env.model.regions(env.state[None])[0] == 2
    # leaving the soup before scooping is an allowed recovery b -> a, not a spill
    infos = walk_from(env, (-5.0, -5.0), (-5.0, -3.0))
    assert [infos[0]["mode_name"], infos[-1]["mode_name"]] == ["b", "a"]
    assert not any(i["constraint_violation"] for i in infos)


@pytest.mark.parametrize(
    ("exit_to", "mode_after"),
    [((1.0, -2.0), "a"), ((1.0, -6.0), "b"), ((7.0, 0.0), "a")],
)
def test_leaving_the_transport_region_spills_the_soup(exit_to: tuple[float, float], mode_after: str) -> None:
    env = SoupScoopEnv()
    corner = (3.0, exit_to[1])
    infos = walk_from(env, (1.0, -6.0), (3.0, -6.0), corner, exit_to)
    flagged = [k for k, i in enumerate(infos) if i["constraint_violation"]]
    assert len(flagged) == 1, "exactly the step that leaves pink spills"
    k = flagged[0]
    assert infos[k - 1]["mode_name"] == "c" and infos[k]["mode_name"] == mode_after
    assert not infos[k]["sensors"]["s"] and infos[k]["success"] is False
    assert all(i["mode_name"] != "c" for i in infos[k:]), "the soup does not come back"


@pytest.mark.parametrize(("convention", "s_at_goal"), [("public", True), ("thesis", False)])
def test_delivery_succeeds_and_done_absorbs(convention: str, s_at_goal: bool) -> None:
    env = SoupScoopEnv(sensor_convention=convention)
    infos = walk_from(env, (1.0, -6.0), (3.0, -6.0), (4.0, -6.0), (4.0, 7.0))
    reached = next(k for k, i in enumerate(infos) if i["success"])
    assert infos[reached]["mode_name"] == "d"
    assert infos[reached]["sensors"] == {"r": False, "s": s_at_goal, "t": True}
    assert SOUP_TASK.mode_of(infos[reached]["sensors"]) == "d"
    _, reward, terminated, _, _ = env.step(np.zeros(2, dtype=np.float32))
    assert terminated and reward == 1.0
    # d absorbs: moving on (ignoring termination) neither spills nor leaves d
    after = _walk_from_here(env, (-3.0, 0.0))
    assert all(i["mode_name"] == "d" and i["success"] and not i["constraint_violation"] for i in after)


def _walk_from_here(env: SoupScoopEnv, target: tuple[float, float]) -> list[dict]:
    out = []
    for _ in range(200):
        delta = np.asarray(target) - env.state
        if np.linalg.norm(delta) < 1e-9:
            break
        out.append(env.step((delta / env.dt).astype(np.float32))[4])
    return out


def test_perturb_moves_memory_with_the_state_and_rejects_bad_arguments() -> None:
    env = SoupScoopEnv()
    walk_from(env, (1.0, -6.0), (3.0, -6.0))
    info = env.perturb(to=np.array([3.0, 2.0]))  # still in pink: soup stays
    assert info["mode_name"] == "c" and info["perturbed"] and not info["constraint_violation"]
    info = env.perturb(delta=np.array([-4.0, 0.0]))  # pushed into white: the soup falls off, not the policy's fault
    assert info["mode_name"] == "a" and not info["constraint_violation"]
    for bad in (np.array([np.nan, 0.0]), np.zeros(3), [[1.0, 2.0]]):
        with pytest.raises(ValueError, match="delta"):
            env.perturb(delta=bad)
    with pytest.raises(ValueError, match="exactly one"):
        env.perturb()
    with pytest.raises(ValueError, match="exactly one"):
        env.perturb(delta=np.zeros(2), to=np.zeros(2))
    with pytest.raises(ValueError, match="to"):
        env.perturb(to=np.array([0.0, np.inf]))
    with pytest.raises(TypeError, match="to"):
        env.perturb(to="soup")


# ------------------------------------------------------------- vector path
def test_vector_env_agrees_step_for_step_with_single_envs() -> None:
    n = 8
    finished, seen_violation = noisy_expert_vector_parity(ENV_ID, SOUP_TASK, SoupScoopEnv, SoupScoopExpert, n=n)
    assert finished.sum() >= n // 2 and seen_violation, "the comparison must cover scooping, spills and success"


# ------------------------------------------------------------------ expert
def test_expert_succeeds_from_100_reset_seeds_without_spilling() -> None:
    env = gym.make(ENV_ID)
    starts = np.stack([env.reset(seed=s)[0] for s in range(100)]).astype(np.float64)
    out = _run_expert_batch(starts, steps=env.spec.max_episode_steps)
    assert out["success"].mean() >= 0.99
    assert out["violations"] == 0 and out["pairs"] == {("a", "b"), ("b", "c"), ("c", "d")}
    assert out["steps"].max() < env.spec.max_episode_steps // 2


def test_expert_succeeds_from_any_state_and_noisy_rollouts_only_make_allowed_transitions() -> None:
    starts = np.random.default_rng(7).uniform(-8, 8, size=(200, 2))
    out = _run_expert_batch(starts)
    assert out["success"].mean() >= 0.99
    noisy = _run_expert_batch(starts[:100], noise=25.0, seed=1)
    assert noisy["violations"] > 0, "heavy action noise must cause some spills"
    assert noisy["pairs"] <= SOUP_TASK.transitions
    assert {("c", "a"), ("c", "b")} & noisy["pairs"]


def test_expert_recovers_after_a_perturbation_spills_the_soup() -> None:
    env = gym.make(ENV_ID)
    expert = make_expert(env)
    obs, info = env.reset(seed=0)
    expert.reset(obs, info)

    def lifting(obs: Any, info: dict) -> bool:
        return info["mode_name"] == "c" and obs[1] > 0

    push = {"delta": np.array([-4.0, 0.0])}  # out of pink: the soup is spilled
    modes, pushed_at, pushed_to, info = run_with_one_push(env, expert, obs, info, 1000, lifting, **push)
    assert pushed_at is not None and pushed_to == "a" and info["success"]
    assert "".join(dict.fromkeys(modes[:pushed_at])) == "abc"
    assert "".join(dict.fromkeys(modes[pushed_at:])) == "abcd", "re-scoops after the spill"


# ------------------------------------------------------------------ render
def test_render_draws_the_thesis_colours() -> None:
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([0.0, -5.0], dtype=np.float32))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape == (256, 256, 3)
    colours = {tuple(c) for c in np.unique(frame.reshape(-1, 3), axis=0)}
    assert {tuple(c) for c in env.unwrapped.model.region_palette} <= colours
    # the pink column sits at x in [2, 6]: pixel column ~ (4 + 8) / 16 * 256 in the middle row
    assert tuple(frame[128, 192]) == tuple(env.unwrapped.model.region_palette[2])
    env.close()
