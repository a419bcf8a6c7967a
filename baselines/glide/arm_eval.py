"""Running a GLiDE arm policy (BC or GLiDE+BC, :mod:`~steer_envs.baselines.glide.arm_policies`) in an env.

:func:`evaluate_arm_policy` runs episodes of a registered robosuite env
(``steer_envs/Lift-v0`` ...), optionally wrapped in
:class:`~steer_envs.wrappers.arm_perturbation.ArmPerturbationWrapper` for the
thesis's "+p" evaluation: each episode stops at success (or at the env's
TimeLimit: Lift 200, Can 400, Square 500 steps), episode ``i`` resets with
seed ``first_seed + i`` (default 10_000, disjoint from the demo seeds), so
methods compare on the same placements. ``violation_rate``: episodes in which
the env reported a constraint violation (pushes are exempt by the env; a drop
caused by a forced gripper opening counts).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from steer_envs.baselines.glide.arm_plan import selected_columns
from steer_envs.baselines.glide.arm_policies import GROUND_TRUTH, ArmPolicy, check_arm_predictor
from steer_envs.core.validation import describe, integer
from steer_envs.data import robosuite_replays as rr

__all__ = ["evaluate_arm_policy"]


@dataclass
class _Tally:
    success: list[bool] = field(default_factory=list)
    violation: list[bool] = field(default_factory=list)
    length: list[int] = field(default_factory=list)
    perturbations: list[int] = field(default_factory=list)
    mode_changes: list[int] = field(default_factory=list)
    log: list[list[tuple[int, str]]] = field(default_factory=list)


def _episode(env: Any, policy: ArmPolicy, predictor: Any, cols: np.ndarray, seed: int, tally: _Tally) -> None:
    """One episode from reset seed ``seed``, stopped at success; its numbers appended to ``tally``."""
    base = env.unwrapped
    obs, info = env.reset(seed=seed)
    success = violation = False
    steps = changes = 0
    last_mode = -1
    done = False
    while not done:
        features = rr.feature_vector(base)
        true_mode = int(info["mode"]) if "mode" in info else None
        if predictor == GROUND_TRUTH:
            mode = int(info["mode"])
        else:
            mode = int(predictor.predict(np.asarray(features[cols], dtype=np.float64)[None])[0])
        changes += int(last_mode >= 0 and mode != last_mode)
        last_mode = mode
        action = np.asarray(policy.act(obs, features, mode, true_mode), dtype=np.float32)
        obs, _, terminated, truncated, info = env.step(action)
        steps += 1
        violation |= bool(info["constraint_violation"])
        success |= bool(info["success"])
        done = success or terminated or truncated
    tally.success.append(success)
    tally.violation.append(violation)
    tally.length.append(steps)
    tally.perturbations.append(int(info.get("perturbation_count", 0)))
    tally.mode_changes.append(changes)
    tally.log.append([(int(t), str(kind)) for t, kind, _ in getattr(env, "log", [])])


def evaluate_arm_policy(
    env: Any,
    policy: ArmPolicy,
    *,
    predictor: Any = GROUND_TRUTH,
    n_episodes: int,
    first_seed: int = 10_000,
) -> dict[str, Any]:
    """Run ``policy`` for ``n_episodes`` episodes of ``env`` (a registered robosuite env, maybe wrapped).

    The mode passed to the policy is the predictor's on the current state's
    selected features (``info["mode"]`` for
    :data:`~steer_envs.baselines.glide.arm_policies.GROUND_TRUTH`); the env's
    ``info["mode"]`` goes with it as ``true_mode`` (for an attractor that reads it). The env
    stays open (the caller closes it). Returns ``task``, ``n_episodes``,
    ``success_rate``, ``violation_rate``, ``mean_length``,
    ``mean_perturbations`` (the wrapper's ``perturbation_count``; 0 without
    it), ``eval_seconds`` and the per-episode lists under ``episodes``.
    """
    owner = "evaluate_arm_policy"
    task = str(getattr(getattr(env, "unwrapped", None), "task_name", ""))
    if task not in rr.ENV_IDS:
        raise TypeError(f"{owner}: `env` must be a robosuite arm env (steer_envs/Lift-v0 ...), got {describe(env)}")
    n_episodes = integer(n_episodes, "n_episodes", low=0, owner=owner)
    first_seed = integer(first_seed, "first_seed", low=0, owner=owner)
    if not callable(getattr(policy, "act", None)):
        raise TypeError(f"{owner}: `policy` must have act(obs, features, mode), got {describe(policy)}")
    check_arm_predictor(predictor)
    cols = selected_columns(task)
    tally = _Tally()
    start = time.perf_counter()
    for i in range(n_episodes):
        _episode(env, policy, predictor, cols, first_seed + i, tally)
    n = max(n_episodes, 1)
    return {
        "task": task,
        "n_episodes": n_episodes,
        "success_rate": sum(tally.success) / n,
        "violation_rate": sum(tally.violation) / n,
        "mean_length": float(np.mean(tally.length)) if tally.length else 0.0,
        "mean_perturbations": float(np.mean(tally.perturbations)) if tally.perturbations else 0.0,
        "eval_seconds": time.perf_counter() - start,
        "episodes": {
            "seed": [first_seed + i for i in range(n_episodes)],
            "success": tally.success,
            "violation": tally.violation,
            "length": tally.length,
            "perturbations": tally.perturbations,
            "mode_changes": tally.mode_changes,
            "perturbation_log": tally.log,
        },
    }
