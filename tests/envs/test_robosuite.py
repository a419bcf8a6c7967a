"""The robosuite envs (Lift, Can, Square): contract, checkers, seeding, modes, experts, RGB-D, bad input.

One env per task for the whole module (robosuite env creation takes 0.3-3 s),
plus one rendering Lift env (``fast_render``) for the RGB-D and pixel tests.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from robosuite_helpers import ROBOSUITE_MARKS, refuse_bad_perturb_and_action
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.data.experts import make_expert
from steer_envs.envs.robosuite.adapter import PERTURB_TOLERANCE, RobosuiteEnv
from steer_envs.envs.robosuite.tasks import TASKS, task_spec
from steer_envs.utils.env_checker import check_steer_env

IDS = {"lift": "steer_envs/Lift-v0", "can": "steer_envs/Can-v0", "square": "steer_envs/Square-v0"}

pytestmark = ROBOSUITE_MARKS


@pytest.fixture(scope="module")
def rgbd_env() -> Iterator[RobosuiteEnv]:
    """A Lift env with an offscreen renderer (256x256, fast_render), reset to seed 0."""
    env = RobosuiteEnv("lift", render_mode="rgb_array", fast_render=True)
    env.reset(seed=0)
    yield env
    env.close()


@pytest.fixture(scope="module")
def envs() -> Iterator[dict[str, gym.Env[Any, Any]]]:
    made: dict[str, gym.Env[Any, Any]] = {}

    class Lazy(dict[str, gym.Env[Any, Any]]):
        def __missing__(self, task: str) -> gym.Env[Any, Any]:
            made[task] = self[task] = gym.make(IDS[task])
            return made[task]

    yield Lazy()
    for env in made.values():
        env.close()


def run_expert(env: gym.Env[Any, Any], seed: int) -> tuple[bool, list[str], bool]:
    """(success, the sequence of distinct modes, any constraint violation) of one expert episode."""
    expert = make_expert(env)
    obs, info = env.reset(seed=seed)
    expert.reset(obs, info)
    modes, violated = [info["mode_name"]], False
    while True:
        obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
        violated |= info["constraint_violation"]
        if info["mode_name"] != modes[-1]:
            modes.append(info["mode_name"])
        if terminated or truncated:
            return bool(info["success"]), modes, violated


def test_import_does_not_load_robosuite() -> None:
    code = "import sys, steer_envs, steer_envs.envs.robosuite; assert 'robosuite' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize("task", list(IDS))
def test_follows_the_steer_env_contract(envs: dict[str, gym.Env[Any, Any]], task: str) -> None:
    check_steer_env(envs[task], steps=10)


@pytest.mark.parametrize("task", list(IDS))
def test_gymnasium_and_sb3_checkers_pass(envs: dict[str, gym.Env[Any, Any]], task: str) -> None:
    gym_check_env(envs[task].unwrapped, skip_render_check=True)
    sb3_check_env(envs[task].unwrapped, warn=False)


def test_seeding_is_deterministic_and_exposes_robosuite_obs(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["can"]
    a, _ = env.reset(seed=7)
    rs_a = env.unwrapped.robosuite_obs["Can_pos"].copy()
    b, _ = env.reset(seed=7)
    c, _ = env.reset(seed=8)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    np.testing.assert_allclose(a[9:12], rs_a, atol=1e-6)  # the can's position (float32) follows the 9 robot numbers


def test_two_instances_replay_the_same_seed(envs: dict[str, gym.Env[Any, Any]]) -> None:
    """robosuite draws Lift's cube size when it builds the model: both instances must build the same one."""
    other = gym.make(IDS["lift"])
    action = np.full(7, 0.3, dtype=np.float32)
    for env in (envs["lift"], other):
        env.reset(seed=1)
        for _ in range(3):
            obs = env.step(action)[0]
        env.unwrapped.last = obs
    np.testing.assert_array_equal(envs["lift"].unwrapped.last, other.unwrapped.last)
    other.close()


