"""Kitchen plan execution: expert skills replayed as plans, plans classified, outcomes, bad input.

One env (the microwave task) and the first two skills of one episode for the
module (open the door, pick the bowl); skill starts are reached
again by reset + replaying the recorded actions (MuJoCo is deterministic).
Synthetic plans are classified against scenes of the real geometry.

The replay-fidelity measurement (:func:`replay_fidelity`, ``-m slow``) also runs as a script::

    MUJOCO_GL=osmesa python tests/control/test_kitchen_control.py --seeds 20 [--noise 0.005]
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from plan_replays import fidelity_parser, fidelity_rates, fidelity_row, noisy, print_fidelity, refuse_bad_plans
from robosuite_helpers import ROBOSUITE_MARKS, module_env

from steer_envs.envs.robosuite.kitchen import rotation
from steer_envs.envs.robosuite.kitchen_assets import BOWL_HEIGHT
from steer_envs.envs.robosuite.kitchen_scene import CAVITY_FRONT_X, CAVITY_HIGH, CAVITY_LOW, SINK_XY, TABLE_Z

pytestmark = ROBOSUITE_MARKS
SEED = 0
env = module_env("steer_envs.data.kitchen_skills:make_env", "microwave")


@pytest.fixture(scope="module")
def records(env: Any) -> list[Any]:
    from steer_envs.data.kitchen_skills import record_episode

    recs = record_episode(env, SEED, max_skills=2)
    assert [r.name for r in recs] == ["open_door", "pick_bowl"]
    assert all(r.success and not r.violation for r in recs)
    return recs


def replay_fidelity(seeds: Sequence[int], *, plan_noise: float = 0.0) -> dict[str, Any]:
    """Replay the expert's recorded skills as plans from their own start states; the agreement rates.

    Seed ``s`` records an episode of the data suite's task for it (even
    microwave, odd sink); skill k's start is reached again with
    ``replay_to_start``; its plan (``skill_plan``) is classified (from the env)
    and executed. Only the expert's successful, violation-free skills that fit
    a plan count. ``plan_noise`` (m): std of Gaussian noise on every waypoint's
    position (seeded), a stand-in for a generated plan's error. Returns the
    count, the rates ``replay_success`` (executed the recorded skill, no
    violation), ``replay_executed``, ``classified``, and one row per skill.
    """
    from steer_envs.control.kitchen import classify_kitchen_plan, execute_kitchen_plan
    from steer_envs.data.kitchen_plans import skill_plan
    from steer_envs.data.kitchen_skills import DATA_TASKS, make_env, record_episode, replay_to_start

    envs: dict[str, Any] = {}
    rows: list[dict[str, Any]] = []
    try:
        for seed in seeds:
            task = DATA_TASKS[seed % len(DATA_TASKS)]
            env = envs.setdefault(task, make_env(task))
            records = record_episode(env, seed)
            rng = np.random.default_rng(seed)
            for k, rec in enumerate(records):
                made = skill_plan(rec)
                if not (rec.success and not rec.violation) or made is None:
                    continue
                replay_to_start(env, records, k)
                plan = noisy(made[1], plan_noise, rng)
                label = classify_kitchen_plan(env, plan)
                rows.append(fidelity_row(seed, k, rec, label, execute_kitchen_plan(env, plan)))
    finally:
        for made_env in envs.values():
            made_env.close()
    return fidelity_rates(rows)


def plan_of(record: Any) -> np.ndarray:
    from steer_envs.data.kitchen_plans import skill_plan

    made = skill_plan(record)
    assert made is not None
    return made[1].astype(np.float64)


def hold_plan(env: Any, n: int = 4, gripper: float = -1.0) -> np.ndarray:
    """A plan that keeps the eef where it is with a fixed gripper command."""
    from steer_envs.control.kitchen import eef_yaw

    return np.tile(np.r_[env.state, eef_yaw(env), gripper], (n, 1))


def handle_at(scene: Any, angle: float) -> np.ndarray:
    """Where the handle's centre is with the door open by ``angle`` (rad), from a scene with the door shut."""
    c, s = np.cos(-angle), np.sin(-angle)
    rel = scene.handle - scene.hinge
    return scene.hinge + np.array([c * rel[0] - s * rel[1], s * rel[0] + c * rel[1], rel[2]])


