"""Run a suite into a results directory: plan, skip finished trials, execute, append.

This is the Python API behind ``steer-bench run``. A second call on the same
directory resumes: trials whose key is already in ``results.jsonl`` are
skipped, the others run and are appended one line each as they finish.

>>> import tempfile
>>> with tempfile.TemporaryDirectory() as out:
...     first = run_suite("selftest", out, seeds=2, trials=100, progress=False)
...     again = run_suite("selftest", out, seeds=3, trials=100, progress=False)
>>> (first.completed, first.skipped), (again.completed, again.skipped), again.ok
((4, 0), (2, 4), True)
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.executors import EXECUTORS, Executor, Outcome, make_executor
from steer_envs.bench.store import ResultStore, check_output_dir
from steer_envs.bench.suite import Suite, Trial, TrialPlan, TrialRequest, get_suite
from steer_envs.core.progress import check_progress, progress_bar
from steer_envs.core.validation import boolean, describe, integer
from steer_envs.envs.registry import NAMESPACE


@dataclass
class RunSummary:
    """What one ``run`` did (see :func:`run_suite` for an example)."""

    suite: str
    out_dir: Path
    planned: int  # trials in the plan
    skipped: int  # already in results.jsonl (resumed)
    completed: int  # run and recorded now
    failures: list[Outcome] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    records: list[dict[str, Any]] = field(default_factory=list)  # every record of the directory
    interrupted: bool = False
    previous: Path | None = None  # where ``fresh=True`` moved the earlier results (None: nothing moved)

    @property
    def ok(self) -> bool:
        """Every planned trial is recorded."""
        return not self.failures and not self.interrupted

    @property
    def all_done(self) -> bool:
        """Every planned trial was already in the directory: nothing ran (and no executor was started)."""
        return self.planned > 0 and self.skipped == self.planned


#: the most trials one run may plan (a bound that keeps a typo in ``--seeds`` from exhausting memory)
MAX_PLANNED_TRIALS = 100_000


def _pick(axis: str, wanted: Iterable[str] | None, available: Sequence[str | None]) -> tuple[str | None, ...]:
    """The requested subset of an axis, in the suite's order (ValueError on unknown names)."""
    if wanted is None:
        return tuple(available)
    if isinstance(wanted, (str, bytes)) or not isinstance(wanted, Iterable):
        raise TypeError(f"{axis}s must be a list of names, got {describe(wanted)}")
    wanted = list(wanted)
    if not wanted:
        raise ValueError(f"--{axis} needs at least one name")
    chosen: list[str] = []
    for name in wanted:
        if not isinstance(name, str):
            raise TypeError(f"{axis} names must be strings, got {type(name).__name__}")
        match = next((a for a in available if a is not None and a in (name, f"{NAMESPACE}/{name}")), None)
        if match is None:
            names = ", ".join(str(a) for a in available)
            raise ValueError(f"unknown {axis} {name!r} for this suite; choose from: {names}")
        if match not in chosen:
            chosen.append(match)
    return tuple(a for a in available if a in chosen)


