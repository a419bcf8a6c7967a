"""steer-bench: the benchmark runner of steer-envs.

Suites (``suite.py``) declare envs x methods x seeds, metrics and the thesis's
reference numbers; executors (``executors.py``) run trials in-process, in a
process pool or on Ray; ``store.py`` appends each finished trial as a JSON
line and resumes killed runs; ``report.py`` / ``plots.py`` turn the lines into
tables and figures; ``cli.py`` is the ``steer-bench`` command.

A suite's parameters are a frozen dataclass (``params.py``,
:class:`SuiteParams`), coerced and checked before any trial runs. What
several suites declare or do alike lives here too: ``findings.py`` (claims
judged on a summary table), ``metrics.py`` (metrics and references declared
alike), ``trials.py`` (the guard and prologue of trial functions, and what
the robot-experiment protocols share) and ``policies.py`` (suites that steer
one frozen policy).

Python API:

>>> import tempfile
>>> with tempfile.TemporaryDirectory() as out:
...     summary = run_suite("selftest", out, seeds=2, trials=400, progress=False)
>>> print(render(summarize(summary.records), "csv").splitlines()[0])
suite,env,method,params,metric,kind,trials,n,mean,std,min,max,reference,diff,source,goal,meets_goal
"""

from steer_envs.bench.executors import Executor, ExecutorStartError, Outcome, execute_trial, make_executor
from steer_envs.bench.params import SuiteParams
from steer_envs.bench.records import ResultsDirError, read_jsonl
from steer_envs.bench.report import render, summarize
from steer_envs.bench.runner import MAX_PLANNED_TRIALS, RunSummary, build_request, plan_trials, run_suite
from steer_envs.bench.store import ResultStore, StoreLockedError, load_results
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
    "MAX_PLANNED_TRIALS",
    "Executor",
    "ExecutorStartError",
    "Finding",
    "Metric",
    "Outcome",
    "Reference",
    "ResultStore",
    "ResultsDirError",
    "RunSummary",
    "StoreLockedError",
    "Suite",
    "SuiteParams",
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
