"""Every registered env refuses arguments that can never work, and never coerces actions or pushes.

Constructors and ``reset(options=...)`` raise a ``TypeError`` (wrong kind) or
``ValueError`` (wrong value) naming the argument; ``step`` and ``perturb`` take
one validation path (strings, complex numbers, bools, objects and NaN are
refused; a tensor that requires grad is read detached; finite out-of-space
actions keep their documented clip); rejection samplers raise
``BoundExceeded`` naming their bound.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import steer_envs  # noqa: F401
from steer_envs.core.validation import BoundExceeded
from steer_envs.envs import convex_mode, polygon_nav
from steer_envs.envs.convex_mode import ConvexModeEnv, ConvexModeModel
from steer_envs.envs.cooking import CookingEnv
from steer_envs.envs.maze2d import Maze2DEnv
from steer_envs.envs.maze_grid import MazeGrid, maze_map
from steer_envs.envs.polygon_nav import PolygonNavEnv, PolygonNavModel
from steer_envs.envs.registry import ENTRIES, env_ids
from steer_envs.envs.soup_scoop import SoupScoopEnv

KINEMATIC = env_ids(kinematic_only=True)
ALL = env_ids()


@pytest.fixture(scope="module")
def made() -> dict[str, Any]:
    envs = {i: gym.make(i).unwrapped for i in ALL}
    yield envs
    for env in envs.values():
        env.close()


# ------------------------------------------------------------------ constructors
KINEMATIC_BAD: list[tuple[type, dict[str, Any], type[Exception], str]] = [
    (SoupScoopEnv, {"render_size": -1}, ValueError, "render_size"),
    (SoupScoopEnv, {"render_size": 10**6}, ValueError, "render_size"),
    (SoupScoopEnv, {"render_size": 256.0}, TypeError, "render_size"),
    (SoupScoopEnv, {"render_size": "256"}, TypeError, "render_size"),
    (SoupScoopEnv, {"dt": "0.01"}, TypeError, "dt"),
    (SoupScoopEnv, {"dt": math.nan}, ValueError, "dt"),
    (SoupScoopEnv, {"max_speed": 1 + 2j}, TypeError, "max_speed"),
    (SoupScoopEnv, {"max_speed": -1.0}, ValueError, "max_speed"),
    (SoupScoopEnv, {"sensor_convention": ["public"]}, TypeError, "sensor_convention"),
    (SoupScoopEnv, {"render_mode": "depth_array"}, ValueError, "render_mode"),
    (SoupScoopEnv, {"render_mode": 1}, TypeError, "render_mode"),
    (CookingEnv, {"dt": True}, TypeError, "dt"),
    (CookingEnv, {"render_size": 0}, ValueError, "render_size"),
    (ConvexModeEnv, {"start_noise": 1e9}, ValueError, "start_noise"),
    (ConvexModeEnv, {"start_noise": "1.0"}, TypeError, "start_noise"),
    (ConvexModeEnv, {"start_noise": math.inf}, ValueError, "start_noise"),
    (ConvexModeEnv, {"layout_seed": "3"}, TypeError, "layout_seed"),
    (ConvexModeEnv, {"layout_seed": 3.0}, TypeError, "layout_seed"),
    (ConvexModeEnv, {"layout_seed": True}, TypeError, "layout_seed"),
    (ConvexModeEnv, {"layout_seed": -1}, ValueError, "layout_seed"),
    (ConvexModeEnv, {"terminate_on_violation": "no"}, TypeError, "terminate_on_violation"),
    (ConvexModeEnv, {"terminate_on_violation": 0}, TypeError, "terminate_on_violation"),
    (PolygonNavEnv, {"terminate_on_violation": "no"}, TypeError, "terminate_on_violation"),
    (PolygonNavEnv, {"layout_seed": np.float64(2.0)}, TypeError, "layout_seed"),
    (PolygonNavEnv, {"num_modes": "4"}, TypeError, "num_modes"),
    (PolygonNavEnv, {"num_modes": 10}, ValueError, "num_modes"),
    (PolygonNavEnv, {"min_gap": "0.5"}, TypeError, "min_gap"),
    (PolygonNavEnv, {"workspace_margin": 2.0}, ValueError, "workspace_margin"),
]


@pytest.mark.parametrize(("cls", "kwargs", "exc", "name"), KINEMATIC_BAD)
def test_kinematic_constructors_refuse_arguments_that_can_never_work(
    cls: type, kwargs: dict[str, Any], exc: type[Exception], name: str
) -> None:
    with pytest.raises(exc, match=name):
        cls(**kwargs)


MAZE_BAD: list[tuple[dict[str, Any], type[Exception], str]] = [
    ({"maze": "Large"}, ValueError, "maze"),
    ({"maze": 5}, TypeError, "maze layout"),
    ({"maze": [[1, 1, 1], [1, "1", 1], [1, 0, 1]]}, ValueError, r"cell \(1, 1\)"),
    ({"maze": [[1, 1, 1], [1, True, 1], [1, 0, 1]]}, TypeError, r"cell \(1, 1\)"),
    ({"maze": [[1, 1, 1], [1, 1.0, 1], [1, 0, 1]]}, TypeError, r"cell \(1, 1\)"),
    ({"maze": [[1, 1, 1], [1, 2, 1], [1, 0, 1]]}, ValueError, r"cell \(1, 1\)"),
    ({"maze": [[1, 1], [1, None]]}, TypeError, r"cell \(1, 1\)"),
    ({"maze": np.array(maze_map("umaze"), dtype=str)}, ValueError, "cell"),
    ({"maze": "1111"}, ValueError, "maze"),
    ({"maze": [[0] * 101]}, ValueError, "at most 100"),
    ({"frame_skip": "4"}, TypeError, "frame_skip"),
    ({"frame_skip": 10**9}, ValueError, "frame_skip"),
    ({"observe_velocity": "no"}, TypeError, "observe_velocity"),
    ({"sample_goal": "no"}, TypeError, "sample_goal"),
    ({"sample_goal": 1}, TypeError, "sample_goal"),
    ({"cell_px": -1}, ValueError, "cell_px"),
    ({"cell_px": 10**5}, ValueError, "cell_px"),
    ({"cell_px": True}, TypeError, "cell_px"),
    ({"render_mode": "depth_array"}, ValueError, "render_mode"),
]


@pytest.mark.parametrize(("kwargs", "exc", "match"), MAZE_BAD)
def test_maze_constructor_refuses_arguments_that_can_never_work(
    kwargs: dict[str, Any], exc: type[Exception], match: str
) -> None:
    kwargs = {"maze": "umaze", **kwargs}
    with pytest.raises(exc, match=match):
        Maze2DEnv(**kwargs)


def test_maze_custom_maps_take_ints_and_the_documented_markers() -> None:
    grid = MazeGrid([[1, 1, 1, 1], [1, "r", np.int64(0), 1], [1, "g", "c", 1], [1, 1, 1, 1]])
    assert grid.walls.sum() == 12 and len(grid.free_cells) == 4
    env = Maze2DEnv([[1, 1, 1], [1, 0, 1], [1, 0, 1], [1, 1, 1]])
    assert env.maze_name == "custom" and env.reset(seed=0)[0].shape == (2,)


@pytest.mark.parametrize("env_id", ALL)
def test_gym_make_refuses_bad_kwargs_of_every_registered_env(env_id: str) -> None:
    with pytest.raises((TypeError, ValueError), match="render_mode"):
        gym.make(env_id, render_mode="no")
    if "Maze2D" in env_id:
        with pytest.raises(TypeError, match="sample_goal"):
            gym.make(env_id, sample_goal="no")
    else:
        with pytest.raises(ValueError, match="render_size"):
            gym.make(env_id, render_size=-1)


# --------------------------------------------------------------------- reset
@pytest.mark.parametrize("env_id", ALL)
def test_reset_options_and_seed_are_checked(made: dict[str, Any], env_id: str) -> None:
    env = made[env_id]
    for options, exc, match in (
        ({"state": ["1", "2"]}, TypeError, "state"),
        ({"state": [1 + 1j, 2.0]}, TypeError, "state"),
        ({"state": [math.nan, 1.0]}, ValueError, "state"),
        ({"state": [True, False]}, TypeError, "state"),
        ({"stat": [1.0, 1.0]}, ValueError, "unknown reset options"),
        ([("state", [1.0, 1.0])], TypeError, "options"),
    ):
        with pytest.raises(exc, match=match):
            env.reset(options=options)
    for seed, exc in (("0", TypeError), (1.5, TypeError), (-1, ValueError), (True, TypeError)):
        with pytest.raises(exc, match="seed"):
            env.reset(seed=seed)
    a, _ = env.reset(seed=np.int64(3))
    b, _ = env.reset(seed=3)
    np.testing.assert_array_equal(a, b)


# ----------------------------------------------------------------- step, perturb
BAD_ACTIONS: list[tuple[Any, type[Exception]]] = [
    (["1", "2"], TypeError),
    ("12", TypeError),
    (np.array([1 + 2j, 0j]), TypeError),
    ([1 + 0j, 0.0], TypeError),
    (np.array([True, False]), TypeError),
    (np.array([0.1, 0.2], dtype=object), TypeError),
    ([None, 0.1], TypeError),
    ({"x": 0.1, "y": 0.2}, TypeError),
    ([math.nan, 0.0], ValueError),
    ([0.0, math.inf], ValueError),
    (WRONG_LENGTH := object(), ValueError),  # replaced by an array one entry too long for the argument
    ([[0.0, 0.0]], ValueError),
    ([[0.0], [0.0, 1.0]], ValueError),
]


@pytest.mark.parametrize("env_id", ALL)
def test_step_and_perturb_take_one_validation_path(made: dict[str, Any], env_id: str) -> None:
    env = made[env_id]
    env.reset(seed=0)
    before = env.state
    action_dim, state_dim = env.action_space.shape[0], before.shape[0]
    for bad, exc in BAD_ACTIONS:
        with pytest.raises(exc, match="action"):
            env.step(np.zeros(action_dim + 1) if bad is WRONG_LENGTH else bad)
        for name in ("delta", "to"):
            with pytest.raises(exc, match=name):
                env.perturb(**{name: np.zeros(state_dim + 1) if bad is WRONG_LENGTH else bad})
    np.testing.assert_array_equal(env.state, before)  # nothing refused moved the agent


@pytest.mark.parametrize("env_id", ALL)
def test_a_tensor_that_requires_grad_acts_like_its_values(env_id: str) -> None:
    a, b = gym.make(env_id).unwrapped, gym.make(env_id).unwrapped
    a.reset(seed=1)
    b.reset(seed=1)
    action = a.action_space.sample() * 0.5 + (a.action_space.low + a.action_space.high) * 0.25
    tensor = torch.tensor(action, requires_grad=True)
    obs_a = a.step(tensor)[0]
    obs_b = b.step(np.asarray(action))[0]
    np.testing.assert_array_equal(obs_a, obs_b)
    assert tensor.grad is None
    delta = np.zeros(a.state.shape[0])
    delta[0] = 0.01
    push = torch.tensor(delta, dtype=torch.float64, requires_grad=True)
    assert a.perturb(delta=push)["mode"] == b.perturb(delta=delta)["mode"]
    np.testing.assert_array_equal(a.state, b.state)
    a.close()
    b.close()


@pytest.mark.parametrize("env_id", KINEMATIC)
def test_finite_out_of_space_actions_keep_their_clip(made: dict[str, Any], env_id: str) -> None:
    env = made[env_id]
    for huge in ([1e308, 1e308], [-1e300, 5.0], [1e6, 0.0]):
        env.reset(seed=0)
        start = env.state
        env.step(np.array(huge))
        moved = env.state - start
        assert np.linalg.norm(moved) <= env.dt * env.max_speed + 1e-9
        direction = np.asarray(huge) / np.max(np.abs(huge))
        if not np.any(np.isclose(env.state, env.model.low) | np.isclose(env.state, env.model.high)):
            assert np.dot(moved, direction) > 0  # the direction is kept, not zeroed by an overflow


def test_maze_waypoints_outside_the_grid_are_clipped(made: dict[str, Any]) -> None:
    env = made["steer_envs/Maze2D-Umaze-v0"]
    env.reset(seed=0, options={"state": [1.0, 1.0]})
    env.step(np.array([1e300, -1e300]))
    assert np.all(np.isfinite(env.state))


@pytest.mark.parametrize("env_id", KINEMATIC)
def test_vector_env_validates_actions_states_and_masks(env_id: str) -> None:
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    base = venv.unwrapped
    venv.reset(seed=0)
    with pytest.raises(TypeError, match="actions"):
        venv.step(np.array([["1", "2"]] * 3))
    with pytest.raises(TypeError, match="actions"):
        venv.step(np.zeros((3, 2), dtype=complex))
    with pytest.raises(ValueError, match="actions"):
        venv.step(np.full((3, 2), math.nan))
    with pytest.raises(TypeError, match="state"):
        venv.reset(options={"state": np.zeros((3, 2), dtype=bool)})
    with pytest.raises(TypeError, match="mask"):
        base.perturb(np.zeros((3, 2)), np.array([1, 0, 1]))
    with pytest.raises(TypeError, match="mask"):
        base.perturb(np.zeros((3, 2)), ["no", "no", "no"])
    with pytest.raises(ValueError, match="to"):
        base.perturb(np.full((3, 2), math.nan), np.array([True, False, False]))
    to = np.full((3, 2), math.nan)
    to[1] = [0.5, 0.5]
    base.perturb(to, np.array([False, True, False]))  # NaN in rows that are not pushed is fine
    with pytest.raises(TypeError, match="num_envs"):
        gym.make_vec(env_id, num_envs="3", vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="num_envs"):
        gym.make_vec(env_id, num_envs=10**9, vectorization_mode="vector_entry_point")
    venv.close()


# -------------------------------------------------------------- bounded samplers
def test_rejection_samplers_raise_bound_exceeded_naming_the_bound(monkeypatch: pytest.MonkeyPatch) -> None:
    model = ConvexModeModel(layout_seed=0, start_noise=convex_mode.MAX_START_NOISE)
    monkeypatch.setattr(convex_mode, "MAX_START_ROUNDS", 1)
    with pytest.raises(BoundExceeded, match="MAX_START_ROUNDS=1"):
        model.sample_start(np.random.default_rng(0), 2000)
    nav = PolygonNavModel(3, 0)
    monkeypatch.setattr(polygon_nav, "MAX_SAMPLE_ROUNDS", 1)
    with pytest.raises(BoundExceeded, match="MAX_SAMPLE_ROUNDS=1"):
        nav.sample_in_mode(np.random.default_rng(0), 500, 1)
    monkeypatch.setattr(polygon_nav, "MAX_LAYOUT_TRIES", 0)
    with pytest.raises(BoundExceeded, match="MAX_LAYOUT_TRIES=0"):
        PolygonNavModel(3, 0)
    with pytest.raises(TypeError, match="mode"):
        nav.sample_in_mode(np.random.default_rng(0), 5, "1")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="n"):
        nav.sample_in_mode(np.random.default_rng(0), 5.0, 1)  # type: ignore[arg-type]


def test_the_widest_start_noise_still_starts_inside_the_mode() -> None:
    env = ConvexModeEnv(layout_seed=0, start_noise=convex_mode.MAX_START_NOISE)
    for seed in range(5):
        _, info = env.reset(seed=seed)
        assert info["mode_name"] == "inside"


# ------------------------------------------------------------------ properties
_junk = st.one_of(
    st.text(max_size=4),
    st.complex_numbers(allow_nan=True),
    st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(),
    st.none(),
    st.integers(min_value=-(10**20), max_value=10**20),
    st.lists(st.one_of(st.text(max_size=2), st.floats(allow_nan=True), st.booleans(), st.none()), max_size=3),
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.sampled_from([*KINEMATIC, "steer_envs/Maze2D-Umaze-v0"]), st.lists(_junk, min_size=0, max_size=3))
def test_property_step_and_perturb_refuse_or_clip(made: dict[str, Any], env_id: str, values: list) -> None:
    env = made[env_id]
    env.reset(seed=0)
    for call in (env.step, lambda v: env.perturb(delta=v), lambda v: env.perturb(to=v)):
        try:
            call(values)
        except (TypeError, ValueError):
            continue
        # accepted: two real, finite numbers, and the state stayed inside the workspace / grid
        assert len(values) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values
        )
        assert np.all(np.isfinite(env.state))
        assert env.observation_space.contains(env._obs()) or "Maze2D" in env_id


_KWARGS = {
    "steer_envs/ConvexMode-v0": (
        "layout_seed",
        "start_noise",
        "terminate_on_violation",
        "dt",
        "max_speed",
        "render_size",
    ),
    "steer_envs/SoupScoop-v0": ("dt", "max_speed", "sensor_convention", "render_size"),
    "steer_envs/Cooking-v0": ("dt", "max_speed", "render_size"),
    "steer_envs/PolygonNav-3Mode-v0": (
        "layout_seed",
        "terminate_on_violation",
        "workspace_margin",
        "min_gap",
        "render_size",
    ),
    "steer_envs/Maze2D-Umaze-v0": ("frame_skip", "observe_velocity", "sample_goal", "cell_px", "relative_actions"),
}


@settings(max_examples=80, deadline=None)
@given(st.sampled_from(sorted(_KWARGS)), st.data())
def test_property_constructors_refuse_junk(env_id: str, data: st.DataObject) -> None:
    name = data.draw(st.sampled_from(_KWARGS[env_id]))
    value = data.draw(_junk)
    try:
        env = gym.make(env_id, **{name: value})
    except (TypeError, ValueError) as err:
        assert name in str(err)
        return
    # accepted: a value of the right kind (never a string, a complex number or a list)
    assert (not isinstance(value, (str, complex, list)) and value is not None) or name == "start_noise"
    env.close()


def test_registry_covers_every_constructor_tested_here() -> None:
    assert {e.entry_point.split(":")[1] for e in ENTRIES} == {
        "SoupScoopEnv",
        "ConvexModeEnv",
        "CookingEnv",
        "InspectionLineEnv",  # a kinematic domain: its constructor is the shared one tested here
        "ColorTracingEnv",  # a kinematic domain (its `automaton`: tests/envs/test_color_tracing.py)
        "PolygonNavEnv",
        "Maze2DEnv",
        "Maze2DGoalEnv",  # Maze2DEnv(goal_conditioned=True): tests/envs/test_rl_variants.py
        "RobosuiteEnv",  # its constructor arguments: tests/envs/test_robosuite.py
        "BlockStackEnv",  # its constructor arguments: tests/envs/test_blockstack.py
        "ArmScoopEnv",  # its constructor arguments: tests/envs/test_arm_scoop.py
        "KitchenEnv",  # its constructor arguments: tests/envs/test_kitchen.py
    }