def build_request(
    suite: Suite,
    *,
    envs: Iterable[str] | None = None,
    methods: Iterable[str] | None = None,
    seeds: int | Sequence[int] | None = None,
    trials: int | None = None,
    params: Mapping[str, Any] | None = None,
) -> TrialRequest:
    """Validate the ``run`` options against ``suite``.

    ``seeds`` is a count (seeds ``0..N-1``) or an explicit list of distinct
    non-negative ints; ``trials`` a positive int; ``params`` a mapping of
    parameter names. Env names may omit the ``steer_envs/`` namespace. A
    request of more than :data:`MAX_PLANNED_TRIALS` trials (envs x methods x
    seeds) is refused. ``TypeError`` / ``ValueError`` name the argument.

    >>> from steer_envs.bench.suite import get_suite
    >>> request = build_request(get_suite("smoke"), envs=["ConvexMode-v0"], seeds=[5, 9])
    >>> request.envs, request.seeds
    (('steer_envs/ConvexMode-v0',), (5, 9))
    """
    if not isinstance(suite, Suite):
        raise TypeError(f"suite must be a Suite, got {describe(suite)}")
    seed_tuple = _seed_tuple(seeds)
    if trials is not None:
        trials = integer(trials, "trials", low=1)
    if params is None:
        params = {}
    if not isinstance(params, Mapping):
        raise TypeError(f"params must be a mapping of parameter names to values, got {describe(params)}")
    for name in params:
        if not isinstance(name, str):
            raise TypeError(f"params names must be strs, got {describe(name)}")
    request = TrialRequest(
        envs=_pick("env", envs, suite.env_list()),
        methods=_pick("method", methods, suite.method_list()),
        seeds=seed_tuple,
        params=dict(params),
        trials=trials,
    )
    n_seeds = len(seed_tuple) if seed_tuple is not None else suite.default_seeds
    planned = len(request.envs) * len(request.methods) * n_seeds
    if planned > MAX_PLANNED_TRIALS:
        raise ValueError(
            f"at most {MAX_PLANNED_TRIALS} trials per run, the request makes up to {planned} "
            f"({len(request.envs)} envs x {len(request.methods)} methods x {n_seeds} seeds); "
            "use fewer --seeds or split the run by --env / --method"
        )
    return request


def _seed_tuple(seeds: int | Sequence[int] | None) -> tuple[int, ...] | None:
    """The seeds of a request: a count ``N`` (``0..N-1``) or distinct non-negative ints; None: the suite's."""
    if seeds is None:
        return None
    if isinstance(seeds, (int, np.integer)) and not isinstance(seeds, (bool, np.bool_)):
        count = integer(seeds, "seeds", low=1)
        if count > MAX_PLANNED_TRIALS:
            raise ValueError(f"seeds: at most {MAX_PLANNED_TRIALS} trials per run, got {count} seeds; split the run")
        return tuple(range(count))
    if isinstance(seeds, (str, bytes, Mapping)) or not isinstance(seeds, Iterable):
        raise TypeError(f"seeds must be an int count or a sequence of ints, got {describe(seeds)}")
    seed_list: list[int] = []
    for i, s in enumerate(seeds):
        seed_list.append(integer(s, f"seeds[{i}]", low=0))
        if len(seed_list) > MAX_PLANNED_TRIALS:
            raise ValueError(f"seeds: at most {MAX_PLANNED_TRIALS} trials per run; split the run")
    if not seed_list:
        raise ValueError("seeds must not be empty")
    if len(set(seed_list)) != len(seed_list):
        raise ValueError(f"seeds must be distinct, got {describe(seeds)}")
    return tuple(seed_list)


def plan_trials(suite: Suite, request: TrialRequest) -> TrialPlan:
    """The suite's plan for ``request``, checked for duplicate trial keys.

    >>> from steer_envs.bench.suite import get_suite
    >>> suite = get_suite("selftest")
    >>> len(plan_trials(suite, build_request(suite, seeds=3)).trials)  # 2 methods x 3 seeds
    6
    """
    plan = suite.plan(request)
    if not isinstance(plan, TrialPlan):
        raise TypeError(f"suite {suite.name!r}: plan must be a TrialPlan, got {describe(plan)}")
    if len(plan.trials) > MAX_PLANNED_TRIALS:
        raise ValueError(
            f"suite {suite.name!r} planned {len(plan.trials)} trials, at most {MAX_PLANNED_TRIALS} per run; "
            "use fewer --seeds or split the run by --env / --method"
        )
    for t in plan.trials:
        if not isinstance(t, Trial):
            raise TypeError(f"suite {suite.name!r} generated {describe(t)}, not a Trial")
        if not suite.accepts_records_of(t.suite):
            raise ValueError(f"suite {suite.name!r} generated a trial of suite {t.suite!r}, which it does not hold")
    keys = [t.key for t in plan.trials]
    if len(set(keys)) != len(keys):
        raise ValueError(f"suite {suite.name!r} generated duplicate trials (same config and seed)")
    return plan


