"""BlockStack plan execution: expert skills replayed as plans, plans classified, outcomes, bad input.

One env and one 2-skill episode (a pick, a place) for the module; skill starts
are reached again by reset + replaying the recorded actions (MuJoCo is deterministic).

The replay-fidelity measurement (:func:`replay_fidelity`, ``-m slow``) also runs as a script::

    MUJOCO_GL=osmesa python tests/control/test_blockstack_control.py --seeds 10 --skills 4 [--noise 0.005]
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from plan_replays import fidelity_parser, fidelity_rates, fidelity_row, noisy, print_fidelity, refuse_bad_plans
from robosuite_helpers import ROBOSUITE_MARKS, module_env

from steer_envs.envs.robosuite.blockstack import CUBE_HALF

pytestmark = ROBOSUITE_MARKS
SEED = 2
env = module_env("steer_envs.data.blockstack_skills:make_env")


def replay_fidelity(seeds: Sequence[int], skills_per_seed: int = 4, *, plan_noise: float = 0.0) -> dict[str, Any]:
    """Replay the expert's recorded skills as plans from their own start states; the agreement rates.

    For each seed the random planner's first ``skills_per_seed`` skills are
    recorded; skill k's start is reached again by resetting with the seed and
    replaying the recorded actions of skills ``0..k-1``; its plan
    (``skill_plan``) is classified and executed. Only the expert's successful,
    violation-free skills that fit a plan count. ``plan_noise`` (m): std of
    Gaussian noise on every waypoint's position (seeded), a stand-in for a
    generated plan's error. Returns the count, the rates ``replay_success``
    (executed the recorded skill, no violation), ``replay_executed``,
    ``classified``, and one row per skill.
    """
    from steer_envs.control.blockstack import classify_plan, execute_plan, yaw_of
    from steer_envs.data.blockstack_plans import skill_plan
    from steer_envs.data.blockstack_skills import make_env, record_episode

    env = make_env()
    rows: list[dict[str, Any]] = []
    try:
        for seed in seeds:
            records = record_episode(env, seed, skills_per_seed)
            rng = np.random.default_rng(seed)
            for k, rec in enumerate(records):
                made = skill_plan(rec)
                if not (rec.success and not rec.violation) or made is None:
                    continue
                env.reset(seed=seed)
                home = yaw_of(env.robosuite_obs["robot0_eef_quat"])  # the expert's home yaw
                for prev in records[:k]:
                    for action in prev.actions:
                        env.step(action)
                plan = noisy(made[1], plan_noise, rng)
                label = classify_plan(env, plan)
                out = execute_plan(env, plan, home_yaw=home)
                same_start = bool(np.allclose(out.trail[0], rec.eef[0], atol=1e-9))
                rows.append({**fidelity_row(seed, k, rec, label, out), "same_start": same_start})
    finally:
        env.close()
    return fidelity_rates(rows)


@pytest.fixture(scope="module")
def records(env: Any) -> list[Any]:
    from steer_envs.data.blockstack_skills import record_episode

    recs = record_episode(env, SEED, 2)
    assert [r.kind for r in recs] == ["pick", "place"] and all(r.success and not r.violation for r in recs)
    return recs


def start_of(env: Any, records: list[Any], k: int) -> None:
    """Reset to skill ``k``'s start state (reset + the earlier skills' actions)."""
    env.reset(seed=SEED)
    for rec in records[:k]:
        for action in rec.actions:
            env.step(action)
    assert np.allclose(env.state, records[k].eef[0], atol=1e-9)


def plan_of(record: Any) -> np.ndarray:
    from steer_envs.data.blockstack_plans import skill_plan

    made = skill_plan(record)
    assert made is not None
    return made[1]


def hold_plan(env: Any, n: int = 8, gripper: float = -1.0) -> np.ndarray:
    """A plan that keeps the eef where it is with a fixed gripper command."""
    return np.tile(np.r_[env.state, gripper], (n, 1))


@pytest.mark.parametrize("execution", ["open_loop", "closed_loop"])
def test_expert_pick_and_place_replay_as_plans(env: Any, records: list[Any], execution: str) -> None:
    from steer_envs.control.blockstack import classify_plan, execute_plan
    from steer_envs.data.blockstack_plans import PLAN_HORIZON, PLAN_STRIDE

    for k, rec in enumerate(records):
        start_of(env, records, k)
        plan = plan_of(rec)
        assert classify_plan(env, plan) == rec.name
        out = execute_plan(gym.Wrapper(env), plan, execution=execution)  # a wrapper is unwrapped
        assert out.executed == rec.name and not out.violation and out.success, (rec.name, out.executed)
        assert out.steps >= PLAN_HORIZON * PLAN_STRIDE and out.trail.shape == (out.steps + 1, 3)
        assert np.allclose(out.trail[0], rec.eef[0]) and np.allclose(out.trail[-1], env.state)
        # the eef ends near where the expert's did (the plan pads with its last waypoint)
        assert np.linalg.norm(out.trail[-1] - rec.eef[-1]) < 0.02


def raised(plan: np.ndarray, dz: float) -> np.ndarray:
    """``plan`` with every waypoint ``dz`` (m) higher."""
    return plan + np.array([0.0, 0.0, dz, 0.0])


def test_closed_loop_grasps_again_where_a_valid_pick_closed_on_nothing(env: Any, records: list[Any]) -> None:
    from steer_envs.control.blockstack import classify_plan, execute_plan

    pick = records[0]
    plan = raised(plan_of(pick), 0.022)  # still a pick by the classifier, but the pads close over the cube's top
    start_of(env, records, 0)
    assert classify_plan(env, plan) == pick.name
    out = execute_plan(env, plan)
    assert out.executed is None and out.regrasps == 0  # open loop closes on nothing and lifts an empty hand
    start_of(env, records, 0)
    out = execute_plan(env, plan, execution="closed_loop")
    assert out.success and out.executed == pick.name and out.regrasps == 1 and env.held_cube == pick.cube


def test_closed_loop_puts_a_valid_place_down_instead_of_dropping_it(env: Any, records: list[Any]) -> None:
    from steer_envs.control.blockstack import classify_plan, execute_plan

    place = records[1]
    plan = raised(plan_of(place), 0.018)  # opens 1.8 cm high: a place by the classifier, a drop in the world
    start_of(env, records, 1)
    assert classify_plan(env, plan) == place.name
    out = execute_plan(env, plan)
    assert out.executed == place.name and out.violation and not out.success
    start_of(env, records, 1)
    out = execute_plan(env, plan, execution="closed_loop")
    assert out.success and out.executed == place.name and env.held_cube is None


def test_closed_loop_runs_a_plan_that_is_no_skill_as_it_is(env: Any, records: list[Any]) -> None:
    from steer_envs.control.blockstack import classify_plan, execute_plan

    plan = raised(plan_of(records[0]), 0.06)  # closes 6 cm above the cube: no pick, and no retry makes one
    start_of(env, records, 0)
    assert classify_plan(env, plan) is None
    out = execute_plan(env, plan, execution="closed_loop")
    assert out.executed is None and out.regrasps == 0 and env.held_cube is None


def test_a_plan_that_does_nothing_executes_nothing(env: Any, records: list[Any]) -> None:
    from steer_envs.control.blockstack import PlanOutcome, classify_plan, execute_plan

    start_of(env, records, 0)
    plan = hold_plan(env, 4)
    assert classify_plan(env, plan) is None
    out = execute_plan(env, plan, stride=2)
    assert out.executed is None and not out.success and out.steps == 8 and out.trail.shape == (9, 3)
    assert PlanOutcome("pick_1", True, 3, np.zeros((4, 3)), np.zeros(33)).success is False
    assert PlanOutcome("pick_1", False, 3, np.zeros((4, 3)), np.zeros(33)).success is True


def test_classify_reads_the_closing_and_opening_waypoints(env: Any, records: list[Any]) -> None:
    from steer_envs.control.blockstack import classify_plan, free_table_spot

    start_of(env, records, 0)
    pos = env.cube_pos
    for cube in range(4):  # close at each cube's centre: a pick of it; high above it or beside it: none
        plan = np.array([[*env.state, -1.0], [*pos[cube], -1.0], [*pos[cube], 1.0]])
        assert classify_plan(env, plan) == f"pick_{cube}"
        high = plan.copy()
        high[1:, 2] += 0.06
        assert classify_plan(env, high) is None
        beside = plan.copy()
        beside[1:, 0] += 0.045
        assert classify_plan(env, beside) is None
    start_of(env, records, 1)  # holding: the held cube's centre where the plan opens decides
    held = env.held_cube
    offset = env.cube_pos[held] - env.state
    pos = env.cube_pos
    for j in (c for c in range(4) if c != held):
        centre = pos[j] + [0.0, 0.0, 2 * CUBE_HALF + 0.005]
        plan = np.array([[*env.state, 1.0], [*(centre - offset), 1.0], [*(centre - offset), -1.0]])
        assert classify_plan(env, plan) == f"place_{held}_on_{j}"
        plan[1:, 2] += 0.1  # opened far above the cube: a drop, no place
        assert classify_plan(env, plan) is None
    xy = free_table_spot(env, np.random.default_rng(0), exclude=held)
    spot = np.array([xy[0], xy[1], env.table_z + CUBE_HALF])
    plan = np.array([[*env.state, 1.0], [*(spot - offset), -1.0]])
    assert classify_plan(env, plan) == f"place_{held}_on_table"
    plan[1, 2] += 0.1
    assert classify_plan(env, plan) is None
    assert classify_plan(env, hold_plan(env, gripper=1.0)) is None  # never opens


def test_plan_target_reads_where_a_plan_heads_grasp_or_not(env: Any, records: list[Any]) -> None:
    from steer_envs.control.blockstack import classify_plan, plan_target

    start_of(env, records, 0)
    pos = env.cube_pos
    for cube in range(4):
        plan = np.array([[*env.state, -1.0], [*pos[cube], -1.0], [*pos[cube], 1.0]])
        assert plan_target(env, plan) == classify_plan(env, plan) == f"pick_{cube}"
        high = plan.copy()
        high[1:, 2] += 0.06  # closes too high to grasp: no skill, but it heads for the cube
        assert classify_plan(env, high) is None and plan_target(env, high) == f"pick_{cube}"
        never_closes = plan[:2].copy()  # ends above the cube without closing: heads for it
        never_closes[1, 2] += 0.05
        assert plan_target(env, never_closes) == f"pick_{cube}"
    start_of(env, records, 1)
    held = env.held_cube
    offset = env.cube_pos[held] - env.state
    pos = env.cube_pos
    for j in (c for c in range(4) if c != held):
        centre = pos[j] + [0.0, 0.0, 2 * CUBE_HALF + 0.1]  # released far above cube j: no place, but toward j
        plan = np.array([[*env.state, 1.0], [*(centre - offset), 1.0], [*(centre - offset), -1.0]])
        assert classify_plan(env, plan) is None and plan_target(env, plan) == f"place_{held}_on_{j}"
    assert plan_target(env, hold_plan(env, gripper=1.0)).startswith(f"place_{held}_on_")  # never opens: its end


def test_plan_target_tells_the_cubes_of_a_tower_apart(env: Any) -> None:
    from steer_envs.control.blockstack import classify_plan, plan_target, towers
    from steer_envs.data.blockstack_skills import record_episode

    recs = record_episode(env, 0, 2)  # seed 0: cube 2 goes onto cube 0
    env.reset(seed=0)
    for action in (a for rec in recs for a in rec.actions):
        env.step(action)
    assert [0, 2] in towers(env)
    pos = env.cube_pos
    assert np.linalg.norm(pos[0, :2] - pos[2, :2]) > 1e-4  # stacked a little off centre
    for cube, other in ((0, 2), (2, 0)):  # nearly the same xy: the closing waypoint's height decides
        point = np.r_[0.3 * pos[cube, :2] + 0.7 * pos[other, :2], pos[cube, 2]]  # xy nearer the other cube
        plan = np.array([[*env.state, -1.0], [*point, -1.0], [*point, 1.0]])
        assert plan_target(env, plan) == f"pick_{cube}"
    top = np.array([[*env.state, -1.0], [*pos[2], -1.0], [*pos[2], 1.0]])
    assert classify_plan(env, top) == "pick_2"


def test_bad_input_is_refused(env: Any, records: list[Any]) -> None:
    from steer_envs.control.blockstack import classify_plan, execute_plan, plan_target

    env.reset(seed=SEED)
    good = hold_plan(env, 2)
    refuse_bad_plans((execute_plan, classify_plan, plan_target), env, good)
    for fn in (execute_plan, classify_plan, plan_target):
        with pytest.raises(TypeError, match="plan"):
            fn(env, good.astype(bool))
    with pytest.raises(ValueError, match="stride"):
        execute_plan(env, good, stride=0)
    with pytest.raises(TypeError, match="stride"):
        execute_plan(env, good, stride=2.0)
    with pytest.raises(TypeError, match="home_yaw"):
        execute_plan(env, good, home_yaw="0")
    for bad in ("closed", None, 1):
        with pytest.raises(ValueError, match="execute_plan: execution must be one of"):
            execute_plan(env, good, execution=bad)  # type: ignore[arg-type]


def test_shared_pieces_are_the_experts_and_the_plan_layout() -> None:
    import steer_envs.control.blockstack as pe
    import steer_envs.data.blockstack_plans as plans
    import steer_envs.data.experts.blockstack as expert

    assert (pe.PLAN_STRIDE, pe.PLAN_DIM) == (plans.PLAN_STRIDE, plans.PLAN_DIM)
    assert expert.Skill is pe.Skill and expert.free_table_spot is pe.free_table_spot


@pytest.mark.slow
def test_replay_fidelity_of_forty_expert_skills() -> None:
    result = replay_fidelity(list(range(10)), 4)
    assert result["skills"] >= 38 and all(r["same_start"] for r in result["rows"])
    assert result["replay_success"] >= 0.9 and result["classified"] >= 0.95, result


if __name__ == "__main__":
    import os

    os.environ.setdefault("MUJOCO_GL", "osmesa")
    parser = fidelity_parser("BlockStack", 10, "reset seeds 0..N-1")
    parser.add_argument("--skills", type=int, default=4, help="skills per seed")
    args = parser.parse_args()
    print_fidelity(
        replay_fidelity(range(args.first_seed, args.first_seed + args.seeds), args.skills, plan_noise=args.noise)
    )
