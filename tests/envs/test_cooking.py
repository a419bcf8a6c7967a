"""Cooking-v0: layout, food physics, sensor APs and modes, vector path, scripted expert (thesis appendix)."""

from __future__ import annotations

import re
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
from steer_envs.data.experts.cooking import CookingExpert
from steer_envs.envs.cooking import COOKING_TASK, MODE_AP_FORMULAS, CookingEnv

ENV_ID = "steer_envs/Cooking-v0"
TASK = COOKING_TASK


def _expected_label(p: np.ndarray) -> np.ndarray:
    """The documented layout, written out independently of the module (0 white, 1 yellow, 2 green, 3 pot)."""
    x, y = p[:, 0], p[:, 1]
    label = np.zeros(len(p), dtype=np.int64)
    label[(x >= -7) & (x <= -2) & (y >= 1)] = 1
    label[(x >= 2) & (x <= 7) & (y >= 1)] = 2
    label[(np.abs(x) <= 2) & (y >= 4)] = 3
    return label


def _mode_path(infos: list[dict]) -> list[str]:
    """The sequence of distinct consecutive modes."""
    path: list[str] = []
    for i in infos:
        if not path or path[-1] != i["mode_name"]:
            path.append(i["mode_name"])
    return path


def _holds(formula: str, sensors: dict[str, bool]) -> bool:
    """Evaluate a Spot-syntax boolean formula (``! & |`` and parentheses) on a sensor reading."""
    expr = formula.replace("!", " not ").replace("&", " and ").replace("|", " or ")
    expr = re.sub(
        r"\b([a-z]+)\b", lambda m: m.group(1) if m.group(1) in ("not", "and", "or") else f"s[{m.group(1)!r}]", expr
    )
    return bool(eval(expr, {"s": sensors}))  # formulas are module constants


def _run_expert_batch(
    starts: np.ndarray, *, steps: int = 2000, noise: float = 0.0, seed: int = 0, **expert_kwargs: str
) -> dict:
    """Roll the expert (plus optional action noise) in the vector env from ``starts``; first episode of each."""
    return run_expert_batch(
        ENV_ID,
        TASK,
        lambda env: CookingExpert(env, **expert_kwargs),
        starts,
        steps=steps,
        noise=noise,
        seed=seed,
        sensor_rows=True,
    )


# ----------------------------------------------------------------- seeding
def test_same_seed_gives_identical_trajectories_and_starts_in_white() -> None:
    check_seeded_start(ENV_ID, "w0")


def test_region_layout_matches_the_documented_rectangles() -> None:
    model = CookingEnv().model
    pts = np.vstack([np.random.default_rng(0).uniform(-8, 8, size=(5000, 2)), [[-2.0, 4.0], [2.0, 6.0], [0.0, 3.99]]])
    np.testing.assert_array_equal(model.regions(pts), _expected_label(pts))
    with pytest.raises(ValueError, match="name"):
        model.in_rect("blue", pts)


# ------------------------------------------------------------------ physics
def test_chicken_first_through_white_and_broccoli_through_the_pot() -> None:
    env = CookingEnv()
    infos = walk_from(env, (-4.5, -1.0), (-4.5, 6.0), (0.0, 6.0), (0.0, 0.0), (4.5, 0.0), (4.5, 6.0), (0.0, 6.0))
    assert _mode_path(infos) == ["w0", "y0", "dc", "wc", "gc", "done"]
    assert not any(i["constraint_violation"] for i in infos)
    final = infos[-1]["sensors"]
    assert infos[-1]["success"] and final == {"hc": False, "hb": False, "p": True, "ch": True, "br": True}
    # broccoli first, then the pot -> yellow -> pot shortcut (the thesis's d => y)
    infos = walk_from(env, (4.5, -1.0), (4.5, 6.0), (0.0, 6.0), (-3.0, 6.0), (0.0, 6.0))
    assert _mode_path(infos) == ["w0", "g0", "db", "yb", "done"]


