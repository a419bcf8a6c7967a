"""``selftest``: a tiny deterministic suite that checks the runner itself.

Each trial estimates pi from ``samples`` points in the unit square, either
plain Monte Carlo (``mc``) or jittered-grid stratified sampling
(``stratified``); the reference is pi itself, so the report's difference
column is the estimation error. It needs no environment, which makes it the
suite to try an executor or a Ray cluster with
(``steer-bench run selftest --executor ray --address auto``) and the one the
runner's own tests use. ``sleep`` stretches trials (kill/resume tests);
``fail_seeds`` makes chosen seeds raise (failure handling).

>>> from steer_envs.bench.suite import Trial
>>> trial = Trial("selftest", None, "stratified", 0, SelftestParams(samples=400).to_json(), SELFTEST.fn)
>>> round(run_selftest_trial(trial)["pi"], 2)
3.13
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Metric, Reference, Suite, Trial, register_suite

#: the most points one estimate may draw (16 bytes each) and the longest delay a trial may take
MAX_SAMPLES = 100_000_000
MAX_SLEEP_S = 3600.0


@dataclass(frozen=True)
class SelftestParams(SuiteParams):
    """Parameters of ``selftest``: points per estimate (1 to 10^8), a delay (0 to 3600 s), seeds that fail."""

    suite_name: ClassVar[str] = "selftest"
    samples: int = 10_000
    sleep: float = 0.0
    fail_seeds: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        self.require_at_least(1, "samples")
        self.require_at_most(MAX_SAMPLES, "samples")
        self.require("sleep", 0.0 <= self.sleep <= MAX_SLEEP_S, f"in [0, {MAX_SLEEP_S:g}] seconds")


def estimate_pi(method: str, samples: int, seed: int) -> float:
    """Fraction of points in the quarter disc, times four.

    >>> estimate_pi("stratified", 10_000, seed=0)
    3.1404
    """
    rng = np.random.default_rng(seed)
    if method == "mc":
        points = rng.random((samples, 2))
    elif method == "stratified":
        k = max(1, math.isqrt(samples))
        cells = np.stack(np.meshgrid(np.arange(k), np.arange(k), indexing="ij"), axis=-1).reshape(-1, 2)
        points = (cells + rng.random(cells.shape)) / k
    else:
        raise ValueError(f"method must be 'mc' or 'stratified', got {method!r}")
    return 4.0 * float(np.mean(np.sum(points**2, axis=1) <= 1.0))


def run_selftest_trial(trial: Trial) -> dict[str, float]:
    """One pi estimate (sleeping ``sleep`` seconds first; raising on ``fail_seeds``)."""
    params = SelftestParams.from_json(trial.params)
    if params.sleep > 0:
        time.sleep(params.sleep)
    if trial.seed in params.fail_seeds:
        raise RuntimeError(f"selftest: seed {trial.seed} is listed in fail_seeds")
    t0 = time.perf_counter()
    pi = estimate_pi(str(trial.method), params.samples, trial.seed)
    elapsed = time.perf_counter() - t0
    return {"pi": pi, "abs_error": abs(pi - math.pi), "samples_per_s": params.samples / max(elapsed, 1e-9)}


SELFTEST = register_suite(
    Suite(
        name="selftest",
        description="Runner self-check: pi by Monte Carlo vs. stratified sampling (no envs needed).",
        metrics=(
            Metric("pi", "estimate of pi", fmt=".4f"),
            Metric("abs_error", "|estimate - pi|", higher_is_better=False, fmt=".2e"),
            Metric("samples_per_s", "samples per second", kind="timing", fmt=".3g"),
        ),
        run_trial=run_selftest_trial,
        methods=("mc", "stratified"),
        params=SelftestParams(),
        trials_param="samples",
        default_seeds=4,
        references=(Reference("pi", math.pi, source="pi = 3.14159..."),),
    )
)
