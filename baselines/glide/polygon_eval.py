"""Evaluating GLiDE on PolygonNav: policy rollouts under teleport perturbations, and grounding scores on a grid.

* :func:`evaluate_polygon_policy` -- success rate of a batched policy
  (``act(states (N, 2)) -> velocities``, ``reset()``) over ``n_rollouts``
  episodes run at once in the vector env, with or without the evaluation
  perturbations (:class:`PerturbationSchedule`: after the first mode change,
  with probability 0.03 per step, at least 100 steps apart and at most 3
  times per episode, the agent is teleported to a uniform free-space point).
* :func:`grounding_scores` -- the overlap and per-mode IoU of a mode
  predictor with the ground truth on the workspace grid (thesis Fig. 4.4).

>>> PerturbationSchedule(), PerturbationSchedule(probability=0.1).min_gap
(PerturbationSchedule(probability=0.03, min_gap=100, max_count=3), 100)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import steer_envs  # noqa: F401  (registers the envs)
from steer_envs.baselines.glide.modes import ModePredictor, mode_iou, mode_overlap, workspace_grid
from steer_envs.baselines.glide.polygon import check_count, check_env_id
from steer_envs.core.validation import integer, real_scalar

__all__ = ["EVAL_STARTS", "PerturbationSchedule", "evaluate_polygon_policy", "grounding_scores"]

#: where evaluation episodes start (:func:`evaluate_polygon_policy`)
EVAL_STARTS: tuple[str, ...] = ("free", "first_mode")


@dataclass(frozen=True)
class PerturbationSchedule:
    """Evaluation perturbations: teleports to uniform free-space points (see the module docstring).

    >>> PerturbationSchedule(), PerturbationSchedule(probability=0.1).min_gap
    (PerturbationSchedule(probability=0.03, min_gap=100, max_count=3), 100)
    """

    probability: float = 0.03
    min_gap: int = 100
    max_count: int = 3

    def __post_init__(self) -> None:
        real_scalar(self.probability, "probability", low=0.0, high=1.0, owner="PerturbationSchedule")
        integer(self.min_gap, "min_gap", low=0, owner="PerturbationSchedule")
        integer(self.max_count, "max_count", low=0, owner="PerturbationSchedule")


class _Episodes:
    """Per-agent bookkeeping of :func:`evaluate_polygon_policy`."""

    def __init__(self, n: int, start_mode: np.ndarray, first_mode_start: bool) -> None:
        self.done = np.zeros(n, dtype=bool)
        self.success = np.zeros(n, dtype=bool)
        self.violation = np.zeros(n, dtype=bool)
        self.left_start = np.full(n, first_mode_start)  # teleports start after the first mode change
        self.start_mode = start_mode
        self.last_push = np.full(n, -(10**9))
        self.pushes = np.zeros(n, dtype=np.int64)
        self.steps = np.zeros(n, dtype=np.int64)

    def record(self, terminated: Any, truncated: Any, info: dict[str, Any]) -> None:
        """Account one vector step (agents already done are left as they were)."""
        live = ~self.done
        self.violation |= live & np.asarray(info["constraint_violation"], dtype=bool)
        ended = live & (np.asarray(terminated) | np.asarray(truncated))
        self.success |= ended & np.asarray(info["success"], dtype=bool)
        self.steps[live] += 1
        self.done |= ended

    def result(self) -> dict[str, Any]:
        return {
            "success_rate": float(self.success.mean()),
            "n_success": int(self.success.sum()),
            "violation_rate": float(self.violation.mean()),
            "timeout_rate": float((~self.success & ~self.violation).mean()),
            "perturbations": int(self.pushes.sum()),
            "perturbed_episodes": int((self.pushes > 0).sum()),
            "mean_steps": float(self.steps.mean()),
        }


def _teleport(
    venv: Any, ep: _Episodes, obs: np.ndarray, t: int, rng: np.random.Generator, schedule: PerturbationSchedule
) -> np.ndarray:
    """Draw this step's teleports (one uniform number per agent) and apply them; the observations after."""
    n = len(ep.done)
    push = (
        ~ep.done
        & ep.left_start
        & (t - ep.last_push >= schedule.min_gap)
        & (ep.pushes < schedule.max_count)
        & (rng.random(n) < schedule.probability)
    )
    if push.any():
        targets = venv.unwrapped.model.sample_start(rng, n)
        venv.unwrapped.perturb(targets, push)
        obs = np.where(push[:, None], targets.astype(np.float32), obs)
        ep.last_push[push] = t
        ep.pushes[push] += 1
    return obs


