"""Building a chosen 4-block tower by sketching (thesis Table 2.2): a user steers a frozen skill policy.

:func:`tower_trial` resets BlockStack at an evaluation scene
(:data:`~steer_envs.steering.study.SCENE_SEED_OFFSET` ``+ seed``: never a
training scene), draws the user's tower order from the seed and lets a
:class:`~steer_envs.users.block_sketcher.TowerSketchUser` steer the frozen
skill policy: at every interaction the user names the next skill toward the
tower (recovering from earlier mistakes as a person would), sketches it in 3D
from the end effector, the sampler (:func:`make_method_sampler`) returns a
batch of plans and picks one, and the plan is executed
(:func:`~steer_envs.control.blockstack.execute_plan`; ``execution``
``"open_loop"`` by default, or ``"closed_loop"``: waypoints reached within a
tolerance, grasps checked by contact and retried, releases settled). The
thesis's scoring, per interaction:

* *aligned* (``TA`` and the AS/AF/MS/MF quadrants): the thesis's definition,
  "the conditional sample [...] corresponds to the intended block", aligned
  "regardless of outcome": the picked plan *heads for* the intended cube or
  tower, grasp or not (:func:`~steer_envs.control.blockstack.plan_target`:
  where it closes or opens the gripper, else its last waypoint);
* *skill-aligned* (``TA_skill``, ``AS_skill``): a stricter reading, the picked
  plan is also the intended skill in shape
  (:func:`~steer_envs.control.blockstack.classify_plan`: it closes at a cube's
  height, or opens just above the tower top or table); a plan that traces the
  sketch to the right cube but never grasps is aligned, not skill-aligned;
* *success*: the executed skill happened in the world (a cube picked, or
  placed and resting) without a drop or a falling tower;
* *valid* and *executed_ok*: the policy's part and the robot's part of
  success, apart: the picked plan is some skill in shape (``valid``:
  :func:`~steer_envs.control.blockstack.classify_plan` reads a skill, the
  intended one or not), and a valid plan's execution did that skill without a
  drop or a falling tower (``executed_ok``, a share of the valid plans).

A trial ends when the tower stands or after ``max_interactions``. Its metrics
are shares of its interactions (TA, CS, valid and the AS/AF/MS/MF quadrants;
``executed_ok`` of its valid plans, None without one), the
share of the batch that performs the intended skill (``batch_aligned``: how
often the intended mode is in the batch at all), whether the tower was built,
and the mean latency of the steering calls.

A method ending in ``+safe`` adds the task's safety cost of the current
state (:func:`tower_safety_cost`, weight ``safety_weight``) to its sampler:
the gripper may close only at a free cube and open only where the held cube
can rest, and the hand stays above the table.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import torch

from steer_envs.core.regions import Boxes
from steer_envs.core.validation import real_scalar
from steer_envs.steering.base import Sampler
from steer_envs.steering.costs import PlanCost, region_cost, switch_cost
from steer_envs.steering.registry import make_sampler
from steer_envs.steering.study import SCENE_SEED_OFFSET, quadrant_shares

__all__ = [
    "FLOW_PREFIX",
    "METHOD_SAMPLERS",
    "SAFE_SUFFIX",
    "TABLE_BETA_METHODS",
    "make_method_sampler",
    "tower_safety_cost",
    "tower_stands",
    "tower_trial",
]

#: method -> (sampler name, keyword arguments): thesis Table 2.2's columns (its header's beta 100) plus RS, SS
#: and GD at the beta 25 that the thesis's text names for the same table (``DP-GD-B25``).
METHOD_SAMPLERS: dict[str, tuple[str, dict[str, Any]]] = {
    "DP-RS": ("RS", {}),
    "DP-PR": ("PR", {}),
    "DP-GD": ("GD", {"guide_ratio": 100.0}),
    "DP-GD-I50": ("GD", {"guide_ratio": 100.0, "min_guided_t": 50}),
    "DP-GD-B25": ("GD", {"guide_ratio": 25.0}),
    "DP-SS": ("SS", {}),
}
#: the methods whose beta a study's ``guide_ratio`` replaces (the table header's beta 100)
TABLE_BETA_METHODS: tuple[str, ...] = ("DP-GD", "DP-GD-I50")
#: a method name ending in this adds :func:`tower_safety_cost` to its sampler (``"DP-GD+safe"``)
SAFE_SUFFIX = "+safe"
#: ``"FLOW-GD"`` is ``"DP-GD"``'s sampler on a flow-matching policy (the samplers take either kind)
FLOW_PREFIX = "FLOW-"
#: the guards sit this far inside the skill classifier's tolerances: a plan the cost is happy with classifies
_GUARD_MARGIN = 0.7


def make_method_sampler(
    method: str, guide_ratio: float | None = None, use_clipped_model_output: bool = True
) -> Sampler:
    """The sampler of ``method`` (``guide_ratio`` replaces the beta of :data:`TABLE_BETA_METHODS` when given).

    ``method``: a key of :data:`METHOD_SAMPLERS`, optionally with ``FLOW-`` for
    ``DP-`` (the same sampler; the policy is the caller's) and ``+safe``.

    ``use_clipped_model_output`` goes to GD and SS (see
    :class:`~steer_envs.steering.GuidedDiffusion`); on by default here:
    over this policy's 100 DDIM steps ITPS's step carries guided plans away from
    the sketch.

    >>> make_method_sampler("DP-GD-I50", guide_ratio=25.0)
    GuidedDiffusion(guide_ratio=25.0, min_guided_t=50, use_clipped_model_output=True)
    >>> make_method_sampler("FLOW-GD-B25")
    GuidedDiffusion(guide_ratio=25.0, min_guided_t=0, use_clipped_model_output=True)
    """
    base = method.removesuffix(SAFE_SUFFIX)
    if base.startswith(FLOW_PREFIX):
        base = "DP-" + base.removeprefix(FLOW_PREFIX)
    if base not in METHOD_SAMPLERS or (method.endswith(SAFE_SUFFIX) and METHOD_SAMPLERS[base][0] == "RS"):
        known = [*METHOD_SAMPLERS, *(f"{m}{SAFE_SUFFIX}" for m, (n, _) in METHOD_SAMPLERS.items() if n != "RS")]
        raise ValueError(f"unknown method {method!r}; methods: {', '.join(known)} (or FLOW- for DP-)")
    method = base
    name, kwargs = METHOD_SAMPLERS[method]
    if guide_ratio is not None and method in TABLE_BETA_METHODS:
        kwargs = {**kwargs, "guide_ratio": float(guide_ratio)}
    if use_clipped_model_output and name in ("GD", "SS"):
        kwargs = {**kwargs, "use_clipped_model_output": True}
    return make_sampler(name, **kwargs)


def tower_safety_cost(env: Any) -> PlanCost:
    """BlockStack's safety cost in ``env``'s current state, for plans ``[x, y, z, gripper]`` of the end effector.

    The task's transitions as guards on the gripper command
    (:func:`~steer_envs.steering.costs.switch_cost`): with the hand empty it
    may close (``free -> holding_i``) only at a free cube's centre (a tower's
    top); holding cube ``i`` it may open (``holding_i -> free``) only where the
    cube rests: just above the table within the placement range, or on a
    tower's top. Each guard sits inside the tolerances of
    :func:`~steer_envs.control.blockstack.classify_plan`, so a plan that
    satisfies them performs a skill. Plus the table as a forbidden region
    (the hand below its top, :func:`~steer_envs.steering.costs.region_cost`).
    The guards depend on where the cubes are: build the cost again after the
    world changes.
    """
    from steer_envs.control.blockstack import CLASSIFY_XY_TOL, GRASP_Z_TOL, PLACE_Z_TOL, towers
    from steer_envs.envs.robosuite.blockstack import CUBE_HALF, PLACE_RANGE, unwrap_blockstack

    base = unwrap_blockstack(env, "tower_safety_cost")
    pos, held, xyz = base.cube_pos, base.held_cube, (0, 1, 2)
    xy_tol = _GUARD_MARGIN * CLASSIFY_XY_TOL
    far = 10.0  # boxes that stand for half-spaces reach this far (m)
    table = Boxes(np.array([[-far, -far, base.table_z - far]]), np.array([[far, far, base.table_z]]), xyz)
    tops = [t[-1] for t in towers(base) if held not in t]
    if held is None:
        half = np.array([xy_tol, xy_tol, _GUARD_MARGIN * GRASP_Z_TOL])
        guard = switch_cost(3, on_at=[Boxes(pos[tops] - half, pos[tops] + half, xyz)])
    else:
        lift = pos[held, 2] - base.state[2]  # the held cube's centre relative to the hand
        band = (0.0, _GUARD_MARGIN * PLACE_Z_TOL)
        centre = np.asarray(base.rs_env.table_offset[:2], dtype=np.float64)
        spread = PLACE_RANGE + xy_tol
        rest = base.table_z + CUBE_HALF - lift
        low = [[*(centre - spread), rest + band[0]]]
        high = [[*(centre + spread), rest + band[1]]]
        for j in tops:
            on_top = pos[j, 2] + 2 * CUBE_HALF - lift
            low.append([pos[j, 0] - xy_tol, pos[j, 1] - xy_tol, on_top + band[0]])
            high.append([pos[j, 0] + xy_tol, pos[j, 1] + xy_tol, on_top + band[1]])
        guard = switch_cost(3, off_at=[Boxes(np.array(low), np.array(high), xyz)])
    below_table = region_cost([table])

    def cost(plans: torch.Tensor) -> torch.Tensor:
        return guard(plans) + below_table(plans)

    cost.__name__ = "tower_safety_cost"
    return cost


def tower_stands(env: Any, order: tuple[int, ...]) -> bool:
    """Whether the tower ``order`` (cube ids bottom to top) stands on the table, the hand empty."""
    support = env.supports
    if env.held_cube is not None or support[order[0]] != "table":
        return False
    return all(support[top] == below for below, top in itertools.pairwise(order))


def _plan_list(plans: np.ndarray) -> list[list[list[float]]]:
    return np.round(np.asarray(plans, dtype=np.float64), 4).tolist()


def _steer_skill(
    env: Any,
    user: Any,
    policy: Any,
    sampler: Sampler,
    obs: Any,
    batch: int,
    rng: np.random.Generator,
    home_yaw: float,
    execution: str,
) -> tuple[dict[str, Any], dict[str, Any], Any]:
    """One interaction: the user's sketch steers a batch, the picked plan runs; ``(row, plans kept, obs after)``."""
    from steer_envs.control.blockstack import classify_plan, execute_plan, plan_target

    skill = user.intended_skill(env)
    sketch = user.sketch(env, skill)
    scene = {"cube_pos": env.cube_pos.round(4).tolist(), "eef": env.state.round(4).tolist()}
    result = sampler(policy, obs, sketch, batch, generator=rng)
    kinds = [classify_plan(env, p) for p in result.plans]
    target = plan_target(env, result.plan)
    on_target = target == skill.name
    outcome = execute_plan(env, result.plan, home_yaw=home_yaw, execution=execution)
    planned = kinds[result.chosen]
    row = {
        "intended": skill.name,
        "planned": planned,
        "target": target,
        "executed": outcome.executed,
        "aligned": on_target,
        "skill_aligned": planned == skill.name,
        "success": outcome.success,
        "valid": planned is not None,
        "executed_ok": planned is not None and outcome.executed == planned and not outcome.violation,
        "regrasps": outcome.regrasps,
        "batch_aligned": float(np.mean([k == skill.name for k in kinds])),
        "latency_ms": float(result.timings["total_ms"]),
    }
    kept = {
        **scene,
        "intended": skill.name,
        "sketch": np.round(sketch.points, 4).tolist(),
        "plans": _plan_list(result.plans),
        "chosen": int(result.chosen),
        "aligned": on_target,
        "success": outcome.success,
    }
    return row, kept, outcome.obs


