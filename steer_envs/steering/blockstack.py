"""Building a chosen 4-block tower by sketching (thesis Table 2.2): a user steers a frozen skill policy.

:func:`tower_trial` resets BlockStack at an evaluation scene
(:data:`~steer_envs.steering.study.SCENE_SEED_OFFSET` ``+ seed``: never a
training scene), draws the user's tower order from the seed and lets a
:class:`~steer_envs.users.block_sketcher.TowerSketchUser` steer the frozen
skill policy: at every interaction the user names the next skill toward the
tower (recovering from earlier mistakes as a person would), sketches it in 3D
from the end effector, the sampler (:func:`make_method_sampler`) returns a
batch of plans and picks one, and the plan is executed open-loop
(:func:`~steer_envs.control.blockstack.execute_plan`). The thesis's scoring,
per interaction:

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
  placed and resting) without a drop or a falling tower.

A trial ends when the tower stands or after ``max_interactions``. Its metrics
are shares of its interactions (TA, CS and the AS/AF/MS/MF quadrants), the
share of the batch that performs the intended skill (``batch_aligned``: how
often the intended mode is in the batch at all), whether the tower was built,
and the mean latency of the steering calls.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from steer_envs.steering.base import Sampler
from steer_envs.steering.registry import make_sampler
from steer_envs.steering.study import SCENE_SEED_OFFSET, quadrant_shares

__all__ = ["METHOD_SAMPLERS", "TABLE_BETA_METHODS", "make_method_sampler", "tower_stands", "tower_trial"]

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


def make_method_sampler(
    method: str, guide_ratio: float | None = None, use_clipped_model_output: bool = True
) -> Sampler:
    """The sampler of ``method`` (``guide_ratio`` replaces the beta of :data:`TABLE_BETA_METHODS` when given).

    ``use_clipped_model_output`` goes to GD and SS (see
    :class:`~steer_envs.steering.GuidedDiffusion`); on by default here:
    over this policy's 100 DDIM steps ITPS's step carries guided plans away from
    the sketch.

    >>> make_method_sampler("DP-GD-I50", guide_ratio=25.0)
    GuidedDiffusion(guide_ratio=25.0, min_guided_t=50, use_clipped_model_output=True)
    """
    if method not in METHOD_SAMPLERS:
        raise ValueError(f"unknown method {method!r}; methods: {', '.join(METHOD_SAMPLERS)}")
    name, kwargs = METHOD_SAMPLERS[method]
    if guide_ratio is not None and method in TABLE_BETA_METHODS:
        kwargs = {**kwargs, "guide_ratio": float(guide_ratio)}
    if use_clipped_model_output and name in ("GD", "SS"):
        kwargs = {**kwargs, "use_clipped_model_output": True}
    return make_sampler(name, **kwargs)


def tower_stands(env: Any, order: tuple[int, ...]) -> bool:
    """Whether the tower ``order`` (cube ids bottom to top) stands on the table, the hand empty."""
    support = env.supports
    if env.held_cube is not None or support[order[0]] != "table":
        return False
    return all(support[top] == below for below, top in itertools.pairwise(order))


def _plan_list(plans: np.ndarray) -> list[list[list[float]]]:
    return np.round(np.asarray(plans, dtype=np.float64), 4).tolist()


def _steer_skill(
    env: Any, user: Any, policy: Any, sampler: Sampler, obs: Any, batch: int, rng: np.random.Generator, home_yaw: float
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
    outcome = execute_plan(env, result.plan, home_yaw=home_yaw)
    row = {
        "intended": skill.name,
        "planned": kinds[result.chosen],
        "target": target,
        "executed": outcome.executed,
        "aligned": on_target,
        "skill_aligned": kinds[result.chosen] == skill.name,
        "success": outcome.success,
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
    return {
        **quadrant_shares([r["aligned"] for r in rows], success),
        "TA_skill": float(skill_shaped.mean()) if n else None,
        "AS_skill": float((skill_shaped & success).mean()) if n else None,
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
) -> tuple[dict[str, float | None], dict[str, Any]]:
    """One tower-building trial of ``method`` from evaluation scene ``seed``: ``(metrics, extra)`` (module docstring).

    ``extra``: the tower ``order``, one row per interaction and, with
    ``keep_plans``, every interaction's scene, sketch and plans.
    """
    from steer_envs.control.blockstack import yaw_of
    from steer_envs.data.blockstack_skills import make_env
    from steer_envs.users.block_sketcher import TowerSketchUser

    sampler = make_method_sampler(method, guide_ratio, use_clipped_model_output)
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
            row, plans, obs = _steer_skill(env, user, policy, sampler, obs, batch, generator, home_yaw)
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