def _rollouts(
    venv: Any, policy: Any, n: int, perturbed: bool, seed: int, schedule: PerturbationSchedule, start: str
) -> dict[str, Any]:
    model = venv.unwrapped.model
    horizon = int(venv.unwrapped.max_episode_steps)
    obs, info = venv.reset(seed=int(seed))
    rng = np.random.default_rng([int(seed), 7])
    if start == "first_mode":
        obs, info = venv.reset(options={"state": model.sample_in_mode(rng, n, 1)})
    policy.reset()
    ep = _Episodes(n, np.asarray(info["mode"]).copy(), start == "first_mode")
    for t in range(horizon):
        action = np.asarray(policy.act(np.asarray(obs, dtype=np.float64)), dtype=np.float32)
        action[ep.done] = 0.0
        obs, _, terminated, truncated, info = venv.step(action)
        ep.record(terminated, truncated, info)
        if ep.done.all():
            break
        ep.left_start |= ~ep.done & (np.asarray(info["mode"]) != ep.start_mode)
        if perturbed:
            obs = _teleport(venv, ep, obs, t, rng, schedule)
    return ep.result()


def evaluate_polygon_policy(
    policy: Any,
    env_id: str,
    layout_seed: int,
    *,
    n_rollouts: int,
    perturbed: bool,
    seed: int,
    schedule: PerturbationSchedule | None = None,
    max_steps: int | None = None,
    start: str = "free",
) -> dict[str, Any]:
    """Run ``n_rollouts`` episodes at once in the vector env; success = the env's success flag.

    ``max_steps`` caps each episode (None: the env's registered 500, the public env's nominal
    limit). An episode that ends neither in success nor in an invalid transition timed out
    (``timeout_rate``). ``start``: ``"free"`` (uniform in free space, the env's reset) or
    ``"first_mode"`` (uniform inside the first polygon, as if just entered from free space: the
    public polygon env's default reset; teleports may then come from the first step).
    """
    n = check_count("n_rollouts", n_rollouts, 1)
    if start not in EVAL_STARTS:
        raise ValueError(f"start must be one of {EVAL_STARTS}, got {start!r}")
    schedule = schedule or PerturbationSchedule()
    horizon_kwargs: dict[str, Any] = (
        {} if max_steps is None else {"max_episode_steps": check_count("max_steps", max_steps, 1)}
    )
    venv = gym.make_vec(
        env_id, num_envs=n, vectorization_mode="vector_entry_point", layout_seed=int(layout_seed), **horizon_kwargs
    )
    try:
        return _rollouts(venv, policy, n, perturbed, seed, schedule, start)
    finally:
        venv.close()


def grounding_scores(
    env_id: str, layout_seed: int, predictor: ModePredictor, resolution: int = 200
) -> tuple[dict[str, Any], np.ndarray]:
    """How well ``predictor`` labels one layout's ``resolution x resolution`` workspace grid.

    Returns the scores -- ``overlap`` (the fraction of grid points with the
    true mode), ``mean_iou`` and the per-mode ``iou`` (free space dominates
    the grid, so overlap alone is lenient: ``all_free_overlap`` is what
    labelling everything free scores) -- and the predicted labels on
    :func:`~steer_envs.baselines.glide.modes.workspace_grid`'s grid.
    """
    k = check_env_id(env_id)
    env = gym.make(env_id, layout_seed=int(layout_seed))
    model = env.unwrapped.model  # type: ignore[attr-defined]
    env.close()
    grid = workspace_grid(model.low, model.high, resolution)
    truth = model.mode_of(grid)
    pred = np.asarray(predictor.predict(grid))
    iou = mode_iou(pred, truth, k)
    scores = {
        "overlap": mode_overlap(pred, truth),
        "mean_iou": float(iou.mean()),
        "iou": [float(v) for v in iou],
        "all_free_overlap": mode_overlap(np.zeros_like(truth), truth),
    }
    return scores, pred
