"""One ITPS steering call in Maze2D, scored as thesis Table 2.1: a start, a sketch, a batch, distances, collisions.

:func:`steering_trial` resets the maze at a random free cell (the seed), lets
a simulated user (:class:`~steer_envs.users.sketcher.SketchUser`, seeded by the
same seed) draw a sketch from there, samples a batch of plans with the policy
and one sampler (:func:`method_sampler`), and scores the plans from the
policy's ``exec_start`` (the executed waypoints): L2 distance to the sketch
over the maze extent, wall collisions, latency, denoiser calls. Every sampler
of a seed sees the same start, sketch and initial noise.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.steering.base import Sampler, SteeringResult
from steer_envs.steering.costs import safety_cost
from steer_envs.steering.diffusion import GuidedDiffusion
from steer_envs.steering.latency import benchmark_latency
from steer_envs.steering.observations import policy_observation
from steer_envs.steering.ranking import OutputPerturbation
from steer_envs.steering.registry import make_sampler

__all__ = ["method_sampler", "steering_trial", "warm_up"]

_warm: set[tuple[int, str, int]] = set()


def method_sampler(name: str, env: Any, *, safety_weight: float = 0.0, mcmc_steps: int | None = None) -> Sampler:
    """The sampler ``name`` for ``env``'s maze: OP stops before the sketch's first wall (``env.is_wall``).

    ``safety_weight > 0`` adds the maze's safety cost (its walls,
    :func:`~steer_envs.steering.costs.safety_cost`) with that weight;
    ``mcmc_steps`` sets SS's iterations per noise level (``None``: its default).
    """
    if name == "OP":
        sampler: Sampler = OutputPerturbation(collides=env.is_wall)
    elif name == "SS" and mcmc_steps is not None:
        sampler = make_sampler(name, mcmc_steps=mcmc_steps)
    else:
        sampler = make_sampler(name)
    if safety_weight > 0:
        sampler.with_costs([(safety_cost(env.task), safety_weight)])
    return sampler


def warm_up(policy: Any, sampler: Sampler, obs: Any, sketch: Any, batch: int) -> None:
    """One untimed call per (policy, sampler, batch) and process: lazy initialisation (per-shape kernels,
    traces, compilation) stays out of the timed call."""
    key = (id(policy), repr(sampler), batch)
    if key not in _warm:
        sampler(policy, obs, sketch, batch, generator=np.random.default_rng(0))
        _warm.add(key)


def _ss_gd_latency(policy: Any, sampler: Sampler, obs: Any, sketch: Any, batch: int, repeats: int, seed: int) -> float:
    """SS's time per call over GD's, the medians of ``repeats`` interleaved calls on the same input."""
    warm_up(policy, GuidedDiffusion(), obs, sketch, batch)
    ms = benchmark_latency(
        policy, {"GD": GuidedDiffusion(), "SS": sampler}, obs, sketch, batch=batch, repeats=repeats, warmup=0, seed=seed
    )
    return ms["SS"] / ms["GD"]


def _kept_plans(
    drawn: Any, plans: np.ndarray, collides: np.ndarray, dist: np.ndarray, result: SteeringResult
) -> dict[str, Any]:
    perturbed = result.perturbed_state
    return {
        "sketch": drawn.sketch.points.round(3).tolist(),
        "plans": plans.round(3).tolist(),
        "collides": collides.tolist(),
        "distances": dist.round(4).tolist(),
        "chosen": int(result.chosen),
        "perturbed_state": None if perturbed is None else perturbed.round(4).tolist(),
    }


def _metrics(result: SteeringResult, dist: np.ndarray, collides: np.ndarray) -> dict[str, float | None]:
    return {
        "min_l2": float(dist[result.chosen]),
        "avg_l2": float(dist.mean()),
        "collision": float(collides.mean()),
        "latency_ms": float(result.timings["total_ms"]),
        "ss_gd_latency": None,
        "network_evals": result.timings.get("network_evals"),
    }


def steering_trial(
    env_id: str,
    seed: int,
    policy: Any,
    sampler_name: str,
    *,
    batch: int = 32,
    through_wall: float = 0.3,
    latency_repeats: int = 1,
    keep_plans: bool = False,
    safety_weight: float = 0.0,
    mcmc_steps: int | None = None,
) -> tuple[dict[str, float | None], dict[str, Any]]:
    """One start location (``seed``) steered by ``sampler_name`` (``"RS"``, ``"PR"``, ``"OP"``, ``"BI"``, ...).

    Returns ``(metrics, extra)``. Metrics: ``min_l2`` (the picked plan's
    distance to the sketch), ``avg_l2`` (the batch mean), ``collision``
    (fraction of the batch in a wall), ``latency_ms`` (one steering call of
    ``batch`` plans, after a per-process warm-up), ``network_evals`` (denoiser
    calls) and, for SS, ``ss_gd_latency`` (SS's time per call over GD's, medians
    of ``latency_repeats`` interleaved calls). ``through_wall`` is the share of
    sketches the user draws through walls. ``extra`` holds the start and the
    sketch kind, plus the plans, sketch and distances with ``keep_plans``.
    ``safety_weight > 0`` adds the walls' safety cost to the sampler and
    ``mcmc_steps`` sets SS's iterations per noise level (:func:`method_sampler`).
    """
    import gymnasium as gym

    import steer_envs  # noqa: F401 - registers the envs in a fresh worker
    from steer_envs.core.metrics import sketch_distances
    from steer_envs.users.sketcher import SketchUser

    env: Any = gym.make(env_id, sample_goal=False).unwrapped
    try:
        obs, _ = env.reset(seed=seed)
        drawn = SketchUser(env.grid, through_wall=through_wall, seed=seed).draw(env.state)
        sampler = method_sampler(sampler_name, env, safety_weight=safety_weight, mcmc_steps=mcmc_steps)
        obs_in = policy_observation(policy, [obs])
        warm_up(policy, sampler, obs_in, drawn.sketch, batch)
        generator = np.random.default_rng(np.random.SeedSequence([seed, 0x1795]))
        result = sampler(policy, obs_in, drawn.sketch, batch, generator=generator)
        # ITPS scores the executed waypoints (LeRobot's DP restates the current position in plan[0])
        plans = result.plans[:, int(getattr(policy, "exec_start", 0)) :]
        dist = sketch_distances(plans, drawn.sketch, scale=env.extent)
        collides = env.plan_collides(plans)
        metrics = _metrics(result, dist, collides)
        if sampler_name == "SS":
            args = (policy, sampler, obs_in, drawn.sketch, batch, latency_repeats, seed)
            metrics["ss_gd_latency"] = _ss_gd_latency(*args)
        extra: dict[str, Any] = {
            "start": np.asarray(env.state).round(4).tolist(),
            "sketch_kind": drawn.kind,
            "sketch_collides": drawn.collides,
        }
        if keep_plans:
            extra.update(_kept_plans(drawn, plans, collides, dist, result))
        return metrics, extra
    finally:
        env.close()
