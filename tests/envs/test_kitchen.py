"""Kitchen-v0: the skills' tree, reset options, sensors, modes, checkers, violations, success, pixels, skills, assets.

One env for the module (robosuite env creation takes seconds), without a
renderer: Gymnasium's checker makes and closes a copy of the env it checks, and
closing a copy's OSMesa renderer leaves the first one's GL context not current.
The pixel test makes its own env with a renderer. Episodes are a skill long.
"""

from __future__ import annotations

import itertools
import socket
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import gymnasium as gym
import networkx as nx
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from robosuite_helpers import ROBOSUITE_MARKS, module_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.data.experts import make_expert
from steer_envs.envs.robosuite.kitchen import SKILLS, KitchenEnv, kitchen_task, legal_skills, skill_target
from steer_envs.envs.robosuite.kitchen_assets import (
    BOWL_FILE,
    BOWL_HEIGHT,
    BOWL_RADIUS,
    MICROWAVE_FILE,
    asset_dir,
    microwave_source,
)
from steer_envs.envs.robosuite.kitchen_scene import (
    CAVITY_FRONT_X,
    CAVITY_HIGH,
    CAVITY_LOW,
    DOOR_START_OPEN,
    SINK_XY,
    TABLE_Z,
)
from steer_envs.utils.env_checker import check_steer_env

ENV_ID = "steer_envs/Kitchen-v0"
ZERO = np.array([0, 0, 0, 0, 0, 0, -1], dtype=np.float32)  # stand still, the gripper open

pytestmark = ROBOSUITE_MARKS


env = module_env(ENV_ID)


def put_bowl(base: KitchenEnv, centre: np.ndarray) -> None:
    """Teleport the bowl (upright, still) so its centre is at ``centre``."""
    rs = base.rs_env
    rs.sim.data.set_joint_qpos(rs.bowl.joints[0], np.r_[centre, 1.0, 0.0, 0.0, 0.0])
    rs.sim.data.set_joint_qvel(rs.bowl.joints[0], np.zeros(6))
    rs.sim.forward()


def in_microwave() -> np.ndarray:
    """A bowl centre resting on the microwave's floor."""
    return np.array([CAVITY_FRONT_X + 0.07, (CAVITY_LOW[1] + CAVITY_HIGH[1]) / 2, CAVITY_LOW[2] + BOWL_HEIGHT / 2])


def settle(env: gym.Env[Any, Any], steps: int = 10) -> list[dict[str, Any]]:
    return [env.step(ZERO)[4] for _ in range(steps)]


def test_import_does_not_load_robosuite() -> None:
    code = (
        "import sys, steer_envs, steer_envs.envs.robosuite.kitchen, steer_envs.data.experts.kitchen;"
        "assert 'robosuite' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_task_tree_needs_six_skills_in_two_orders() -> None:
    task = kitchen_task()
    assert task.initial == "closed_table" and task.goal == ("closed_microwave_washed",)
    plans = sorted(nx.all_shortest_paths(task.graph(), "closed_table", "closed_microwave_washed"))
    assert [len(p) - 1 for p in plans] == [6, 6]
    skills = [[next(s for s in SKILLS if skill_target(a, s) == b) for a, b in itertools.pairwise(p)] for p in plans]
    assert sorted(skills) == [
        ["open_door", "pick_bowl", "place_in_sink", "pick_bowl", "place_in_microwave", "close_door"],
        ["pick_bowl", "place_in_sink", "open_door", "pick_bowl", "place_in_microwave", "close_door"],
    ]
    assert skill_target("closed_held", "place_in_microwave") is None  # the door is shut
    assert skill_target("open_held", "place_in_microwave") == "open_microwave"
    assert not task.is_allowed("closed_held", "closed_microwave")
    assert skill_target("closed_microwave", "pick_bowl") is None and "open_door" not in legal_skills("open_held")
    assert legal_skills("closed_table") == ("open_door", "pick_bowl")
    assert legal_skills("lost") == ()
    assert len(kitchen_task("microwave").shortest_plan("closed_table", "closed_microwave")) - 1 == 4
    assert len(kitchen_task("sink").shortest_plan("closed_table", "closed_sink")) - 1 == 2
    for mode in task.modes:  # every mode's sensor reading names it
        assert task.mode_of(task.sensors_of(mode)) == mode


def test_checkers_pass(env: gym.Env[Any, Any]) -> None:
    check_steer_env(env, steps=8)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)


