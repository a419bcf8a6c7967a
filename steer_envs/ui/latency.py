"""How long a person waits for plans: the latency of a :class:`~steer_envs.ui.session.Session`'s steering call.

:func:`steering_latency` times ``calls`` steering calls of one interaction
after ``warmup`` untimed ones (per-shape exports, traces and int8 calibration
happen there) and returns medians, split into the network (the policy's
denoiser / velocity calls and observation encoding), the sampler (the rest of
the sampler's call) and other (the session around it: resampling the sketch,
collision checks, bookkeeping). The ``itps-latency`` suite runs it for every
acceleration path; steer-ui's round trip adds the browser on top.
"""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass
from typing import Any

from steer_envs.core.validation import integer

__all__ = ["Latency", "steering_latency"]


@dataclass(frozen=True)
class Latency:
    """Medians (ms) of a steering call: ``total`` = ``network`` + ``sampler`` + ``other``; network calls per call."""

    total: float
    network: float
    sampler: float
    other: float
    network_evals: float
    calls: int


def steering_latency(session: Any, interaction: Any, *, calls: int = 8, warmup: int = 2) -> Latency:
    """Medians of ``calls`` timed ``session.steer(interaction)`` calls after ``warmup`` untimed ones.

    ``session``: a :class:`~steer_envs.ui.session.Session` (or anything whose
    ``steer`` returns an outcome with ``timings``); the session's state does
    not change between calls (nothing is executed).
    """
    calls = integer(calls, "calls", low=1, high=10_000, owner="steering_latency")
    warmup = integer(warmup, "warmup", low=0, high=10_000, owner="steering_latency")
    for _ in range(warmup):
        session.steer(interaction)
    rows = []
    for _ in range(calls):
        t0 = time.perf_counter()
        outcome = session.steer(interaction)
        wall = (time.perf_counter() - t0) * 1e3
        network, sampler = outcome.timings["network_ms"], outcome.timings["sampler_ms"]
        rows.append((wall, network, sampler, max(0.0, wall - network - sampler), outcome.timings["network_evals"]))
    total, network, sampler, other, evals = (statistics.median(column) for column in zip(*rows, strict=True))
    return Latency(total, network, sampler, other, evals, calls=calls)