def test_reset_can_start_the_end_effector_elsewhere(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["can"]
    env.reset(seed=2)
    start = env.unwrapped.state + np.array([0.02, 0.0, 0.03])
    _, info = env.reset(seed=2, options={"state": start})
    np.testing.assert_allclose(env.unwrapped.state, start, atol=1e-6)
    assert info["mode_name"] == "reach" and not info["perturbed"]


def test_perturb_tracks_the_target_within_the_tolerance(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["lift"]
    base = env.unwrapped
    env.reset(seed=1)
    target = base.state + np.array([0.05, -0.03, 0.04])
    base.perturb_exact = False
    try:
        info = base.perturb(to=target)
    finally:
        base.perturb_exact = True
    assert info["perturbed"] and not info["constraint_violation"]
    assert np.linalg.norm(base.state - target) <= PERTURB_TOLERANCE
    before = base.state
    base.perturb(delta=np.array([0.0, 0.02, 0.0]))  # perturb_exact (the default): on the target
    np.testing.assert_allclose(base.state, before + np.array([0.0, 0.02, 0.0]), atol=1e-6)


def test_dropping_the_cube_is_a_constraint_violation(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["lift"]
    expert = make_expert(env)
    obs, info = env.reset(seed=0)
    expert.reset(obs, info)
    while not (info["mode_name"] == "lift" and info["sensors"]["lifted"]):
        obs, _, _, _, info = env.step(expert.act(obs, info))
    flags = []
    for _ in range(40):  # open the gripper mid-air: the cube falls back onto the table
        _, _, _, _, info = env.step(np.array([0, 0, 0, 0, 0, 0, -1], dtype=np.float32))
        flags.append(info["constraint_violation"])
    assert info["mode_name"] == "reach" and sum(flags) == 1


def test_pressing_the_cube_into_the_table_does_not_lower_its_rest_height(envs: dict[str, gym.Env[Any, Any]]) -> None:
    """Closed fingers press the cube ~1.5 cm into the soft table contact, then rise: it never reads lifted.

    Before the rest height ignored readings with the robot touching the cube,
    the press lowered it and the cube flicked up by the fingers read `lifted`.
    """
    env = envs["lift"].unwrapped
    env.reset(seed=3)
    lifted, heights = [], []
    for t in range(140):
        offset = 0.06 if t < 60 else (-0.05 if t < 110 else 0.15)  # above, press through the top, up again
        d = env.object_pos + np.array([0.0, 0.0, offset]) - env.state
        _, _, _, _, info = env.step(np.concatenate([np.clip(10 * d, -1, 1), [0, 0, 0, 1.0]]).astype(np.float32))
        lifted.append(info["sensors"]["lifted"])
        heights.append(env.object_pos[2])
    settled = heights[55]
    assert min(heights[60:110]) < settled - 0.01  # the press sank the cube below where it rests
    for is_lifted, z in zip(lifted, heights, strict=True):
        assert not is_lifted or z > settled + 0.009


@pytest.mark.parametrize(("task", "seeds"), [("lift", (0, 1)), ("can", (0,)), ("square", (0,))])
def test_expert_solves_and_walks_the_modes_in_order(
    envs: dict[str, gym.Env[Any, Any]], task: str, seeds: tuple[int, ...]
) -> None:
    for seed in seeds:
        success, modes, violated = run_expert(envs[task], seed)
        assert success and not violated
        assert modes == list(TASKS[task].modes)


def test_every_sensor_reading_has_a_mode() -> None:
    for task in TASKS.values():
        spec = task_spec(task)
        assert len(spec.sensor_modes) == 2 ** len(task.sensors)
        assert not spec.is_allowed(spec.modes[1], "reach")


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"task": "stack"}, ValueError, "task"),
        ({"task": 3}, ValueError, "task"),
        ({"render_size": 0}, ValueError, "render_size"),
        ({"render_size": 64.0}, TypeError, "render_size"),
        ({"render_mode": "human"}, ValueError, "render_mode"),
        ({"camera": 1}, TypeError, "camera"),
        ({"perturb_exact": "yes"}, TypeError, "perturb_exact"),
        ({"fast_render": 1}, TypeError, "fast_render"),
    ],
)
def test_bad_constructor_arguments_are_refused_before_robosuite_runs(
    kwargs: dict[str, Any], error: type[Exception], match: str
) -> None:
    with pytest.raises(error, match=match):
        RobosuiteEnv(**kwargs)


