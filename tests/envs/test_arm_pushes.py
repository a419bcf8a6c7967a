"""Pushes the arms can take: the workspace, joint limits, and no silent reset of the simulation.

The arm envs' ``perturb`` refuses targets outside ``perturb_workspace`` (below
the table, past the arm's reach) naming the argument and the bounds, sets the
joints within their limits, and an unstable simulation (MuJoCo's NaN/Inf
warnings, after which MuJoCo resets it) raises ``SimulationUnstableError``
until ``reset``. One env per id for the module.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from robosuite_helpers import ROBOSUITE_MARKS, lazy_arms

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.envs.robosuite import SimulationUnstableError
from steer_envs.envs.robosuite.arm_scoop import WORKSPACE
from steer_envs.envs.robosuite.kitchen import push_toward
from steer_envs.envs.robosuite.stability import StepWatch
from steer_envs.envs.robosuite.workspace import PANDA_REACH, PERTURB_CLEARANCE, Workspace

pytestmark = ROBOSUITE_MARKS

CONTROL_DT = 0.05
#: the arm joints the old unconstrained IK left behind a push to z = -1 m (tens of radians)
WILD_JOINTS = np.array([10.6, -85.7, 6.8, -121.0, -6.2, -80.1, 0.79])


@pytest.fixture(scope="module")
def envs() -> Iterator[dict[str, gym.Env[Any, Any]]]:
    yield from lazy_arms()


@pytest.fixture
def mujoco_log_in_tmp(tmp_path: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """Run in ``tmp_path``: MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working directory."""
    monkeypatch.chdir(tmp_path)


def sim_time(base: Any) -> float:
    return float(base.rs_env.sim.data.time)


def arm_joints(base: Any) -> np.ndarray:
    return np.array(base.rs_env.sim.data.qpos[base._arm_qpos])


def within_limits(base: Any) -> bool:
    model = base.rs_env.sim.model._model
    low, high = model.jnt_range[base._robot._ref_joint_indexes].T
    q = arm_joints(base)
    return bool(np.all((q >= low - 1e-9) & (q <= high + 1e-9)))


def zero_action(env: gym.Env[Any, Any]) -> np.ndarray:
    return np.zeros(env.action_space.shape, dtype=np.float32)


def object_positions(base: Any) -> np.ndarray:
    """Every free body's position (cubes, bowl, can...), from the sim."""
    model, data = base.rs_env.sim.model._model, base.rs_env.sim.data._data
    free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    return np.array([data.qpos[model.jnt_qposadr[j] : model.jnt_qposadr[j] + 3] for j in free]).reshape(-1, 3)


# ------------------------------------------------------------------ silent resets
@pytest.mark.parametrize("name", ["Lift", "BlockStack", "Kitchen"])
def test_a_push_through_the_table_is_refused_and_the_next_step_goes_on(
    envs: dict[str, gym.Env[Any, Any]], name: str
) -> None:
    env = envs[name]
    base = env.unwrapped
    env.reset(seed=0)
    eef, t0, objects = base.state, sim_time(base), object_positions(base)
    with pytest.raises(ValueError, match=r"`delta`.*outside its workspace.*z in \[0\.805"):
        base.perturb(delta=[0.0, 0.0, -2.0])
    np.testing.assert_array_equal(base.state, eef)
    assert sim_time(base) == t0
    env.step(zero_action(env))
    assert sim_time(base) == pytest.approx(t0 + CONTROL_DT)
    assert np.linalg.norm(base.state - eef) < 0.02  # the arm did not jump to MuJoCo's initial pose
    np.testing.assert_allclose(object_positions(base), objects, atol=0.03)  # settling, not MuJoCo's defaults


