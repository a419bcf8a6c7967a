"""Running one ITPS steering trial: a start, a sketch, a batch of plans, their distances and collisions.

:func:`steering_trial` resets the maze at a random free cell (the seed), lets
a simulated user (:class:`~steer_envs.users.sketcher.SketchUser`, seeded by the
same seed) draw a sketch from there, samples a batch of plans with the policy
and one inference-time steering sampler, and scores the plans from the
policy's ``exec_start`` (the executed waypoints): L2 distance to the sketch
over the maze extent, wall collisions, latency, denoiser calls. Every sampler
of a seed sees the same start, sketch and initial noise.

:func:`load_policy` resolves the frozen policy from a checkpoint file or a
``"module:function"`` loader, cached per process.

>>> FileNotFoundError in POLICY_UNAVAILABLE  # a missing checkpoint skips that policy's methods
True
"""

from __future__ import annotations

import functools
import inspect
from typing import Any

import numpy as np

from steer_envs.bench.suite import TrialResult, resolve_function

__all__ = ["POLICY_UNAVAILABLE", "load_policy", "steering_trial"]

#: exceptions that mean "this policy is not available (yet)": module, function or checkpoint missing
POLICY_UNAVAILABLE: tuple[type[Exception], ...] = (ImportError, AttributeError, FileNotFoundError)


@functools.lru_cache(maxsize=4)
def load_policy(loader: str, kind: str, checkpoint: str = "", accelerate: str = "none") -> Any:
    """The frozen policy ``kind`` from a checkpoint file or the ``"module:function"`` loader (cached per process).

    A non-empty ``checkpoint`` (a file written by ``python -m
    steer_envs.baselines.training``) wins; else the loader is called as
    ``loader(kind)`` when it takes an argument, else ``loader()``. Raises one
    of :data:`POLICY_UNAVAILABLE` while the policy is not available.
    ``accelerate`` other than ``"none"`` is passed to the policy's
    ``accelerate`` method (:meth:`~steer_envs.baselines.diffusion.DiffusionPolicy.accelerate`);
    ``TypeError`` for a policy without one.

    >>> load_policy("steer_envs.no_such_module:load", "dp")
    Traceback (most recent call last):
    ModuleNotFoundError: No module named 'steer_envs.no_such_module'
    """
    if checkpoint:
        from steer_envs.baselines.pretrained import load_checkpoint

        policy: Any = load_checkpoint(kind, checkpoint)  # a wrong path is a ValueError, not a skipped policy
    else:
        fn = resolve_function(loader)
        try:
            takes_arg = bool(inspect.signature(fn).parameters)
        except (TypeError, ValueError):
            takes_arg = True
        policy = fn(kind) if takes_arg else fn()
        from steer_envs.core.policy import TrajectoryPolicy

        if not isinstance(policy, TrajectoryPolicy):
            raise TypeError(f"{loader}({kind!r}) must return a TrajectoryPolicy, got {type(policy).__name__}")
    if accelerate != "none":
        from steer_envs.baselines.diffusion.acceleration import accelerated

        policy = accelerated(policy, accelerate, owner="dp_accelerate")
    return policy


_warm: set[tuple[int, str, int]] = set()


def _warm_up(policy: Any, sampler: Any, obs: Any, sketch: Any, batch: int) -> None:
    """One untimed call per (policy, sampler, batch) and process: lazy initialisation (per-shape kernels,
    traces, compilation) stays out of latency_ms."""
    key = (id(policy), sampler.name, batch)
    if key not in _warm:
        sampler(policy, obs, sketch, batch, generator=np.random.default_rng(0))
        _warm.add(key)


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
) -> TrialResult:
    """One start location (``seed``) steered by ``sampler_name`` (``"RS"``, ``"PR"``, ``"OP"``, ``"BI"``, ...).

    Metrics: ``min_l2`` (the picked plan's distance to the sketch), ``avg_l2``
    (the batch mean), ``collision`` (fraction of the batch in a wall),
    ``latency_ms`` (one steering call of ``batch`` plans, after a per-process
    warm-up), ``network_evals`` (denoiser calls) and, for SS,
    ``ss_gd_latency`` (SS's time per call over GD's, medians of
    ``latency_repeats`` interleaved calls). ``through_wall`` is the share of
    sketches the user draws through walls. ``extra`` holds the start and the
    sketch kind, plus the plans, sketch and distances with ``keep_plans``.
    """
    import gymnasium as gym

    import steer_envs  # noqa: F401 - registers the envs in a fresh worker
    from steer_envs.core.metrics import sketch_distances
    from steer_envs.users.sketcher import SketchUser
    from steer_envs.wrappers.samplers import GuidedDiffusion, OutputPerturbation, benchmark_latency, make_sampler
    from steer_envs.wrappers.steering import policy_observation

    env: Any = gym.make(env_id, sample_goal=False).unwrapped
    try:
        obs, _ = env.reset(seed=seed)
        user = SketchUser(env.grid, through_wall=through_wall, seed=seed)
        drawn = user.draw(env.state)
        sampler = OutputPerturbation(collides=env.is_wall) if sampler_name == "OP" else make_sampler(sampler_name)
        obs_in = policy_observation(policy, [obs])
        _warm_up(policy, sampler, obs_in, drawn.sketch, batch)
        generator = np.random.default_rng(np.random.SeedSequence([seed, 0x1795]))
        result = sampler(policy, obs_in, drawn.sketch, batch, generator=generator)
        # ITPS scores the executed waypoints (LeRobot's DP restates the current position in plan[0])
        plans = result.plans[:, int(getattr(policy, "exec_start", 0)) :]
        dist = sketch_distances(plans, drawn.sketch, scale=env.extent)
        collides = env.plan_collides(plans)
        metrics: dict[str, float | None] = {
            "min_l2": float(dist[result.chosen]),
            "avg_l2": float(dist.mean()),
            "collision": float(collides.mean()),
            "latency_ms": float(result.timings["total_ms"]),
            "ss_gd_latency": None,
            "network_evals": result.timings.get("network_evals"),
        }
        if sampler_name == "SS":
            _warm_up(policy, GuidedDiffusion(), obs_in, drawn.sketch, batch)
            ms = benchmark_latency(
                policy,
                {"GD": GuidedDiffusion(), "SS": sampler},
                obs_in,
                drawn.sketch,
                batch=batch,
                repeats=latency_repeats,
                warmup=0,
                seed=seed,
            )
            metrics["ss_gd_latency"] = ms["SS"] / ms["GD"]
        extra: dict[str, Any] = {
            "start": np.asarray(env.state).round(4).tolist(),
            "sketch_kind": drawn.kind,
            "sketch_collides": drawn.collides,
        }
        if keep_plans:
            extra.update(
                sketch=drawn.sketch.points.round(3).tolist(),
                plans=plans.round(3).tolist(),
                collides=collides.tolist(),
                distances=dist.round(4).tolist(),
                chosen=int(result.chosen),
                perturbed_state=None if result.perturbed_state is None else result.perturbed_state.round(4).tolist(),
            )
        return TrialResult(metrics, extra)
    finally:
        env.close()
