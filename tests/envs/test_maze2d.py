"""Maze2D: MuJoCo point mass, ITPS geometry helpers, PD tracking, perturbation, rendering, expert."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.data.experts import make_expert
from steer_envs.data.experts.maze2d import Maze2DExpert
from steer_envs.envs.maze2d import Maze2DEnv
from steer_envs.envs.maze_grid import AGENT_RADIUS, MazeGrid, maze_map
from steer_envs.envs.maze_physics import MazePhysics

# LARGE_MAZE (9 x 12), row 0 on top:
#   ############      row 1: free cols 1-4 and 6-10
#   #....#.....#      row 2: free cols 1, 4, 6, 8, 10
#   #.##.#.#.#.#      row 3: free cols 1-6 and 8-10
#   #......#...#
#   #.####.###.#
#   #..#.#.....#
#   ##.#.#.#.###
#   #..#...#...#
#   ############


@pytest.fixture(scope="module")
def large() -> Maze2DEnv:
    return Maze2DEnv("large")


def test_maps_come_from_gymnasium_robotics() -> None:
    assert MazeGrid(maze_map("large")).shape == (9, 12)
    assert MazeGrid(maze_map("medium")).shape == (8, 8)
    assert MazeGrid(maze_map("umaze")).shape == (5, 5)
    with pytest.raises(ValueError, match="maze"):
        maze_map("huge")
    with pytest.raises(ValueError, match="rectangular"):
        MazeGrid([[1, 1], [1]])


@pytest.mark.filterwarnings("ignore:.*symmetric and normalized:UserWarning")  # actions are absolute waypoints
@pytest.mark.parametrize("kwargs", [{"maze": "large"}, {"maze": "umaze", "observe_velocity": True}])
def test_gymnasium_and_sb3_checkers_pass_with_rendering(kwargs: dict) -> None:
    name = {"large": "Large", "umaze": "Umaze"}[kwargs.pop("maze")]
    env = gym.make(f"steer_envs/Maze2D-{name}-v0", render_mode="rgb_array", **kwargs).unwrapped
    gym_check_env(env)
    sb3_check_env(env, warn=False)
    assert env.observation_space.shape == ((4,) if kwargs.get("observe_velocity") else (2,))


def _rollout(seed: int, steps: int = 60) -> np.ndarray:
    env = gym.make("steer_envs/Maze2D-Large-v0", observe_velocity=True)
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    states = [obs]
    for _ in range(steps):
        obs, *_ = env.step(env.action_space.sample())
        states.append(obs)
    return np.asarray(states)


def test_same_seed_gives_identical_trajectories() -> None:
    np.testing.assert_array_equal(_rollout(4), _rollout(4))
    assert not np.array_equal(_rollout(4), _rollout(5))


def test_cell_xy_round_trip(large: Maze2DEnv) -> None:
    rows, cols = large.grid.shape
    cells = np.stack(np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"), -1).reshape(-1, 2)
    np.testing.assert_array_equal(large.xy_to_cell(large.cell_to_xy(cells)), cells)
    jitter = np.random.default_rng(0).uniform(-0.49, 0.49, size=cells.shape)
    np.testing.assert_array_equal(large.xy_to_cell(large.cell_to_xy(cells) + jitter), cells)
    # rounding is half-up and points off the grid are clipped onto it
    np.testing.assert_array_equal(large.xy_to_cell(np.array([[1.49, 2.5], [-3.0, 40.0]])), [[1, 3], [0, 11]])
    assert large.extent == 9.0
    assert large.is_wall(np.array([0.0, 0.0])) and not large.is_wall(np.array([1.0, 1.0]))


def test_plan_collides_on_hand_made_plans(large: Maze2DEnv) -> None:
    free_row = np.stack([np.full(20, 1.0), np.linspace(1.0, 4.0, 20)], -1)  # along row 1, cols 1..4
    through_wall = np.stack([np.full(20, 1.0), np.linspace(1.0, 7.0, 20)], -1)  # crosses wall (1, 5)
    down_col1 = np.stack([np.linspace(1.0, 5.0, 20), np.full(20, 1.0)], -1)  # column 1 is free in rows 1-5
    grazing = free_row.copy()
    grazing[7] = [1.0, 5.45]  # one waypoint rounds into the wall cell (1, 5)
    off_grid = free_row.copy()
    off_grid[3] = [-2.0, 2.0]  # clipped to row 0: the border wall
    plans = np.stack([free_row, through_wall, down_col1, grazing, off_grid])
    np.testing.assert_array_equal(large.plan_collides(plans), [False, True, False, True, True])
    np.testing.assert_array_equal(large.plan_collides(plans.reshape(5, 1, 20, 2))[:, 0], large.plan_collides(plans))
    assert large.plan_collides(free_row).shape == ()
    with pytest.raises(ValueError, match="plans"):
        large.plan_collides(np.zeros((4, 3)))
    with pytest.raises(ValueError, match="plans"):
        large.plan_collides(np.full((2, 2), np.nan))


def test_pd_actuator_is_exactly_the_d4rl_law() -> None:
    physics = MazePhysics(MazeGrid(maze_map("large")))
    rng = np.random.default_rng(1)
    for _ in range(20):
        pos, vel = np.array([3.0, 3.0]) + rng.uniform(-0.3, 0.3, 2), rng.normal(size=2) * 3
        waypoint = pos + rng.normal(size=2) * 0.2
        physics.set_state(pos, vel)
        physics.step(waypoint, 1)
        np.testing.assert_allclose(physics.control(), np.clip(10 * (waypoint - pos) - vel, -1, 1), atol=1e-9)


def test_pd_tracking_reaches_a_waypoint(large: Maze2DEnv) -> None:
    large.reset(seed=0, options={"state": [1.0, 1.0], "goal_cell": None})
    waypoint = np.array([1.0, 3.0], dtype=np.float32)  # two cells along the free row 1
    for _ in range(40):  # 1.6 s
        _, _, terminated, _, info = large.step(waypoint)
        assert not terminated and not info["constraint_violation"]
    assert np.linalg.norm(large.state - waypoint) < 0.02
    assert np.linalg.norm(large.velocity) < 0.2
    assert large.dt == pytest.approx(0.04)


def test_pushing_into_a_wall_flags_a_constraint_violation(large: Maze2DEnv) -> None:
    large.reset(seed=0, options={"state": [1.0, 1.0], "goal_cell": None})
    flags = [large.step(np.array([1.0, 0.0], dtype=np.float32))[4]["constraint_violation"] for _ in range(25)]
    assert any(flags)
    assert large.state[1] > 0.5 + AGENT_RADIUS - 0.01  # the wall held
    assert large.step(np.array([1.0, 0.0], dtype=np.float32))[4]["sensors"]["in_wall_contact"]
    # moving away from the wall ends the contact
    for _ in range(25):
        info = large.step(np.array([1.0, 2.0], dtype=np.float32))[4]
    assert not info["constraint_violation"] and not info["sensors"]["in_wall_contact"]


def test_goal_cell_success_and_termination(large: Maze2DEnv) -> None:
    _, info = large.reset(seed=0, options={"state": [1.0, 1.0], "goal_cell": (1, 3)})
    assert not info["success"] and large.goal_cell == (1, 3)
    for _ in range(100):
        _, reward, terminated, _, info = large.step(np.array([1.0, 3.0], dtype=np.float32))
        if terminated:
            break
    assert terminated and info["success"] and reward == 1.0 and info["sensors"]["at_goal"]
    assert large.xy_to_cell(large.state).tolist() == [1, 3]
    free = Maze2DEnv("umaze", sample_goal=False)
    _, info = free.reset(seed=0)
    assert free.goal_cell is None and not info["success"]


def test_reset_options_are_validated(large: Maze2DEnv) -> None:
    with pytest.raises(ValueError, match="wall"):
        large.reset(options={"state": [0.0, 0.0]})
    with pytest.raises(ValueError, match="goal_cell"):
        large.reset(options={"goal_cell": (0, 0)})
    with pytest.raises(TypeError, match="goal_cell"):  # a float is the wrong kind for a cell index
        large.reset(options={"goal_cell": (1.5, 2.0)})
    with pytest.raises(ValueError, match="unknown reset options"):
        large.reset(options={"start": [1.0, 1.0]})
    obs, _ = large.reset(options={"state": [1.0, 0.55]})  # too close to the wall: nudged off it
    assert obs[1] >= 0.5 + AGENT_RADIUS - 1e-6
    with pytest.raises(ValueError, match="action"):
        large.step(np.zeros(3, dtype=np.float32))
    with pytest.raises(ValueError, match="frame_skip"):
        Maze2DEnv("umaze", frame_skip=0)


def test_perturb_moves_the_simulator_and_stops_at_walls(large: Maze2DEnv) -> None:
    large.reset(seed=0, options={"state": [3.0, 2.0]})
    info = large.perturb(delta=np.array([0.0, 0.3]))
    assert info["perturbed"] is True and not info["constraint_violation"]
    np.testing.assert_allclose(large.state, [3.0, 2.3])
    np.testing.assert_allclose(large.physics.data.qpos[:2], [3.0, 2.3])
    large.perturb(to=np.array([7.0, 9.0]))
    np.testing.assert_allclose(large.state, [7.0, 9.0])
    large.perturb(to=np.array([2.0, 2.0]))  # a wall cell: placed at the nearest free position
    assert not large.is_wall(large.state)
    assert large.grid.clearance(large.state) >= AGENT_RADIUS - 1e-9
    assert np.linalg.norm(large.state - [2.0, 2.0]) < 0.7
    with pytest.raises(ValueError, match="delta"):
        large.perturb(delta=np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="shape"):
        large.perturb(delta=np.zeros(3))
    with pytest.raises(ValueError, match="exactly one"):
        large.perturb()
    with pytest.raises(ValueError, match="exactly one"):
        large.perturb(delta=np.zeros(2), to=np.zeros(2))
    with pytest.raises(TypeError, match="to"):
        large.perturb(to="left")


def test_project_free_keeps_the_agent_off_every_wall() -> None:
    grid = MazeGrid(maze_map("medium"))
    points = np.random.default_rng(0).uniform(-1.0, 8.0, size=(300, 2))
    placed = np.array([grid.project_free(p) for p in points])
    assert not grid.is_wall(placed).any()
    assert grid.clearance(placed).min() >= AGENT_RADIUS - 1e-9
    free_enough = grid.clearance(points) >= AGENT_RADIUS + 1e-6
    free_enough &= ~grid.is_wall(points) & np.all((points > -0.5) & (points < 7.5), axis=1)
    np.testing.assert_allclose(placed[free_enough], points[free_enough])  # valid points are left alone


def test_rendering_draws_maze_agent_sketch_and_plans() -> None:
    env = Maze2DEnv("large", render_mode="rgb_array", cell_px=16)
    env.reset(seed=0, options={"state": [1.0, 1.0], "goal_cell": (7, 10)})
    env.step(np.array([1.0, 2.0], dtype=np.float32))
    frame = env.render()
    assert frame.shape == (9 * 16, 12 * 16, 3) and frame.dtype == np.uint8
    assert tuple(frame[8, 8]) == (90, 90, 100)  # cell (0, 0) is a wall
    assert tuple(frame[7 * 16 + 8, 10 * 16 + 8]) == (170, 230, 170)  # the goal cell
    plans = np.stack([np.linspace([3.0, 1.0], [3.0, 6.0], 32), np.linspace([3.0, 1.0], [5.0, 2.0], 32)])
    image = env.render_overlay(sketch=np.array([[1.0, 1.0], [1.0, 4.0], [3.0, 4.0]]), plans=plans)
    colours = {tuple(c) for c in image.reshape(-1, 3)}
    assert {(200, 30, 200), (20, 160, 160), (240, 140, 30), (220, 30, 30)} <= colours
    np.testing.assert_allclose(env.pixel_to_xy(4 * 16 + 8, 2 * 16 + 8), [2.0, 4.0])
    assert Maze2DEnv("umaze").render() is None


def test_expert_reaches_the_goal_from_random_starts() -> None:
    env = gym.make("steer_envs/Maze2D-Large-v0")
    expert = make_expert(env)
    rng = np.random.default_rng(0)
    free = env.unwrapped.grid.free_cells
    successes = 0
    for _ in range(20):
        start, goal = free[rng.choice(len(free), size=2, replace=False)]
        obs, info = env.reset(seed=int(rng.integers(1000)), options={"state": start, "goal_cell": tuple(goal)})
        expert.reset(obs, info)
        for _ in range(800):
            obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
            if terminated or truncated:
                break
        successes += info["success"]
    assert successes >= 19


def test_expert_replans_after_a_push_and_holds_without_goal() -> None:
    env = Maze2DEnv("large")
    expert = Maze2DExpert(env)
    obs, info = env.reset(seed=1, options={"state": [1.0, 1.0], "goal_cell": (7, 10)})
    expert.reset(obs, info)
    for _ in range(5):
        obs, _, _, _, info = env.step(expert.act(obs, info))
    env.perturb(to=np.array([5.0, 6.0]))
    for _ in range(400):
        obs, _, terminated, _, info = env.step(expert.act(obs, info))
        if terminated:
            break
    assert info["success"]
    obs, info = env.reset(seed=1, options={"state": [3.0, 3.0], "goal_cell": None})
    expert.reset(obs, info)
    np.testing.assert_allclose(expert.act(obs, info), [3.0, 3.0], atol=1e-6)