def test_arm_scoop_pushes_corner_to_corner_keep_the_simulation(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["ArmScoop"]
    base = env.unwrapped
    env.reset(seed=0)
    base.perturb(delta=[100.0] * 3)
    np.testing.assert_allclose(base.state, WORKSPACE[1], atol=1e-6)
    base.perturb(delta=[-100.0] * 3)
    np.testing.assert_allclose(base.state, WORKSPACE[0], atol=1e-6)
    assert within_limits(base)
    t0 = sim_time(base)
    env.step(zero_action(env))
    assert sim_time(base) == pytest.approx(t0 + CONTROL_DT)
    assert np.linalg.norm(base.state[:2] - WORKSPACE[0][:2]) < 0.05


@pytest.mark.usefixtures("mujoco_log_in_tmp")
@pytest.mark.parametrize("name", ["Lift", "BlockStack", "Kitchen", "ArmScoop"])
def test_an_unstable_simulation_raises_until_reset(envs: dict[str, gym.Env[Any, Any]], name: str) -> None:
    env = envs[name]
    base = env.unwrapped
    env.reset(seed=0)
    data = base.rs_env.sim.data._data
    data.qpos[base._arm_qpos] = WILD_JOINTS  # what the unconstrained IK did: MuJoCo blows up on the next step
    mujoco.mj_forward(base.rs_env.sim.model._model, data)
    with pytest.raises(SimulationUnstableError, match=r"step: MuJoCo found .*mjWARN_BAD.*call reset\(\)"):
        env.step(zero_action(env))
    with pytest.raises(SimulationUnstableError, match="became unstable earlier"):
        env.step(zero_action(env))
    with pytest.raises(SimulationUnstableError, match="perturb"):
        base.perturb(delta=np.zeros(3))
    env.reset(seed=0)
    env.step(zero_action(env))
    assert sim_time(base) == pytest.approx(CONTROL_DT)


@pytest.mark.usefixtures("mujoco_log_in_tmp")
def test_a_runaway_velocity_is_caught_as_well(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["Lift"]
    base = env.unwrapped
    env.reset(seed=1)
    base.rs_env.sim.data._data.qvel[base._arm_qvel[0]] = 1e12
    with pytest.raises(SimulationUnstableError, match="mjWARN_BADQVEL"):
        env.step(zero_action(env))
    env.reset(seed=1)


@pytest.mark.usefixtures("mujoco_log_in_tmp")
def test_the_step_watch_reads_mujocos_counters_and_the_time() -> None:
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1'/></body></worldbody></mujoco>"
    )
    data = mujoco.MjData(model)
    for _ in range(5):
        mujoco.mj_step(model, data)
    watch = StepWatch.start(data)
    mujoco.mj_step(model, data)
    assert watch.problem() is None
    watch = StepWatch.start(data)
    mujoco.mj_resetData(model, data)  # a reset under the episode: the time goes back
    assert "sim time went back" in (watch.problem() or "")
    with pytest.raises(SimulationUnstableError, match="owner: the simulation was reset"):
        watch.check("owner")
    data.qvel[0] = np.inf
    watch = StepWatch.start(data)
    mujoco.mj_step(model, data)  # MuJoCo warns and resets the simulation
    assert "mjWARN_BADQVEL" in (watch.problem() or "")


# ------------------------------------------------------------------ the workspace
@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"delta": [0.0, 0.0, -0.6]}, "delta"),  # the hand under the table
        ({"delta": [1e6] * 3}, "delta"),
        ({"delta": [1e300] * 3}, "delta"),
        ({"to": [1e9] * 3}, "to"),
        ({"to": [0.0, 0.0, 0.79]}, "to"),  # inside the table top
        ({"to": [0.6, 0.0, 1.0]}, "to"),  # past the arm's reach
        ({"to": [-0.5, 0.05, 1.0]}, "to"),  # into the robot's own column
    ],
)
def test_pushes_outside_the_workspace_are_refused_naming_the_argument(
    envs: dict[str, gym.Env[Any, Any]], kwargs: dict[str, Any], argument: str
) -> None:
    env = envs["Lift"]
    base = env.unwrapped
    env.reset(seed=0)
    eef, t0, joints = base.state, sim_time(base), arm_joints(base)
    with pytest.raises(
        ValueError, match=rf"`{argument}`.*outside its workspace \(x in \[.*within 0\.900 of the shoulder"
    ):
        base.perturb(**kwargs)
    np.testing.assert_array_equal(base.state, eef)
    np.testing.assert_array_equal(arm_joints(base), joints)
    assert sim_time(base) == t0


