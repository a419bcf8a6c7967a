"""TowerSketchUser: intended skills toward the goal tower (recovery included), 3-D sketches, seeding, bad input.

One env for the module; the states are a reset, a teleported wrong cube and one
expert pick (a skill costs about a second).

The sketch -> plan ranking check (:func:`sketch_sanity`, ``-m slow``) also runs as a script::

    MUJOCO_GL=osmesa python tests/users/test_block_sketcher.py --seeds 10 [--follow-through]
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
import pytest
from robosuite_helpers import ROBOSUITE_MARKS

from steer_envs.core.interaction import Sketch
from steer_envs.envs.robosuite.blockstack import CUBE_HALF

pytestmark = ROBOSUITE_MARKS
SEED = 5
ORDER = (2, 0, 3, 1)


@pytest.fixture(scope="module")
def env() -> Iterator[Any]:
    from steer_envs.data.blockstack_skills import make_env

    made = make_env()
    yield made
    made.close()


def run(env: Any, skill: Any) -> None:
    from steer_envs.data.experts.blockstack import BlockStackSkills

    skills = BlockStackSkills(env)
    skills.start(skill)
    while not skills.done:
        env.step(skills.act())
    assert skills.succeeded(), skill


def expert_plan(env: Any, skill: Any) -> np.ndarray | None:
    """The expert's plan of ``skill`` from ``env``'s state (the env is stepped through it); None if it failed."""
    from steer_envs.data.blockstack_plans import PLAN_HORIZON, PLAN_STRIDE
    from steer_envs.data.experts.blockstack import BlockStackSkills

    skills = BlockStackSkills(env)
    skills.start(skill)
    eef, grip = [env.state], [env._gripper]
    while not skills.done:
        env.step(skills.act())
        eef.append(env.state)
        grip.append(env._gripper)
    steps = len(eef) - 1
    if not skills.succeeded() or steps > PLAN_STRIDE * PLAN_HORIZON:
        return None
    ends = np.minimum(PLAN_STRIDE * np.arange(1, PLAN_HORIZON + 1), steps)  # as skill_plan
    return np.concatenate([np.asarray(eef)[ends], np.asarray(grip)[ends, None]], axis=1)


def sketch_sanity(seeds: Sequence[int], *, jitter: float = 0.01, follow_through: bool = False) -> list[dict[str, Any]]:
    """For each seed two states (the reset; holding the first cube the user picks): rank the expert's plans.

    At each state the user's sketch of the intended skill is compared
    (``alignment_cost_np``) with the expert's plans of every skill possible there
    (each pick; each place on a cube and one on a free table spot), each recorded
    from the same state (reset with the seed and replay). One row per state: the
    intended skill, every candidate's cost, whether the intended plan is the cheapest.
    """
    from steer_envs.control.blockstack import Skill, free_table_spot
    from steer_envs.data.blockstack_skills import make_env
    from steer_envs.data.experts.blockstack import BlockStackSkills
    from steer_envs.steering.objectives import alignment_cost_np
    from steer_envs.users.block_sketcher import TowerSketchUser

    env = make_env()
    rows: list[dict[str, Any]] = []

    def replay(seed: int, prefix: list[np.ndarray]) -> None:
        env.reset(seed=seed)
        for a in prefix:
            env.step(a)

    try:
        for seed in seeds:
            order = tuple(int(c) for c in np.random.default_rng(seed).permutation(4))
            user = TowerSketchUser(order, seed=seed, jitter=jitter, follow_through=follow_through)
            prefix: list[np.ndarray] = []
            for _ in range(2):
                replay(seed, prefix)
                drawn = user.draw(env)
                intended, held = drawn.skill, env.held_cube
                if held is None:
                    cands = [Skill("pick", c) for c in range(4)]
                else:
                    spot = free_table_spot(env, np.random.default_rng(seed), exclude=held)
                    cands = [Skill("place", held, j) for j in range(4) if j != held]
                    table = Skill("place", held, None, (float(spot[0]), float(spot[1])))
                    cands.append(intended if intended.onto is None else table)
                costs: dict[str, float] = {}
                for cand in cands:
                    replay(seed, prefix)
                    plan = expert_plan(env, cand)
                    if plan is not None:
                        costs[cand.name] = float(alignment_cost_np(plan[None, :, :3], drawn.sketch)[0])
                best = min(costs, key=costs.__getitem__) if costs else None
                rows.append({"seed": seed, "intended": intended.name, "costs": costs, "best": best == intended.name})
                replay(seed, prefix)  # the next state: the intended skill done by the expert
                skills = BlockStackSkills(env)
                skills.start(intended)
                while not skills.done:
                    prefix.append(skills.act())
                    env.step(prefix[-1])
                if not skills.succeeded():
                    break
    finally:
        env.close()
    return rows


def plan_from(sketch: Sketch, close: bool) -> np.ndarray:
    """The sketch as a plan that switches the gripper at its last point."""
    g = np.full((len(sketch), 1), 1.0 if not close else -1.0)
    g[-1] = 1.0 if close else -1.0
    return np.concatenate([sketch.points, g], axis=1)


def test_pick_sketch_goes_up_over_and_down_to_the_intended_cube(env: Any) -> None:
    from steer_envs.control.blockstack import classify_plan
    from steer_envs.users.block_sketcher import TowerSketchUser

    env.reset(seed=SEED)
    user = TowerSketchUser(ORDER, seed=1)
    drawn = user.draw(env)
    assert drawn.skill.name == f"pick_{ORDER[1]}"  # the base already stands on the table
    pts = drawn.sketch.points
    assert pts.shape == (32, 3) and np.allclose(pts[0], env.state)  # from the hand, no jitter there
    assert np.allclose(drawn.target, env.cube_pos[ORDER[1]])
    assert np.linalg.norm(pts[-1] - drawn.target) < 0.04  # ~1 cm hand jitter
    assert pts[:, 2].max() > env.table_z + 0.14  # carried high
    gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    assert gaps.std() < 0.05 * gaps.mean()  # even in arc length
    assert classify_plan(env, plan_from(drawn.sketch, close=True)) == drawn.skill.name
    # without jitter the sketch ends on the target; the same seed draws the same sketch
    exact = TowerSketchUser(ORDER, jitter=0.0, n_points=10).sketch(env, drawn.skill)
    assert exact.points.shape == (10, 3) and np.allclose(exact.points[-1], drawn.target)
    assert TowerSketchUser(ORDER, seed=1).draw(env).sketch == drawn.sketch
    assert TowerSketchUser(ORDER, seed=2).draw(env).sketch != drawn.sketch
    through = TowerSketchUser(ORDER, seed=1, jitter=0.0, follow_through=True).sketch(env, drawn.skill)
    assert through.points[-1, 2] > drawn.target[2] + 0.1  # back up to the carry height


def test_a_wrong_cube_on_the_partial_tower_is_picked_off(env: Any) -> None:
    from steer_envs.users.block_sketcher import TowerSketchUser

    env.reset(seed=SEED)
    base_xy = env.cube_pos[ORDER[0], :2] - env.rs_env.table_offset[:2]
    wrong = ORDER[2]
    pos = np.r_[base_xy, 3 * CUBE_HALF]
    rs = env.rs_env
    rs.sim.data.set_joint_qpos(
        rs.cubes[wrong].joints[0],
        np.r_[pos + np.r_[rs.table_offset[:2], env.table_z], env.cube_quat[ORDER[0]][[3, 0, 1, 2]]],
    )
    rs.sim.forward()
    for _ in range(5):
        env.step(np.r_[np.zeros(6), -1.0].astype(np.float32))
    assert env.supports[wrong] == ORDER[0]
    assert TowerSketchUser(ORDER).intended_skill(env).name == f"pick_{wrong}"


def test_place_sketches_draw_the_eef_path_for_the_held_cube(env: Any) -> None:
    from steer_envs.control.blockstack import Skill, classify_plan
    from steer_envs.users.block_sketcher import TowerSketchUser

    env.reset(seed=SEED)
    wrong = ORDER[3]  # holding a cube the tower does not need yet: it goes to the table
    run(env, Skill("pick", wrong))
    user = TowerSketchUser(ORDER, seed=3, jitter=0.0)
    drawn = user.draw(env)
    assert drawn.skill.kind == "place" and drawn.skill.onto is None and drawn.skill.xy is not None
    offset = env.cube_pos[wrong] - env.state
    assert np.allclose(drawn.target + offset, [*drawn.skill.xy, env.table_z + CUBE_HALF])
    assert np.allclose(drawn.sketch.points[-1], drawn.target)
    assert classify_plan(env, plan_from(drawn.sketch, close=False)) == drawn.skill.name
    onto = Skill("place", wrong, ORDER[0])
    on_base = user.sketch(env, onto)
    assert np.allclose(on_base.points[-1] + offset, env.cube_pos[ORDER[0]] + [0, 0, 2 * CUBE_HALF])
    assert classify_plan(env, plan_from(on_base, close=False)) == onto.name
    with pytest.raises(ValueError, match="skill"):
        user.sketch(env, Skill("place", ORDER[0], None, (0.0, 0.0)))  # not the held cube
    with pytest.raises(ValueError, match="skill"):
        user.sketch(env, Skill("pick", ORDER[0]))  # the hand is full


def test_intended_skills_follow_the_goal_tower_planner_and_carry_like_the_expert(env: Any) -> None:
    from steer_envs.data.experts.blockstack import BlockStackSkills, GoalTowerPlanner
    from steer_envs.users import block_sketcher as bs

    assert (bs.CARRY_CLEARANCE, bs.MIN_CARRY_Z, bs.RETREAT) == (
        BlockStackSkills.carry_clearance,
        BlockStackSkills.min_carry_z,
        BlockStackSkills.retreat,
    )
    env.reset(seed=SEED, options={"goal_order": ORDER})
    planner = GoalTowerPlanner(0)
    user = bs.TowerSketchUser(ORDER)
    for _ in range(2):  # the reset, then holding the cube picked
        skill = user.intended_skill(env)
        assert skill == planner.next_skill(env)
        run(env, skill)


def test_bad_input_is_refused(env: Any) -> None:
    from steer_envs.control.blockstack import Skill
    from steer_envs.users.block_sketcher import TowerSketchUser

    for bad, err in (((0, 1, 2), ValueError), ((0, 1, 2, 2), ValueError), ("0123", TypeError), (None, TypeError)):
        with pytest.raises(err, match="goal_order"):
            TowerSketchUser(bad)  # type: ignore[arg-type]
    for kwargs, err, name in (
        ({"seed": -1}, ValueError, "seed"),
        ({"seed": 1.0}, TypeError, "seed"),
        ({"n_points": 1}, ValueError, "n_points"),
        ({"jitter": -0.01}, ValueError, "jitter"),
        ({"jitter": "1"}, TypeError, "jitter"),
        ({"smoothing": 0.0}, ValueError, "smoothing"),
        ({"follow_through": 1}, TypeError, "follow_through"),
    ):
        with pytest.raises(err, match=name):
            TowerSketchUser(ORDER, **kwargs)
    user = TowerSketchUser(ORDER)
    with pytest.raises(TypeError, match="env"):
        user.intended_skill(object())
    env.reset(seed=SEED)
    with pytest.raises(TypeError, match="skill"):
        user.sketch(env, "pick_0")  # type: ignore[arg-type]
    for skill in (Skill("grab", 0), Skill("pick", 7), Skill("place", 1, 1), Skill("place", 1), Skill("place", 1, 9)):
        with pytest.raises(ValueError, match="skill"):
            user.sketch(env, skill)
    with pytest.raises(TypeError, match=r"skill\.cube"):
        user.sketch(env, Skill("pick", "0"))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"skill\.xy"):
        user.sketch(env, Skill("place", 1, None, (0.0, float("nan"))))


@pytest.mark.slow
def test_the_intended_skills_plan_is_closest_to_the_sketch() -> None:
    rows = sketch_sanity(range(5))
    assert len(rows) == 10 and all(r["best"] for r in rows), rows


if __name__ == "__main__":
    import os

    os.environ.setdefault("MUJOCO_GL", "osmesa")
    parser = argparse.ArgumentParser(description="BlockStack: the sketch of the intended skill vs the expert's plans")
    parser.add_argument("--seeds", type=int, default=10, help="reset seeds 0..N-1")
    parser.add_argument("--jitter", type=float, default=0.01)
    parser.add_argument("--follow-through", action="store_true")
    args = parser.parse_args()
    found = sketch_sanity(range(args.seeds), jitter=args.jitter, follow_through=args.follow_through)
    ratios = []
    for r in found:
        mine = r["costs"][r["intended"]]
        ratios.append(mine / min(v for k, v in r["costs"].items() if k != r["intended"]))
        print(r["seed"], r["intended"], {k: round(v, 3) for k, v in r["costs"].items()})
    print(
        f"{sum(r['best'] for r in found)}/{len(found)} states: the intended plan is the cheapest; "
        f"cost / best other: mean {np.mean(ratios):.3f}, max {np.max(ratios):.3f}"
    )