def check_metrics(outcome: Outcome) -> Outcome:
    """Reject metrics the trial's suite does not declare (typos would vanish from reports).

    >>> from steer_envs.bench.suite import Trial
    >>> trial = Trial("selftest", None, "mc", 0, {}, "steer_envs.bench.suites.selftest:run_selftest_trial")
    >>> check_metrics(Outcome(trial, {"metrics": {"pie": 3.1}})).error
    "ValueError: undeclared metrics ['pie']; declared: ['abs_error', 'pi', 'samples_per_s']"
    """
    if outcome.record is None:
        return outcome
    try:
        declared = {m.name for m in get_suite(outcome.trial.suite).metrics}
    except KeyError:
        return outcome
    unknown = sorted(set(outcome.record["metrics"]) - declared)
    if unknown:
        return Outcome(outcome.trial, None, f"ValueError: undeclared metrics {unknown}; declared: {sorted(declared)}")
    return outcome


def run_suite(
    suite: str | Suite,
    out_dir: str | os.PathLike[str],
    *,
    envs: Iterable[str] | None = None,
    methods: Iterable[str] | None = None,
    seeds: int | Sequence[int] | None = None,
    trials: int | None = None,
    params: Mapping[str, Any] | None = None,
    executor: str | Executor = "local",
    workers: int | None = None,
    address: str | None = None,
    progress: bool | None = None,
    fresh: bool = False,
    argv: Sequence[str] | None = None,
) -> RunSummary:
    """Run (or resume) ``suite`` into ``out_dir``; see the module docstring.

    ``KeyboardInterrupt`` is caught: the summary comes back with
    ``interrupted=True`` and every finished trial is on disk. A trial that
    raises (or whose record cannot be stored) is a failure in the summary and
    in ``failures.jsonl``; the run goes on. Bad requests raise ``TypeError`` /
    ``ValueError`` before anything is written; an unusable ``out_dir``
    :class:`~steer_envs.bench.records.ResultsDirError`; an executor that cannot
    start :class:`~steer_envs.bench.executors.ExecutorStartError`.

    When every planned trial is already recorded, no executor is started (no
    process pool, no Ray) and the summary says :attr:`RunSummary.all_done`.
    ``fresh=True`` starts over: the directory's earlier results move to
    ``out_dir/previous/<UTC time>/`` first (nothing is deleted; see
    :mod:`steer_envs.bench.store`) and every planned trial runs.
    ``progress``: ``None`` a bar only when stderr is a terminal, ``True``
    always, ``False`` never (:mod:`steer_envs.core.progress`).

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as out:
    ...     summary = run_suite("selftest", out, methods=["stratified"], seeds=1, trials=100, progress=False)
    >>> summary.ok, summary.records[0]["metrics"]["pi"]
    (True, 3.16)
    """
    suite, out, progress, fresh = _check_run_args(suite, out_dir, progress, fresh, argv, executor)
    request = build_request(suite, envs=envs, methods=methods, seeds=seeds, trials=trials, params=params)
    plan = plan_trials(suite, request)
    runner = make_executor(executor, workers, address) if isinstance(executor, str) else executor
    summary = RunSummary(suite.name, out, planned=len(plan.trials), skipped=0, completed=0)
    summary.notes.extend(plan.notes)
    with ResultStore(out, suite.name, accepts_suite=suite.accepts_records_of, fresh=fresh) as store:
        todo = _start(store, runner, plan, summary)
        store.start_session(_session(argv, runner, request, summary, fresh))
        for note in summary.notes:
            _write(None, f"note: {note}")
        if todo:
            _run_trials(runner, todo, store, summary, progress)
        else:  # all done: nothing to start (a Ray executor would start Ray in map)
            runner.close()
        summary.records = list(store.records)
    return summary