def test_loading_needs_an_entry_from_white_or_the_pot() -> None:
    env = CookingEnv()
    infos = walk_from(env, (-4.5, 0.0), (-4.5, 2.0))
    assert infos[-1]["mode_name"] == "y0" and infos[-1]["sensors"]["hc"]
    info = env.perturb(to=np.array([-4.5, 5.0]))  # a push inside the corridor keeps the chicken
    assert info["mode_name"] == "y0"
    info = env.perturb(to=np.array([4.5, 5.0]))  # pushed from yellow into green: chicken lost, nothing loaded
    assert info["mode_name"] == "w0" and not info["constraint_violation"]
    assert env.perturb(to=np.array([-4.5, 5.0]))["mode_name"] == "w0"  # corridor to corridor never loads
    assert env.perturb(to=np.array([4.5, 5.0]))["mode_name"] == "w0"
    infos = walk_from(env, None, (4.5, 3.0))
    assert all(i["mode_name"] == "w0" for i in infos)  # an empty spoon in green stays empty ...
    infos = walk_from(env, None, (4.5, 0.0), (4.5, 2.0))  # ... until it leaves and comes back
    assert infos[-1]["mode_name"] == "g0"


def test_spilling_food_into_white_is_a_violation_and_loses_it() -> None:
    env = CookingEnv()
    infos = walk_from(env, (-4.5, 0.0), (-4.5, 3.0), (-8.0, 3.0), (-8.0, 0.0))
    flagged = [k for k, i in enumerate(infos) if i["constraint_violation"]]
    assert len(flagged) == 1 and infos[flagged[0] - 1]["mode_name"] == "y0"
    assert infos[flagged[0]]["mode_name"] == "w0" and not infos[-1]["sensors"]["ch"]
    # the same through the gap under the pot, with chicken already in the pot
    infos = walk_from(env, (-4.5, 0.0), (-4.5, 6.0), (0.0, 6.0), (0.0, 0.0), (4.5, 0.0), (4.5, 3.0), (0.0, 3.0))
    assert _mode_path(infos) == ["w0", "y0", "dc", "wc", "gc", "wc"]
    assert sum(i["constraint_violation"] for i in infos) == 1 and not infos[-1]["sensors"]["br"]


def test_an_empty_spoon_in_the_pot_adds_nothing_and_done_absorbs() -> None:
    env = CookingEnv()
    infos = walk_from(env, (0.0, 2.0), (0.0, 6.0), (0.0, 2.0))
    assert _mode_path(infos) == ["w0", "d0", "w0"]
    infos = walk_from(env, (-4.5, 0.0), (-4.5, 6.0), (0.0, 6.0), (3.0, 6.0), (0.0, 6.0))
    assert infos[-1]["success"] and infos[-1]["mode_name"] == "done"
    after = walk_from(env, None, (4.5, 6.0), (4.5, -2.0))  # ignoring termination: nothing is spilled any more
    assert all(i["mode_name"] == "done" and i["success"] and not i["constraint_violation"] for i in after)


def test_task_spec_modes_sensors_and_plans() -> None:
    assert TASK.sensors == ("hc", "hb", "p", "ch", "br") and TASK.initial == "w0" and TASK.goal == ("done",)
    assert TASK.shortest_plan("w0") in (["w0", "y0", "dc", "gc", "done"], ["w0", "g0", "db", "yb", "done"])
    assert TASK.shortest_plan("wc") == ["wc", "gc", "done"] and TASK.shortest_plan("wb") == ["wb", "yb", "done"]
    assert ("y0", "g0") not in TASK.transitions and ("y0", "w0") in TASK.transitions  # no yellow-green border
    assert gym.make(ENV_ID).unwrapped.task is TASK


def test_mode_ap_formulas_express_the_thesis_modes() -> None:
    for key, mode in TASK.sensor_modes.items():
        s = {ap: ap in key for ap in TASK.sensors}
        food = int(s["ch"]) + int(s["br"])
        coarse = [m for m in ("w", "y", "g", "d") if _holds(MODE_AP_FORMULAS[m], s)]
        assert len(coarse) == 1, (s, coarse)  # w, y, g, d partition the readings (phi_c, phi_cc)
        assert mode == "done" or mode[0] == coarse[0]
        fine = [m for m in ("w1", "w2", "d1", "d2") if _holds(MODE_AP_FORMULAS[m], s)]
        if coarse[0] == "w":  # phi_cb / phi_bc: white before (w1) and after (w2) the first food
            assert fine == (["w1"] if food == 0 else ["w2"])
        elif coarse[0] == "d":  # the pot after one (d1) or both (d2) foods; an empty pot is neither
            assert fine == ([f"d{food}"] if food else [])
        else:
            assert fine == []


