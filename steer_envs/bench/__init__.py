"""steer-bench: the benchmark runner of steer-envs.

Suites (``suite.py``) declare envs x methods x seeds, metrics and the thesis's
reference numbers; executors (``executors.py``) run trials in-process, in a
process pool or on Ray; ``store.py`` appends each finished trial as a JSON
line and resumes killed runs; ``report.py`` / ``plots.py`` turn the lines into
tables and figures; ``cli.py`` is the ``steer-bench`` command.

Python API::

    from steer_envs.bench import run_suite, summarize, render
    summary = run_suite("smoke", "runs/smoke", seeds=3)
    print(render(summarize(summary.records), "md"))
"""

from steer_envs.bench.executors import Executor, Outcome, execute_trial, make_executor
from steer_envs.bench.report import render, summarize
from steer_envs.bench.runner import RunSummary, build_request, plan_trials, run_suite
from steer_envs.bench.store import ResultStore, load_results, read_jsonl
from steer_envs.bench.suite import (
    Finding,
    Metric,
    Reference,
    Suite,
    Trial,
    TrialPlan,
    TrialRequest,
    TrialResult,
    get_suite,
    load_plugins,
    register_suite,
    suites,
)

__all__ = [
    "Executor",
    "Finding",
    "Metric",
    "Outcome",
    "Reference",
    "ResultStore",
    "RunSummary",
    "Suite",
    "Trial",
    "TrialPlan",
    "TrialRequest",
    "TrialResult",
    "build_request",
    "execute_trial",
    "get_suite",
    "load_plugins",
    "load_results",
    "make_executor",
    "plan_trials",
    "read_jsonl",
    "register_suite",
    "render",
    "run_suite",
    "suites",
    "summarize",
]