def test_expert_skills_replay_as_plans(env: Any, records: list[Any]) -> None:
    from steer_envs.control.kitchen import classify_kitchen_plan, execute_kitchen_plan
    from steer_envs.data.kitchen_plans import PLAN_HORIZON, PLAN_STRIDE
    from steer_envs.data.kitchen_skills import replay_to_start

    for k in (0, 1):  # open the door (a half turn of the wrist, a swing), pick the bowl (the turn back)
        rec = records[k]
        replay_to_start(env, records, k)
        plan = plan_of(rec)
        assert classify_kitchen_plan(env, plan) == rec.name
        out = execute_kitchen_plan(gym.Wrapper(env), plan)  # a wrapper is unwrapped
        assert out.executed == rec.name and not out.violation and out.success, (rec.name, out)
        assert (out.mode_before, out.mode_after) == (rec.mode_before, rec.mode_after)
        assert out.steps >= PLAN_HORIZON * PLAN_STRIDE and out.trail.shape == (out.steps + 1, 3)
        assert np.allclose(out.trail[0], rec.eef[0]) and np.allclose(out.trail[-1], env.state)
        assert np.linalg.norm(out.trail[-1] - rec.eef[-1]) < 0.02  # the eef ends near where the expert's did
        assert out.obs.shape == (17,)


def test_closed_loop_keeps_up_with_a_plan_that_runs_ahead_and_grasps_again(env: Any, records: list[Any]) -> None:
    from steer_envs.control.kitchen import classify_kitchen_plan, execute_kitchen_plan
    from steer_envs.data.kitchen_skills import replay_to_start

    pick = records[1]
    plan = plan_of(pick)
    replay_to_start(env, records, 1)
    assert execute_kitchen_plan(env, plan, stride=2).executed is None  # open loop closes before the bowl
    replay_to_start(env, records, 1)
    out = execute_kitchen_plan(env, plan, stride=2, execution="closed_loop")  # waits on the waypoints
    assert out.success and out.executed == pick.name and out.regrasps == 0
    high = plan.copy()
    close = int(np.argmax(high[:, 4] > 0))
    high[close, 2] += 0.03  # closes 3 cm higher: still a pick by the classifier, but over the bowl's rim
    high[:close, 2] += np.linspace(0.0, 0.03, close)  # (open loop lifts an empty hand)
    replay_to_start(env, records, 1)
    assert classify_kitchen_plan(env, high) == pick.name
    out = execute_kitchen_plan(env, high, execution="closed_loop")
    assert out.success and out.executed == pick.name and out.regrasps == 1


def test_recorded_skills_classify_offline_from_their_scenes(records: list[Any]) -> None:
    from steer_envs.control.kitchen import classify_kitchen_plan

    for rec in records:
        assert classify_kitchen_plan(rec.scene, plan_of(rec)) == rec.name
    assert [r.scene.held for r in records] == [False, False]
    assert records[1].scene.door_angle > 1.0 and records[0].scene.door_angle < 0.05


def test_a_plan_that_does_nothing_executes_nothing(env: Any) -> None:
    from steer_envs.control.kitchen import (
        KitchenPlanOutcome,
        classify_kitchen_plan,
        execute_kitchen_plan,
    )

    env.reset(seed=SEED)
    plan = hold_plan(env)
    assert classify_kitchen_plan(env, plan) is None
    out = execute_kitchen_plan(env, plan, stride=2)
    assert out.executed is None and not out.success and out.steps == 8 and out.trail.shape == (9, 3)
    assert out.mode_before == out.mode_after == "closed_table"
    modes = {"mode_before": "a", "mode_after": "b"}
    assert not KitchenPlanOutcome("pick_bowl", True, 3, np.zeros((4, 3)), np.zeros(17), **modes).success
    assert KitchenPlanOutcome("pick_bowl", False, 3, np.zeros((4, 3)), np.zeros(17), **modes).success