def test_bad_perturb_and_action_are_refused(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["square"]
    env.reset(seed=0)
    before = refuse_bad_perturb_and_action(env)
    np.testing.assert_array_equal(env.unwrapped.state, before)
    with pytest.raises(ValueError, match="options"):
        env.reset(options={"start": [0, 0, 0]})
    with pytest.raises(ValueError, match="state"):
        env.reset(options={"state": [0.0, 0.0]})


def test_a_tensor_that_requires_grad_acts_like_its_values(envs: dict[str, gym.Env[Any, Any]]) -> None:
    torch = pytest.importorskip("torch")
    env = envs["lift"]
    action = np.full(7, 0.2, dtype=np.float32)
    env.reset(seed=4)
    by_array = env.step(action)[0]
    env.reset(seed=4)
    tensor = torch.tensor(action, requires_grad=True)
    np.testing.assert_array_equal(env.step(tensor)[0], by_array)
    assert tensor.grad is None
    push = torch.tensor([0.01, 0.0, 0.0], dtype=torch.float64, requires_grad=True)
    before = env.unwrapped.state
    env.unwrapped.perturb(delta=push)
    np.testing.assert_allclose(env.unwrapped.state, before + np.array([0.01, 0.0, 0.0]), atol=1e-6)


def test_rgb_array_render() -> None:
    env = gym.make("steer_envs/Lift-v0", render_mode="rgb_array", render_size=64, fast_render=True)
    env.reset(seed=0)
    frame = env.render()
    env.reset(seed=1)  # a soft reset keeps the renderer (and its fast settings)
    again = env.render()
    env.close()
    assert frame.shape == again.shape == (64, 64, 3) and frame.dtype == np.uint8 and frame.std() > 0


def test_renders_survive_another_env_with_a_renderer_being_made_and_closed(rgbd_env: RobosuiteEnv) -> None:
    """Each env binds its own GL context before rendering (gymnasium's check_env makes and closes a copy)."""
    rgb, depth = rgbd_env.render_rgbd()
    other = RobosuiteEnv("lift", render_mode="rgb_array", render_size=64, fast_render=True)
    other.reset(seed=1)
    other.render()
    other.close()
    rgb_after, depth_after = rgbd_env.render_rgbd()
    np.testing.assert_array_equal(rgb_after, rgb)
    np.testing.assert_allclose(depth_after, depth, atol=1e-5)


def _surface_points(env: RobosuiteEnv) -> dict[str, np.ndarray]:
    """World points on visible surfaces: the centre of the cube's top face and a spot of the table top."""
    rs = env.rs_env
    return {
        "cube top": env.object_pos + np.array([0.0, 0.0, rs.cube.size[2]]),
        "table": np.array([-0.1, 0.15, rs.model.mujoco_arena.table_offset[2]]),
    }


def test_render_rgbd_gives_the_frame_and_metric_depth_in_image_convention(rgbd_env: RobosuiteEnv) -> None:
    rgb, depth = rgbd_env.render_rgbd()
    assert rgb.shape == (256, 256, 3) and rgb.dtype == np.uint8 and depth.shape == (256, 256)
    assert depth.dtype == np.float32 and np.all(np.isfinite(depth)) and depth.min() > 0.1
    np.testing.assert_array_equal(rgb, rgbd_env.render())  # the same frame as render, row 0 on top
    u, v, z = rgbd_env.world_to_pixel(_surface_points(rgbd_env)["cube top"])
    row, col = round(v), round(u)
    assert rgb[row, col, 0] > rgb[row, col, 1] + 60  # the red cube is where the camera matrix puts it
    assert abs(depth[row, col] - z) < 0.005  # metres along the optical axis
    front_rgb, front_depth = rgbd_env.render_rgbd("frontview")
    assert front_rgb.shape == (256, 256, 3) and not np.allclose(front_depth, depth)


def test_pixel_to_world_inverts_world_to_pixel(rgbd_env: RobosuiteEnv) -> None:
    for point in (rgbd_env.object_pos, rgbd_env.state):  # the depth given: exact
        u, v, z = rgbd_env.world_to_pixel(point)
        np.testing.assert_allclose(rgbd_env.pixel_to_world(u, v, depth=z), point, atol=1e-9)
    for camera in ("agentview", "sideview"):  # the depth read from a render: the surface seen at that pixel
        for name, point in _surface_points(rgbd_env).items():
            u, v, _ = rgbd_env.world_to_pixel(point, camera=camera)
            error = np.linalg.norm(rgbd_env.pixel_to_world(round(u), round(v), camera=camera) - point)
            assert error < 0.01, f"{camera} {name}: {error * 1e3:.1f} mm"


def test_grasp_check_matches_robosuites_own(envs: dict[str, gym.Env[Any, Any]]) -> None:
    """The adapter's geom-id grasp check answers like robosuite's ``_check_grasp`` on every step of an episode."""
    env = envs["lift"]
    base = env.unwrapped
    expert = make_expert(env)
    obs, info = env.reset(seed=0)
    expert.reset(obs, info)
    answers = set()
    while True:
        obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
        ours = base._grasped()
        assert ours == bool(base.rs_env._check_grasp(gripper=base._robot.gripper, object_geoms=base._object))
        answers.add(ours)
        if terminated or truncated:
            break
    assert answers == {False, True}


def test_held_needs_a_grasp_of_two_steps(envs: dict[str, gym.Env[Any, Any]], monkeypatch: Any) -> None:
    """A one-step touch of both pads (fingers closing on the resting object) neither holds nor drops the object."""
    env = envs["lift"]
    base = env.unwrapped
    env.reset(seed=0)
    readings = iter([True, False, False, True, True, True, False])
    monkeypatch.setattr(base, "_grasped", lambda: next(readings))
    rest = np.zeros(7, dtype=np.float32)  # the cube stays on the table
    infos = [env.step(rest)[4] for _ in range(7)]
    assert [i["sensors"]["held"] for i in infos] == [False, False, False, False, True, True, False]
    assert [i["constraint_violation"] for i in infos] == [False] * 6 + [True]  # a real grasp dropped on the table


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda e: e.pixel_to_world(256, 10), ValueError, r"u must be in \[0.0, 256\), got 256"),
        (lambda e: e.pixel_to_world(10, -0.5), ValueError, r"v must be in \[0.0, 256\), got -0.5"),
        (lambda e: e.pixel_to_world(np.nan, 10), ValueError, "u must be a finite"),
        (lambda e: e.pixel_to_world(10, 10, depth=np.nan), ValueError, "depth must be a finite"),
        (lambda e: e.pixel_to_world(10, 10, depth=0.0), ValueError, r"depth must be in \(0.0, inf\]"),
        (lambda e: e.pixel_to_world("10", 10), TypeError, "u must be a real number"),
        (lambda e: e.pixel_to_world(10, 10, camera="nope"), ValueError, r"unknown `camera` 'nope'; cameras: \["),
        (lambda e: e.render_rgbd("nope"), ValueError, "unknown `camera` 'nope'; cameras: .*agentview"),
        (lambda e: e.render_rgbd(3), TypeError, "camera"),
        (lambda e: e.world_to_pixel([np.nan, 0.0, 0.0]), ValueError, "point"),
    ],
)
def test_bad_pixels_depths_and_cameras_are_refused(
    rgbd_env: RobosuiteEnv, call: Any, error: type[Exception], match: str
) -> None:
    with pytest.raises(error, match=match):
        call(rgbd_env)


def test_rgbd_needs_a_renderer_but_a_given_depth_does_not(envs: dict[str, gym.Env[Any, Any]]) -> None:
    base = envs["lift"].unwrapped  # render_mode=None
    envs["lift"].reset(seed=0)
    for call in (base.render_rgbd, lambda: base.pixel_to_world(10, 10)):
        with pytest.raises(ValueError, match="render_mode='rgb_array'"):
            call()
    point = base.object_pos
    u, v, z = base.world_to_pixel(point)
    np.testing.assert_allclose(base.pixel_to_world(u, v, depth=z), point, atol=1e-9)


def test_an_unknown_camera_is_refused_without_a_renderer_too() -> None:
    with pytest.raises(ValueError, match=r"unknown `camera` 'nope'; cameras: .*agentview"):
        RobosuiteEnv("lift", camera="nope")


@pytest.mark.slow
@pytest.mark.parametrize("task", list(IDS))
def test_expert_succeeds_in_95_of_100_seeded_episodes(envs: dict[str, gym.Env[Any, Any]], task: str) -> None:
    wins = sum(run_expert(envs[task], seed)[0] for seed in range(100))
    assert wins >= 95, f"{task}: {wins}/100"