def _tower_metrics(rows: list[dict[str, Any]], built: bool) -> dict[str, float | None]:
    n = len(rows)
    success = np.array([r["success"] for r in rows], dtype=bool)
    skill_shaped = np.array([r["skill_aligned"] for r in rows], dtype=bool)
    valid = [r for r in rows if r["valid"]]
    return {
        **quadrant_shares([r["aligned"] for r in rows], success),
        "TA_skill": float(skill_shaped.mean()) if n else None,
        "AS_skill": float((skill_shaped & success).mean()) if n else None,
        "valid": float(np.mean([r["valid"] for r in rows])) if n else None,
        "executed_ok": float(np.mean([r["executed_ok"] for r in valid])) if valid else None,
        "batch_aligned": float(np.mean([r["batch_aligned"] for r in rows])) if n else None,
        "tower_built": float(built),
        "interactions": float(n),
        "latency_ms": float(np.mean([r["latency_ms"] for r in rows])) if n else None,
    }


def tower_trial(
    seed: int,
    policy: Any,
    method: str,
    *,
    batch: int = 32,
    max_interactions: int = 8,
    guide_ratio: float | None = None,
    keep_plans: bool = False,
    use_clipped_model_output: bool = True,
    safety_weight: float = 5.0,
    execution: str = "open_loop",
) -> tuple[dict[str, float | None], dict[str, Any]]:
    """One tower-building trial of ``method`` from evaluation scene ``seed``: ``(metrics, extra)`` (module docstring).

    ``safety_weight``: the weight of :func:`tower_safety_cost` in a ``+safe`` method.
    ``execution``: how the picked plans run on the arm, ``"open_loop"`` or ``"closed_loop"``
    (:data:`~steer_envs.control.plans.EXECUTIONS`).

    ``extra``: the tower ``order``, one row per interaction and, with
    ``keep_plans``, every interaction's scene, sketch and plans.
    """
    from steer_envs.control.blockstack import yaw_of
    from steer_envs.control.plans import check_execution
    from steer_envs.data.blockstack_skills import make_env
    from steer_envs.users.block_sketcher import TowerSketchUser

    sampler = make_method_sampler(method, guide_ratio, use_clipped_model_output)
    safe = method.endswith(SAFE_SUFFIX)
    weight = real_scalar(safety_weight, "`safety_weight`", low=0.0)
    execution = check_execution(execution, "tower_trial")
    rng = np.random.default_rng([seed, 7])
    order = tuple(int(c) for c in rng.permutation(4))
    env = make_env()
    try:
        obs, _ = env.reset(seed=SCENE_SEED_OFFSET + seed)
        home_yaw = yaw_of(env.robosuite_obs["robot0_eef_quat"])  # yaw targets stay near it, as the expert's
        user = TowerSketchUser(order, seed=seed)
        rows: list[dict[str, Any]] = []
        kept: list[dict[str, Any]] = []
        for _ in range(max_interactions):
            if tower_stands(env, order):
                break
            generator = np.random.default_rng([seed, len(rows)])
            if safe:
                sampler.with_costs([(tower_safety_cost(env), weight)])
            row, plans, obs = _steer_skill(env, user, policy, sampler, obs, batch, generator, home_yaw, execution)
            rows.append(row)
            if keep_plans:
                kept.append(plans)
        built = tower_stands(env, order)
    finally:
        env.close()
    extra: dict[str, Any] = {"order": list(order), "interactions": rows}
    if keep_plans:
        extra["plans"] = kept
    return _tower_metrics(rows, built), extra
