"""A test-only steer-bench suite, loaded as a plugin (``--plugin`` / ``STEER_BENCH_PLUGINS``).

``toy_faults`` trials fail in every way a trial can (raise, exit, return junk, kill their
worker) so the runner's tests can check that none of them stops a run.
``toy`` trials compute a deterministic number from (method, seed, scale) and
fail while the file named by ``fail_flag`` exists, so a test can make trials
fail, remove the flag and check that the resume re-runs exactly those.
"""

from __future__ import annotations

import multiprocessing
import os
import time

import numpy as np

from steer_envs.bench.suite import Metric, Reference, Suite, Trial, TrialResult, register_suite


def run_toy_trial(trial: Trial) -> TrialResult:
    """``value = scale * mean of 100 seeded normals`` (+1 for method ``b``)."""
    params = trial.params
    if params["fail_flag"] and os.path.exists(params["fail_flag"]):
        raise RuntimeError(f"fail flag {params['fail_flag']} is present")
    if params["sleep"]:
        time.sleep(params["sleep"])
    rng = np.random.default_rng(trial.seed)
    value = params["scale"] * float(rng.normal(size=100).mean()) + (1.0 if trial.method == "b" else 0.0)
    return TrialResult({"value": value, "flag": None}, extra={"points": rng.normal(size=(3, 2)).round(3).tolist()})


TOY = register_suite(
    Suite(
        name="toy",
        description="test-only toy suite",
        metrics=(Metric("value", "a seeded number", fmt=".3f"), Metric("flag", "never reported")),
        run_trial=run_toy_trial,
        envs=("toy/A-v0", "toy/B-v0"),
        methods=("a", "b"),
        params={"scale": 1.0, "sleep": 0.0, "fail_flag": ""},
        default_seeds=2,
        references=(
            Reference("value", 0.0, method="a", source="toy ref a"),
            Reference("value", 1.0, method="b", source="toy ref b"),
            Reference("value", 1.5, env="toy/B-v0", method="b", source="toy ref Bb"),
        ),
    ),
    replace=True,
)


def run_typo_trial(trial: Trial) -> dict[str, float]:
    """Reports a metric its suite does not declare (the runner must reject it)."""
    return {"valu": 1.0}


TYPO = register_suite(
    Suite("toy_typo", "test-only: undeclared metric", (Metric("value"),), run_typo_trial, default_seeds=1),
    replace=True,
)


class _NotJson:
    """An object a trial may wrongly put into its extra data."""


def run_faulty_trial(trial: Trial) -> TrialResult:
    """One way for a trial to go wrong per method (``ok`` is fine); none of them may stop the run."""
    method = trial.method
    if method == "raise":
        raise ValueError("this trial raises on purpose")
    if method == "exit":
        raise SystemExit(3)
    if method == "nonjson":
        return TrialResult({"value": 1.0}, extra={"obj": _NotJson()})
    if method == "nan":
        return TrialResult({"value": float("nan")})
    if method == "complex":
        return TrialResult({"value": np.complex128(1 + 2j)})
    if method == "text":
        return TrialResult({"value": "1.0"})  # type: ignore[dict-item]
    if method == "die":  # the worker process dies (in a process pool; in the main process it only raises)
        if multiprocessing.parent_process() is None:
            raise RuntimeError("toy_faults: 'die' only kills pool workers")
        os.kill(os.getpid(), 9)
    return TrialResult({"value": float(trial.seed)})


FAULTS = register_suite(
    Suite(
        name="toy_faults",
        description="test-only: trials that fail in every way but one",
        metrics=(Metric("value"),),
        run_trial=run_faulty_trial,
        methods=("ok", "raise", "exit", "nonjson", "nan", "complex", "text", "die"),
        default_seeds=2,
    ),
    replace=True,
)