@pytest.mark.parametrize(
    ("options", "mode", "true"),
    [
        ({}, "closed_table", {"on_table"}),
        ({"bowl": "sink"}, "closed_sink", {"in_sink", "washed"}),
        ({"bowl": "microwave", "door": "open"}, "open_microwave", {"in_microwave", "door_open"}),
        ({"bowl": "microwave"}, "closed_microwave", {"in_microwave"}),
        ({"door": "open"}, "open_table", {"on_table", "door_open"}),
    ],
)
def test_reset_options_set_the_sensors_and_mode(
    env: gym.Env[Any, Any], options: dict[str, str], mode: str, true: set[str]
) -> None:
    obs, first = env.reset(seed=2, options=options)
    base = env.unwrapped
    assert obs.shape == (17,) and obs.dtype == np.float32
    for info in [first, *settle(env)]:  # the bowl stays where it started
        assert info["mode_name"] == mode and {k for k, v in info["sensors"].items() if v} == true
        assert not info["constraint_violation"]
    assert abs(obs[16] - (DOOR_START_OPEN if options.get("door") == "open" else 0.0)) < 1e-6
    np.testing.assert_allclose(obs[9:12], base.bowl_pos, atol=0.01)
    again, _ = env.reset(seed=2, options=options)
    np.testing.assert_array_equal(again, obs)


def test_a_bowl_put_in_the_closed_microwave_or_off_the_table_is_a_violation(env: gym.Env[Any, Any]) -> None:
    base = env.unwrapped
    env.reset(seed=0)
    put_bowl(base, in_microwave())
    info = env.step(ZERO)[4]
    assert info["mode_name"] == "closed_microwave" and info["constraint_violation"] and not info["success"]
    env.reset(seed=0)
    put_bowl(base, np.array([0.0, 0.9, TABLE_Z + 0.2]))  # beyond the table's edge: it falls
    flags = [i["constraint_violation"] for i in settle(env, 15)]
    assert base.place == "lost" and any(flags)


def test_success_needs_the_washed_bowl_in_the_shut_microwave(env: gym.Env[Any, Any]) -> None:
    base = env.unwrapped
    env.reset(seed=1, options={"bowl": "sink"})
    settle(env, 3)  # the bowl rests in the sink: washed
    put_bowl(base, in_microwave())
    rs = base.rs_env
    rs.sim.data.qpos[rs.door_qpos] = -0.5  # ajar: the "closed" mode, but not shut
    rs.sim.forward()
    _, reward, terminated, _, info = env.step(ZERO)
    assert info["mode_name"] == "closed_microwave_washed" and not info["success"] and not terminated
    rs.sim.data.qpos[rs.door_qpos] = 0.0
    rs.sim.data.qvel[rs.door_qvel] = 0.0
    rs.sim.forward()
    _, reward, terminated, _, info = env.step(ZERO)
    assert info["success"] and info["is_success"] and terminated and reward == 1.0


def test_pixel_to_world_inverts_world_to_pixel_on_known_surfaces() -> None:
    env = gym.make(ENV_ID, render_mode="rgb_array", fast_render=True)
    base = env.unwrapped
    env.reset(seed=0)
    bowl = base.bowl_pos
    cam = base.rs_env.sim.data.cam_xpos[base.rs_env.sim.model.camera_name2id(base.camera)]
    toward = (cam - bowl)[:2] / np.linalg.norm((cam - bowl)[:2])  # the bowl's wall facing the camera
    points = {
        "bowl wall": np.r_[bowl[:2] + BOWL_RADIUS * toward, bowl[2]],
        "bowl rim": np.r_[bowl[:2] + (BOWL_RADIUS - 0.003) * toward, bowl[2] + BOWL_HEIGHT / 2],
        "sink floor": np.array([SINK_XY[0], SINK_XY[1], base.sink_floor_z]),
        "table": np.array([0.15, -0.1, TABLE_Z]),
        "table far": np.array([0.3, -0.45, TABLE_Z]),
    }
    for name, point in points.items():
        u, v, z = base.world_to_pixel(point)
        np.testing.assert_allclose(base.pixel_to_world(u, v, depth=z), point, atol=1e-9)
        error = np.linalg.norm(base.pixel_to_world(round(u), round(v)) - point)
        assert error < 0.01, f"{name}: {error * 1e3:.1f} mm"
    rgb, depth = base.render_rgbd()
    assert rgb.shape == (256, 256, 3) and depth.shape == (256, 256) and np.all(np.isfinite(depth))
    env.close()


def run_skill(env: gym.Env[Any, Any], skills: Any, limit: int = 600) -> list[dict[str, Any]]:
    infos = []
    for _ in range(limit):
        if skills.done:
            return infos
        infos.append(env.step(skills.act())[4])
    raise AssertionError(f"skill {skills.skill} still in phase {skills.phase!r} after {limit} steps")


