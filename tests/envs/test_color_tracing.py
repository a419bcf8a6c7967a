"""ColorTracing-v0: checkers, tile physics (chain, exits into D, re-entries per automaton), the expert, bad input."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from kinematic_helpers import walk
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import steer_envs  # noqa: F401
from steer_envs.data.demos import collect_demonstrations, rollout_expert
from steer_envs.envs.color_tracing import (
    AUTOMATA,
    DARK_MODES,
    EXIT_MODE,
    RECTS,
    REENTRY,
    TILES,
    ColorTracingEnv,
    ColorTracingModel,
    color_task,
    reentry_target,
)
from steer_envs.ltl import specs
from steer_envs.ltl.replanner import TaskAutomaton
from steer_envs.utils.env_checker import check_steer_env

ENV_ID = "steer_envs/ColorTracing-v0"


def _centre(tile: str) -> np.ndarray:
    x0, y0, x1, y1 = RECTS[tile]
    return np.array([(x0 + x1) / 2, (y0 + y1) / 2])


@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize("automaton", [None, "c"])
def test_checkers_pass(automaton: str | None) -> None:
    env = gym.make(ENV_ID, automaton=automaton)
    check_steer_env(env)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)
    env.close()


def test_task_matches_the_ltl_specs() -> None:
    """The env's modes, sensors and transitions are those of steer_envs.ltl.specs.color_tracing (a)-(c)."""
    assert color_task().modes == specs.COLOR_MODES and color_task().sensors == specs.COLOR_SENSORS
    assert specs.for_env(ENV_ID).name == "color_tracing_a"
    for a in AUTOMATA:
        edges = TaskAutomaton(color_task(a), specs.color_tracing(a)).mode_edges()
        assert edges == color_task(a).transitions
    assert (
        color_task().transitions
        == color_task("a").transitions | color_task("b").transitions | color_task("c").transitions
    )


def test_expert_demonstration_traces_every_tile_in_order() -> None:
    (demo,) = collect_demonstrations(ENV_ID, 1, seed=0)
    assert demo.success and list(dict.fromkeys(demo.modes.tolist())) == [0, 1, 2, 3, 4, 5]
    assert len(demo.states) < 300


def test_pushes_into_d_create_the_d_mode_of_the_tile_left() -> None:
    env = ColorTracingEnv()
    env.reset(seed=0)
    for tile, dark in EXIT_MODE.items():
        assert env.perturb(to=_centre(tile))["mode_name"] == tile
        info = env.perturb(delta=[0.0, 3.0])
        assert info["mode_name"] == dark and info["sensors"]["k"] and not info["constraint_violation"]
        assert sum(info["sensors"].values()) == 1  # D1..D4 read the same: only k
    assert env.task.label_of("dark4") == "dark_from_orange_or_pink"


def test_own_exits_and_steps_back_are_violations_the_chain_is_not() -> None:
    env = ColorTracingEnv()
    env.reset(options={"state": [-5.5, 0.0]})
    infos = walk(env, (-4.5, 0.0), (-3.5, 0.0), (-2.5, 0.0))
    assert [i["mode_name"] for i in infos][-1] == "blue" and not any(i["constraint_violation"] for i in infos)
    back = walk(env, (-4.5, 0.0))
    assert back[-1]["mode_name"] == "yellow" and sum(i["constraint_violation"] for i in back) == 1
    out = walk(env, (-4.5, 2.5))
    assert out[-1]["mode_name"] == "dark1" and sum(i["constraint_violation"] for i in out) == 1


@pytest.mark.parametrize("automaton", AUTOMATA)
def test_reentries_follow_the_automaton(automaton: str) -> None:
    env = ColorTracingEnv(automaton=automaton)
    for dark in DARK_MODES:
        tile = next(t for t, d in EXIT_MODE.items() if d == dark)
        for target in TILES[:-1]:
            env.reset(options={"state": _centre(tile)})
            env.perturb(to=_centre(tile) + np.array([0.0, 2.5]))
            env.perturb(to=_centre(target) + np.array([0.0, 1.6]))  # still in D, right above the target tile
            infos = walk(env, tuple(_centre(target)))
            entered = next(i for i in infos if i["mode_name"] != dark)
            assert entered["mode_name"] == target
            assert entered["constraint_violation"] == (REENTRY[automaton][dark] != target)


def test_red_from_d_is_a_violation_and_success_latches() -> None:
    env = ColorTracingEnv()
    env.reset(options={"state": _centre("pink")})
    env.perturb(delta=[0.0, 2.5])
    info = walk(env, (5.0, 1.0))[-1]
    assert info["success"] and info["mode_name"] == "red"
    env.reset(options={"state": _centre("pink")})
    _, reward, terminated, _, info = env.step(np.array([10.0, 0.0], dtype=np.float32))
    while not terminated:
        _, reward, terminated, _, info = env.step(np.array([10.0, 0.0], dtype=np.float32))
    assert info["success"] and reward == 1.0 and not info["constraint_violation"]