def _check_run_args(
    suite: str | Suite,
    out_dir: str | os.PathLike[str],
    progress: bool | None,
    fresh: bool,
    argv: Sequence[str] | None,
    executor: str | Executor,
) -> tuple[Suite, Path, bool | None, bool]:
    """:func:`run_suite`'s arguments checked: the suite (looked up by name), the output folder, the flags."""
    suite = get_suite(suite) if isinstance(suite, str) else suite
    if not isinstance(suite, Suite):
        raise TypeError(f"suite must be a name or a Suite, got {type(suite).__name__}")
    out = check_output_dir(out_dir)
    progress = check_progress(progress)
    fresh = boolean(fresh, "fresh")
    if argv is not None and (isinstance(argv, (str, bytes)) or not all(isinstance(a, str) for a in argv)):
        raise TypeError(f"argv must be a list of strs or None, got {describe(argv)}")
    if not isinstance(executor, (str, Executor)):
        raise TypeError(f"executor must be a name {EXECUTORS} or an Executor, got {describe(executor)}")
    return suite, out, progress, fresh


def _start(store: ResultStore, runner: Executor, plan: TrialPlan, summary: RunSummary) -> list[Trial]:
    """The planned trials not yet in ``store`` (the others count as skipped); starts ``runner`` if any are left."""
    summary.notes.extend(store.notes)
    summary.previous = store.previous
    done = store.finished_keys
    todo: list[Trial] = [t for t in plan.trials if t.key not in done]
    summary.skipped = len(plan.trials) - len(todo)
    if todo:
        runner.start()  # an executor that cannot start fails here, before the session is recorded
    return todo


def _session(
    argv: Sequence[str] | None, runner: Executor, request: TrialRequest, summary: RunSummary, fresh: bool
) -> dict[str, Any]:
    """The ``sessions.jsonl`` entry of a run: its command, executor, request and plan."""
    return {
        "argv": list(argv) if argv is not None else None,
        "executor": runner.name,
        "request": {
            "envs": list(request.envs),
            "methods": list(request.methods),
            "seeds": None if request.seeds is None else list(request.seeds),
            "trials": request.trials,
            "params": dict(request.params),
        },
        "planned": summary.planned,
        "skipped": summary.skipped,
        "fresh": fresh,
        "notes": list(summary.notes),
    }


def _run_trials(
    runner: Executor, todo: list[Trial], store: ResultStore, summary: RunSummary, progress: bool | None
) -> None:
    """Run ``todo`` and store each outcome as it finishes; a ``KeyboardInterrupt`` marks the summary interrupted."""
    bar = progress_bar(
        total=len(todo),
        enabled=progress,
        desc=summary.suite,
        unit="trial",
        file=sys.stderr,
        dynamic_ncols=True,
    )
    try:
        with runner:
            for outcome in runner.map(todo):
                outcome = _store_outcome(store, check_metrics(outcome))
                if outcome.ok:
                    summary.completed += 1
                else:
                    summary.failures.append(outcome)
                    store.append_failure(
                        {
                            "key": outcome.trial.key,
                            "config": outcome.trial.config,
                            "seed": outcome.trial.seed,
                            "error": outcome.error,
                        }
                    )
                    first = (outcome.error or "").splitlines()[0] if outcome.error else "unknown error"
                    _write(bar, f"FAILED {outcome.trial.label}: {first}")
                bar.update(1)
                bar.set_postfix_str(f"failed={len(summary.failures)}" if summary.failures else "")
    except KeyboardInterrupt:
        summary.interrupted = True
    finally:
        bar.close()


def _store_outcome(store: ResultStore, outcome: Outcome) -> Outcome:
    """Append a finished trial's record; a record the store refuses turns the outcome into a failure."""
    if outcome.record is None:
        return outcome
    try:
        store.append(outcome.record)
    except (TypeError, ValueError) as exc:
        return Outcome(outcome.trial, None, f"{type(exc).__name__}: the trial's record cannot be stored: {exc}")
    return outcome


def _write(bar: Any, message: str) -> None:
    if bar is not None and not bar.disable:
        bar.write(message, file=sys.stderr)
    else:
        print(message, file=sys.stderr)