def test_open_door_from_reset_then_pick_from_the_microwave(env: gym.Env[Any, Any]) -> None:
    from steer_envs.data.experts.kitchen import KitchenSkills

    base = env.unwrapped
    env.reset(seed=3, options={"bowl": "microwave"})
    skills = KitchenSkills(base)
    skills.start("open_door")
    infos = run_skill(env, skills)
    assert skills.succeeded() and infos[-1]["mode_name"] == "open_microwave"
    skills.start("pick_bowl")
    infos += run_skill(env, skills)
    assert skills.succeeded() and infos[-1]["mode_name"] == "open_held" and base.bowl_pos[2] > TABLE_Z + 0.2
    assert not any(i["constraint_violation"] for i in infos)
    modes = [infos[0]["mode_name"]]
    modes += [b["mode_name"] for a, b in itertools.pairwise(infos) if a["mode_name"] != b["mode_name"]]
    assert modes == ["closed_microwave", "open_microwave", "open_held"]


def test_registered_expert_is_the_kitchen_expert(env: gym.Env[Any, Any]) -> None:
    from steer_envs.data.experts.kitchen import KitchenExpert, KitchenPlanner

    assert isinstance(make_expert(env), KitchenExpert)
    assert env.spec is not None and env.spec.max_episode_steps is not None and env.spec.max_episode_steps >= 1200
    env.reset(seed=0)
    firsts = {KitchenPlanner(seed).next_skill(env.unwrapped) for seed in range(12)}
    assert firsts == {"open_door", "pick_bowl"}  # the two orders of the cleaning task


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"task": "oven"}, ValueError, "task"),
        ({"task": 1}, ValueError, "task"),
        ({"render_size": 0}, ValueError, "render_size"),
        ({"render_mode": "human"}, ValueError, "render_mode"),
        ({"camera": 3}, TypeError, "camera"),
        ({"fast_render": 1}, TypeError, "fast_render"),
    ],
)
def test_bad_constructor_arguments_are_refused(kwargs: dict[str, Any], error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        KitchenEnv(**kwargs)


def test_bad_reset_options_skills_and_pixels_are_refused(env: gym.Env[Any, Any]) -> None:
    from steer_envs.data.experts.kitchen import KitchenExpert, KitchenPlanner, KitchenSkills

    base = env.unwrapped
    env.reset(seed=0)
    before = base.state
    for options, error, match in (
        ({"bowl": "oven"}, ValueError, "bowl"),
        ({"door": "ajar"}, ValueError, "door"),
        ({"door": 1}, ValueError, "door"),
        ({"bowls": "sink"}, ValueError, "options"),
        ({"state": [0.0, 0.0]}, ValueError, "state"),
    ):
        with pytest.raises(error, match=match):
            env.reset(options=options)
    for call, error, match in (
        (lambda: KitchenSkills(base).start("fly"), ValueError, "skill"),
        (lambda: KitchenExpert(gym.make("steer_envs/ConvexMode-v0").unwrapped), TypeError, "env"),
        (lambda: KitchenPlanner(seed=-1), ValueError, "seed"),
        (lambda: skill_target("closed_table", "wash"), ValueError, "skill"),
        (lambda: skill_target("dirty", "pick_bowl"), ValueError, "mode"),
        (lambda: kitchen_task("oven"), ValueError, "task"),
        (lambda: base.pixel_to_world(256, 10, depth=1.0), ValueError, "u must be in"),
        (lambda: base.pixel_to_world(10, "10", depth=1.0), TypeError, "v must be a real"),
        (lambda: base.pixel_to_world(10, 10), ValueError, "render_mode='rgb_array'"),
        (lambda: base.world_to_pixel([np.nan, 0.0, 0.0]), ValueError, "point"),
    ):
        with pytest.raises(error, match=match):
            call()
    np.testing.assert_array_equal(base.state, before)


def test_assets_are_built_from_installed_files_into_a_cache_atomically(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_network(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("the asset build opened a socket")

    monkeypatch.setattr(socket, "socket", no_network)
    monkeypatch.setattr(socket, "create_connection", no_network)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".v2-0123456789abcdef.{dead.pid}-abcdefgh.tmp"  # what a killed build leaves behind
    stale.mkdir()
    (stale / MICROWAVE_FILE).write_text("<mujoco")  # a torn file
    folder = asset_dir(tmp_path)
    assert folder.parent == tmp_path and sorted(p.name for p in tmp_path.iterdir()) == [folder.name]
    assert sorted(p.name for p in folder.iterdir()) == sorted([BOWL_FILE, MICROWAVE_FILE])
    text = (folder / MICROWAVE_FILE).read_text()
    assert 'class="' not in text and "childclass" not in text and 'name="microwave"' in text
    files = [Path(el.attrib["file"]) for el in ET.fromstring(text).iter() if "file" in el.attrib]
    package = microwave_source().parent.resolve()
    assert files and all(f.is_absolute() and f.is_file() and f.is_relative_to(package) for f in files)
    stamp = (folder / MICROWAVE_FILE).stat().st_mtime_ns
    assert asset_dir(tmp_path) == folder and (folder / MICROWAVE_FILE).stat().st_mtime_ns == stamp  # cached