def test_a_reset_start_outside_the_workspace_is_refused(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["Kitchen"]
    with pytest.raises(ValueError, match=r"options\['state'\].*outside its workspace"):
        env.reset(seed=0, options={"state": [0.0, 0.0, 0.7]})
    env.reset(seed=0)


def test_the_workspace_is_the_tables_top_and_the_arms_reach(envs: dict[str, gym.Env[Any, Any]]) -> None:
    tops = {"Lift": 0.8, "Square": 0.82, "Can": 0.82, "Kitchen": 0.8, "BlockStack": 0.8}  # Can: the bins' floors
    for name, top in tops.items():
        base = envs[name].unwrapped
        ws = base.perturb_workspace
        assert isinstance(ws, Workspace)
        assert ws.low[2] == pytest.approx(top + PERTURB_CLEARANCE)
        assert ws.reach == PANDA_REACH and ws.centre is not None
        assert ws.centre[2] == pytest.approx(0.912 + 0.333)  # the shoulder, above the base
        envs[name].reset(seed=0)
        assert ws.contains(base.state)


def test_a_target_a_metre_away_is_reached_exactly_or_refused(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["Lift"]
    base = env.unwrapped
    ws = base.perturb_workspace
    directions = [np.eye(3)[i] * s for i in range(3) for s in (1.0, -1.0)]
    directions += [
        np.array(d) / np.linalg.norm(d) for d in ([1, 1, -0.3], [1, -1, 0.3], [-0.2, 1, 0.2], [0.3, -1, -0.1])
    ]
    start = np.array([0.0, -0.55, 0.95])
    env.reset(seed=0)
    base.perturb(to=start)
    reached = 0
    for d in directions:
        target = start + d
        try:
            base.perturb(delta=d)
        except ValueError as error:
            assert "`delta`" in str(error) and not ws.contains(target)
            np.testing.assert_allclose(base.state, start, atol=1e-6)
            continue
        np.testing.assert_allclose(base.state, target, atol=1e-6)
        assert within_limits(base)
        reached += 1
        base.perturb(to=start)
    assert reached >= 1  # +y: across the table


def edge_targets(ws: Workspace) -> list[np.ndarray]:
    """Points on the workspace's edges: the floor at full reach, beside and behind the robot, high and wide."""
    assert ws.centre is not None and ws.reach is not None
    c, r, floor = ws.centre, ws.reach, ws.low[2]
    return [
        np.array([c[0] + np.sqrt(r**2 - (c[2] - floor) ** 2) - 1e-3, c[1], floor]),
        np.array([c[0] + 0.3, c[1] - 0.7, 0.9]),
        np.array([-0.3, -0.6, 1.4]),  # the old IK reached this one with joints past their limits
        np.array([c[0] + 0.5, c[1] + 0.7, c[2]]),
        np.array([c[0] - 0.4, c[1] + 0.1, c[2] + 0.2]),  # behind the robot, where a failed Kitchen skill left it
    ]


@pytest.mark.parametrize("name", ["Lift", "Can", "Kitchen"])
def test_every_part_of_the_workspace_is_reachable_within_the_joint_limits(
    envs: dict[str, gym.Env[Any, Any]], name: str
) -> None:
    env = envs[name]
    base = env.unwrapped
    ws = base.perturb_workspace
    env.reset(seed=2)
    rng = np.random.default_rng(0)
    targets = edge_targets(ws)
    while len(targets) < 150:
        p = rng.uniform(ws.low, ws.high)
        if ws.contains(p):
            targets.append(p)
    data = base.rs_env.sim.data._data
    for target in targets:
        assert ws.contains(target), target
        plan = base._ik.plan(data, base._position_residual(target), base._ik_seeds(target), iters=200)
        assert plan is not None and base._ik.within_limits(plan), target


def test_pushes_to_the_workspaces_edges_land_exactly_within_the_joint_limits(
    envs: dict[str, gym.Env[Any, Any]],
) -> None:
    env = envs["Lift"]
    base = env.unwrapped
    env.reset(seed=2)
    for target in edge_targets(base.perturb_workspace):
        base.perturb(to=target)
        np.testing.assert_allclose(base.state, target, atol=1e-6)
        assert within_limits(base), (target, arm_joints(base))
    t0 = sim_time(base)
    env.step(zero_action(env))
    assert sim_time(base) == pytest.approx(t0 + CONTROL_DT)


@pytest.mark.parametrize("name", ["BlockStack", "Kitchen"])
def test_an_in_range_push_works_as_before(envs: dict[str, gym.Env[Any, Any]], name: str) -> None:
    env = envs[name]
    base = env.unwrapped
    env.reset(seed=3)
    before = base.state
    info = base.perturb(delta=[0.03, -0.02, 0.04])
    assert info["perturbed"] and not info["constraint_violation"]
    np.testing.assert_allclose(base.state, before + np.array([0.03, -0.02, 0.04]), atol=1e-6)
    assert within_limits(base)
    _, _, _, _, info = env.step(zero_action(env))
    assert not info["perturbed"]


def test_without_perturb_exact_the_workspace_still_holds() -> None:
    env = gym.make("steer_envs/Lift-v0", perturb_exact=False)
    try:
        env.reset(seed=0)
        with pytest.raises(ValueError, match=r"`delta`.*outside its workspace"):
            env.unwrapped.perturb(delta=[0.0, 0.0, -0.6])
    finally:
        env.close()


def test_arm_scoop_refuses_a_pose_its_joints_cannot_take(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["ArmScoop"]
    base = env.unwrapped
    env.reset(seed=0)
    state, t0 = base.state, sim_time(base)
    with pytest.raises(ValueError, match=r"`to`.*cannot take within its joint limits.*pitch in \[-1\.200"):
        base.perturb(to=[-0.38, 0.84, 1.2])  # the spoon tipped far over at the soup-side corner
    np.testing.assert_array_equal(base.state, state)
    assert sim_time(base) == t0
    with pytest.raises(ValueError, match=r"options\['state'\]"):
        env.reset(seed=0, options={"state": [-0.38, 0.84, 1.2]})
    env.reset(seed=0)
    assert base.perturb_workspace.axes == ("y", "z", "pitch")


def test_kitchens_push_toward_stops_at_the_workspaces_edge(envs: dict[str, gym.Env[Any, Any]]) -> None:
    env = envs["Kitchen"]
    base = env.unwrapped
    env.reset(seed=0)
    start = base.state
    info = push_toward(base, start + np.array([0.0, 0.0, -1.0]), 0.5)  # aimed through the table
    assert info is not None and info["perturbed"]
    floor = base.perturb_workspace.low[2]
    assert floor <= base.state[2] < floor + 2e-4
    np.testing.assert_allclose(base.state[:2], start[:2], atol=1e-6)