def test_perturb_rejects_bad_arguments() -> None:
    env = CookingEnv()
    env.reset(seed=0)
    for bad in (np.array([np.nan, 0.0]), np.zeros(3)):
        with pytest.raises(ValueError, match="delta"):
            env.perturb(delta=bad)
    with pytest.raises(ValueError, match="exactly one"):
        env.perturb()
    with pytest.raises(TypeError, match="to"):
        env.perturb(to="pot")


# ------------------------------------------------------------- vector path
def test_vector_env_agrees_step_for_step_with_single_envs() -> None:
    n = 8
    finished, seen_violation = noisy_expert_vector_parity(
        ENV_ID, TASK, CookingEnv, lambda env: CookingExpert(env, route="direct"), n=n, sensor_rows=True
    )
    assert finished.sum() >= n // 2 and seen_violation, "the comparison must cover loading, spills and success"


# ------------------------------------------------------------------ expert
@pytest.mark.parametrize("order", ["cb", "bc"])
@pytest.mark.parametrize("route", ["white", "direct"])
def test_expert_succeeds_from_100_reset_seeds_in_the_requested_order(order: str, route: str) -> None:
    env = gym.make(ENV_ID)
    starts = np.stack([env.reset(seed=s)[0] for s in range(100)]).astype(np.float64)
    out = _run_expert_batch(starts, steps=env.spec.max_episode_steps, order=order, route=route)
    assert out["success"].mean() >= 0.99 and out["violations"] == 0
    assert out["steps"].max() < env.spec.max_episode_steps // 4
    first, second = ("y0", "gc") if order == "cb" else ("g0", "yb")
    expected = {("w0", first), (first, "d" + second[1]), (second, "done")}
    expected |= {("d" + second[1], "w" + second[1]), ("w" + second[1], second)} if route == "white" else set()
    expected |= {("d" + second[1], second)} if route == "direct" else set()
    assert out["pairs"] == expected


def test_expert_succeeds_from_any_state_and_noisy_rollouts_only_make_allowed_transitions() -> None:
    starts = np.random.default_rng(7).uniform(-8, 8, size=(200, 2))
    assert _run_expert_batch(starts)["success"].mean() >= 0.99
    noisy = _run_expert_batch(starts[:100], steps=1000, noise=25.0, seed=1)
    assert noisy["violations"] > 0, "heavy action noise must cause some spills"
    assert noisy["pairs"] <= TASK.transitions
    assert {("y0", "w0"), ("g0", "w0")} & noisy["pairs"]


def test_expert_rejects_bad_arguments_and_recovers_after_a_spill() -> None:
    with pytest.raises(ValueError, match="order"):
        CookingExpert(CookingEnv(), order="chicken")
    with pytest.raises(ValueError, match="route"):
        CookingExpert(CookingEnv(), route="air")
    with pytest.raises(TypeError, match="CookingEnv"):
        CookingExpert(gym.make(ENV_ID))
    env = gym.make(ENV_ID)
    expert = make_expert(env, order="bc")
    obs, info = env.reset(seed=0)

    def carrying(obs: Any, info: dict) -> bool:
        return info["mode_name"] == "yb" and obs[1] > 3.0

    push = {"to": np.array([-7.5, 3.0])}  # out of yellow: the chicken is lost
    modes, pushed_at, pushed_to, info = run_with_one_push(env, expert, obs, info, 2000, carrying, **push)
    assert pushed_at is not None and pushed_to == "wb" and info["success"]
    assert _mode_path([{"mode_name": m} for m in modes[pushed_at:]]) == ["wb", "yb", "done"]


# ------------------------------------------------------------------ render
def test_render_draws_the_thesis_colours() -> None:
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([0.0, 5.0], dtype=np.float32))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape == (256, 256, 3)
    palette = env.unwrapped.model.region_palette
    colours = {tuple(c) for c in np.unique(frame.reshape(-1, 3), axis=0)}
    assert {tuple(c) for c in palette} <= colours
    # pot (dark) at the top centre, chicken (yellow) top left, broccoli (green) top right
    assert tuple(frame[20, 128 + 10]) == tuple(palette[3])
    assert tuple(frame[40, 48]) == tuple(palette[1]) and tuple(frame[40, 208]) == tuple(palette[2])
    env.close()