def test_the_handle_turns_about_the_hinge_and_eef_yaw_is_the_experts(env: Any) -> None:
    from steer_envs.control.kitchen import eef_yaw, kitchen_scene
    from steer_envs.data.experts.kitchen import _yaw

    env.reset(seed=SEED)
    shut = kitchen_scene(env)
    rs = env.rs_env
    rs.sim.data.qpos[rs.door_qpos] = -1.3
    rs.sim.forward()
    assert np.allclose(env.handle_pos, handle_at(shut, 1.3), atol=1e-6) and np.allclose(env.hinge_pos, shut.hinge)
    env.reset(seed=SEED)
    assert eef_yaw(gym.Wrapper(env)) == _yaw(env.eef_rotation)
    for yaw in (-2.0, 0.0, 1.0, 3.0):
        rot = rotation(yaw, 0.0)
        assert np.isclose(np.arctan2(-rot[0, 0], rot[1, 0]), yaw)


def test_classify_reads_where_the_gripper_closes_and_opens(env: Any) -> None:
    from steer_envs.control.kitchen import (
        HANDLE_Z_RANGE,
        classify_kitchen_plan,
        kitchen_scene,
    )

    env.reset(seed=SEED)
    scene = kitchen_scene(env)
    start = np.r_[scene.eef, 0.0, -1.0]

    def grasp(point: np.ndarray, then: Sequence[np.ndarray] = ()) -> np.ndarray:
        """Approach ``point`` open, close there, move closed through ``then``, open at the end."""
        path = [point, *then]
        rows = [start, np.r_[point, 0.0, -1.0], *(np.r_[p, 0.0, 1.0] for p in path), np.r_[path[-1], 0.0, -1.0]]
        return np.array(rows)

    # the bowl: close at its centre; high above it or beside it: nothing
    up, ahead = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    bowl = scene.bowl + 0.005 * up
    assert classify_kitchen_plan(scene, grasp(bowl)) == "pick_bowl"
    assert classify_kitchen_plan(scene, grasp(bowl + 0.06 * up)) is None
    assert classify_kitchen_plan(scene, grasp(bowl + 0.04 * ahead)) is None
    assert classify_kitchen_plan(scene, np.array([start, [*bowl, 0.0, -1.0]])) is None  # never closes
    # the door: close on the handle, swing along the arc about the hinge
    on_bar = np.array([0.0, 0.0, 0.14])
    swing_open = [handle_at(scene, a) + on_bar for a in np.linspace(0.1, 1.3, 6)]
    assert classify_kitchen_plan(scene, grasp(scene.handle + on_bar, swing_open)) == "open_door"
    assert classify_kitchen_plan(scene, grasp(scene.handle + on_bar, swing_open[:3])) is None  # not open enough
    assert classify_kitchen_plan(scene, grasp(scene.handle + on_bar)) is None  # no swing
    nudged = handle_at(scene, 0.1) + on_bar  # the door gave a little as the hand came down: still the handle
    assert classify_kitchen_plan(scene, grasp(nudged, swing_open)) == "open_door"
    assert classify_kitchen_plan(scene, grasp(handle_at(scene, -0.3) + on_bar, swing_open)) is None  # past the bar
    outward = np.r_[(scene.handle - scene.hinge)[:2], 0.0] / np.linalg.norm((scene.handle - scene.hinge)[:2])
    assert classify_kitchen_plan(scene, grasp(scene.handle + on_bar + 0.04 * outward, swing_open)) is None
    high = scene.handle + (HANDLE_Z_RANGE[1] + 0.02) * up
    assert classify_kitchen_plan(scene, grasp(high, [p + 0.04 * up for p in swing_open])) is None
    opened = dataclasses.replace(scene, door_angle=1.3, handle=handle_at(scene, 1.3))
    swing_shut = [handle_at(scene, a) + on_bar for a in np.linspace(1.2, 0.0, 6)]
    assert classify_kitchen_plan(opened, grasp(opened.handle + on_bar, swing_shut)) == "close_door"
    assert classify_kitchen_plan(opened, grasp(opened.handle + on_bar, swing_open)) is None  # already open
    assert classify_kitchen_plan(scene, grasp(scene.handle + on_bar, swing_shut)) is None  # a shut door
    # holding: the held bowl's centre where the plan opens
    held = dataclasses.replace(scene, held=True, bowl=scene.eef - 0.01 * up)
    offset = held.bowl - held.eef
    sink = np.array([*SINK_XY, TABLE_Z + 0.01 + BOWL_HEIGHT / 2 + 0.005])
    oven = np.array([CAVITY_FRONT_X + 0.05, (CAVITY_LOW[1] + CAVITY_HIGH[1]) / 2, CAVITY_LOW[2] + BOWL_HEIGHT / 2])

    def release(centre: np.ndarray) -> np.ndarray:
        return np.array(
            [np.r_[held.eef, 0.0, 1.0], np.r_[centre - offset, 0.0, 1.0], np.r_[centre - offset, 0.0, -1.0]]
        )

    assert classify_kitchen_plan(held, release(sink)) == "place_in_sink"
    assert classify_kitchen_plan(held, release(oven)) == "place_in_microwave"
    assert classify_kitchen_plan(held, release(sink + 0.1 * up)) is None  # a drop
    assert classify_kitchen_plan(held, release(oven + 0.1 * up)) is None
    assert classify_kitchen_plan(held, release(np.array([-0.2, -0.1, TABLE_Z + BOWL_HEIGHT / 2]))) is None
    assert classify_kitchen_plan(held, release(sink)[:2]) is None  # never opens


