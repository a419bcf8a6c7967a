"""How long a steering call takes: :func:`benchmark_latency` times samplers against each other."""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from steer_envs.core.interaction import Interaction
from steer_envs.core.policy import TrajectoryPolicy
from steer_envs.core.validation import integer
from steer_envs.steering.base import Sampler, check_batch

__all__ = ["MAX_TIMING_ROUNDS", "benchmark_latency"]


#: the most timed (and warm-up) rounds of :func:`benchmark_latency`.
MAX_TIMING_ROUNDS = 10_000


def benchmark_latency(
    policy: TrajectoryPolicy,
    samplers: Mapping[str, Sampler],
    obs: Any,
    interaction: Interaction,
    *,
    batch: int = 32,
    repeats: int = 5,
    warmup: int = 1,
    seed: int = 0,
) -> dict[str, float]:
    """Milliseconds per steering call of every sampler (median over ``repeats``, after ``warmup`` calls).

    Samplers are timed in interleaved rounds (one call each per round) so a
    change of machine load affects all of them alike; every call uses the same
    seed, hence the same initial noise.
    """
    if not isinstance(samplers, Mapping) or not samplers:
        raise ValueError("`samplers` must be a non-empty mapping name -> Sampler")
    for key, sampler in samplers.items():
        if not isinstance(sampler, Sampler):
            raise TypeError(f"`samplers[{key!r}]` must be a Sampler, got {type(sampler).__name__}")
    repeats = integer(repeats, "`repeats`", low=1, high=MAX_TIMING_ROUNDS)
    warmup = integer(warmup, "`warmup`", low=0, high=MAX_TIMING_ROUNDS)
    batch = check_batch(batch)
    times: dict[str, list[float]] = {key: [] for key in samplers}
    for round_ in range(int(warmup) + int(repeats)):
        for key, sampler in samplers.items():
            t0 = time.perf_counter()
            sampler(policy, obs, interaction, batch, generator=np.random.default_rng(seed))
            if round_ >= warmup:
                times[key].append((time.perf_counter() - t0) * 1e3)
    return {key: float(np.median(values)) for key, values in times.items()}