def test_reentry_target_routes_through_d_only() -> None:
    """Following reentry_target from anywhere in D enters the chosen tile first."""
    model = ColorTracingModel()
    rng = np.random.default_rng(0)
    starts = rng.uniform(-7.5, 7.5, size=(400, 2))
    starts = starts[model.regions(starts) == 0][:120]
    for tile in range(len(TILES)):
        pos = starts.copy()
        first = np.full(len(pos), -1)
        for _ in range(600):
            step = reentry_target(pos, tile) - pos
            speed = np.linalg.norm(step, axis=1, keepdims=True)
            pos = pos + step * np.minimum(1.0, 0.1 / np.maximum(speed, 1e-12))
            reg = model.regions(pos)
            first = np.where((first < 0) & (reg > 0), reg - 1, first)
        assert np.all(first == tile), (tile, np.unique(first))


@pytest.mark.parametrize("automaton", AUTOMATA)
def test_expert_recovers_from_pushes_as_the_automaton_says(automaton: str) -> None:
    env = gym.make(ENV_ID, automaton=automaton)
    from steer_envs.data.experts import make_expert

    expert = make_expert(env)
    obs, info = env.reset(seed=1)
    expert.reset(obs, info)
    pushed = False
    violations = 0
    modes = []
    for _ in range(1000):
        if info["mode_name"] == "green" and not pushed:
            info = env.unwrapped.perturb(delta=[0.0, -3.0])
            obs, pushed = env.unwrapped.state.astype(np.float32), True
        obs, _, terminated, _, info = env.step(expert.act(obs, info))
        violations += info["constraint_violation"]
        modes.append(info["mode_name"])
        if terminated:
            break
    assert info["success"] and violations == 0
    after = [m for m in modes[modes.index("dark3") :] if m != "dark3"]
    assert after[0] == REENTRY[automaton]["dark3"]


def test_render_draws_the_tiles_in_their_colours() -> None:
    env = ColorTracingEnv(render_mode="rgb_array", render_size=160)
    env.reset(seed=0)
    frame = env.render()
    assert frame is not None and frame.shape == (160, 160, 3)
    palette = env.model.region_palette
    for i, tile in enumerate(TILES):
        x, y = _centre(tile) + np.array([0.3, -1.0])
        col, row = int((x + 8) / 16 * 160), int((8 - y) / 16 * 160)
        assert frame[row, col].tolist() == palette[i + 1].tolist(), tile
    assert frame[5, 5].tolist() == palette[0].tolist()


def test_bad_input_names_the_argument() -> None:
    with pytest.raises(ValueError, match="automaton"):
        ColorTracingEnv(automaton="d")
    with pytest.raises(TypeError, match="automaton"):
        ColorTracingEnv(automaton=1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="automaton"):
        color_task("x")
    with pytest.raises(ValueError, match="tile"):
        reentry_target(np.zeros((1, 2)), 6)
    with pytest.raises(TypeError, match="env"):
        from steer_envs.data.experts.color_tracing import ColorTracingExpert

        ColorTracingExpert(object())  # type: ignore[arg-type]
    env = ColorTracingEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="delta"):
        env.perturb(delta=[np.nan, 0.0])
    with pytest.raises(ValueError, match="max_speed"):
        ColorTracingEnv(max_speed=-1.0)


def test_rollout_expert_is_seeded() -> None:
    env = gym.make(ENV_ID)
    a, b = rollout_expert(env, 3), rollout_expert(env, 3)
    np.testing.assert_array_equal(a.states, b.states)
    env.close()


def test_batched_expert_matches_single_env_experts() -> None:
    from steer_envs.data.experts import make_expert

    venv = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point")
    obs, info = venv.reset(seed=4)
    venv.unwrapped.perturb(np.array([[0.0, 0.0], [-3.0, 4.0], [3.0, -4.0]]), np.array([False, True, True]))
    obs, info = venv.step(np.zeros((3, 2), dtype=np.float32))[::4]
    batched = make_expert(gym.make(ENV_ID)).act(obs, info)
    assert batched.shape == (3, 2)
    for i in range(3):  # agent i is a single env seeded 4 + i, pushed and stepped the same way
        single = gym.make(ENV_ID)
        single.reset(seed=4 + i)
        if i:
            single.unwrapped.perturb(to=[-3.0, 4.0] if i == 1 else [3.0, -4.0])
        single_obs, *_, single_info = single.step(np.zeros(2, dtype=np.float32))
        assert single_info["mode_name"] == ("yellow", "dark1", "dark1")[i]
        np.testing.assert_allclose(make_expert(single).act(single_obs, single_info), batched[i], atol=1e-5)
    venv.close()