def test_bad_input_is_refused(env: Any) -> None:
    from steer_envs.control.kitchen import (
        classify_kitchen_plan,
        eef_yaw,
        execute_kitchen_plan,
        kitchen_scene,
    )

    env.reset(seed=SEED)
    good = hold_plan(env, 2)
    refuse_bad_plans((execute_kitchen_plan, classify_kitchen_plan), env, good)
    with pytest.raises(ValueError, match="stride"):
        execute_kitchen_plan(env, good, stride=0)
    with pytest.raises(TypeError, match="stride"):
        execute_kitchen_plan(env, good, stride=2.0)
    for bad in ("closed", None):
        with pytest.raises(ValueError, match="execute_kitchen_plan: execution must be one of"):
            execute_kitchen_plan(env, good, execution=bad)  # type: ignore[arg-type]
    for fn in (eef_yaw, kitchen_scene):
        with pytest.raises(TypeError, match="env"):
            fn(object())


def test_bad_replays_are_refused(env: Any, records: list[Any]) -> None:
    from steer_envs.data.kitchen_skills import record_episode, replay_to_start

    with pytest.raises(TypeError, match="env"):
        replay_to_start(object(), records, 0)
    with pytest.raises(ValueError, match="index"):
        replay_to_start(env, records, 2)
    with pytest.raises(ValueError, match="records"):
        replay_to_start(env, records[1:], 0)  # not an episode from its start
    with pytest.raises(TypeError, match="records"):
        replay_to_start(env, "abc", 0)
    with pytest.raises(TypeError, match="env"):
        record_episode(object(), 0)
    with pytest.raises(ValueError, match="max_skills"):
        record_episode(env, 0, max_skills=0)
    with pytest.raises(TypeError, match="seed"):
        record_episode(env, 0.5)


def test_shared_layout() -> None:
    import steer_envs.control.kitchen as pe
    import steer_envs.data.kitchen_plans as plans

    assert (pe.PLAN_STRIDE, pe.PLAN_DIM) == (plans.PLAN_STRIDE, plans.PLAN_DIM)


@pytest.mark.slow
def test_replay_fidelity_of_the_experts_skills() -> None:
    result = replay_fidelity(list(range(20)))
    assert result["skills"] >= 40
    assert result["replay_success"] >= 0.95 and result["classified"] >= 0.95, result


if __name__ == "__main__":
    import os

    os.environ.setdefault("MUJOCO_GL", "osmesa")
    args = fidelity_parser("Kitchen", 20, "reset seeds 0..N-1 (even: microwave, odd: sink)").parse_args()
    print_fidelity(replay_fidelity(range(args.first_seed, args.first_seed + args.seeds), plan_noise=args.noise))
