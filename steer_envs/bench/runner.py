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

from steer_envs.bench.executors import Executor, Outcome, make_executor
from steer_envs.bench.store import ResultStore
from steer_envs.bench.suite import Suite, Trial, TrialPlan, TrialRequest, get_suite
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

    @property
    def ok(self) -> bool:
        """Every planned trial is recorded."""
        return not self.failures and not self.interrupted


def _pick(axis: str, wanted: Iterable[str] | None, available: Sequence[str | None]) -> tuple[str | None, ...]:
    """The requested subset of an axis, in the suite's order (ValueError on unknown names)."""
    if wanted is None:
        return tuple(available)
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

    ``seeds`` is a count (seeds ``0..N-1``) or an explicit list of seeds.
    Env names may omit the ``steer_envs/`` namespace.

    >>> from steer_envs.bench.suite import get_suite
    >>> request = build_request(get_suite("smoke"), envs=["ConvexMode-v0"], seeds=[5, 9])
    >>> request.envs, request.seeds
    (('steer_envs/ConvexMode-v0',), (5, 9))
    """
    if isinstance(seeds, bool):
        raise TypeError("seeds must be an int count or a sequence of ints")
    if isinstance(seeds, int):
        if seeds < 1:
            raise ValueError(f"seeds must be >= 1, got {seeds}")
        seed_tuple: tuple[int, ...] | None = tuple(range(seeds))
    elif seeds is None:
        seed_tuple = None
    else:
        seed_tuple = tuple(seeds)
        if not seed_tuple or not all(isinstance(s, int) and not isinstance(s, bool) for s in seed_tuple):
            raise ValueError(f"seeds must be a non-empty sequence of ints, got {seeds!r}")
    if trials is not None and (isinstance(trials, bool) or not isinstance(trials, int) or trials < 1):
        raise ValueError(f"trials must be a positive int, got {trials!r}")
    return TrialRequest(
        envs=_pick("env", envs, suite.env_list()),
        methods=_pick("method", methods, suite.method_list()),
        seeds=seed_tuple,
        params=dict(params or {}),
        trials=trials,
    )


def plan_trials(suite: Suite, request: TrialRequest) -> TrialPlan:
    """The suite's plan for ``request``, checked for duplicate trial keys.

    >>> from steer_envs.bench.suite import get_suite
    >>> suite = get_suite("selftest")
    >>> len(plan_trials(suite, build_request(suite, seeds=3)).trials)  # 2 methods x 3 seeds
    6
    """
    plan = suite.plan(request)
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
    progress: bool = True,
    argv: Sequence[str] | None = None,
) -> RunSummary:
    """Run (or resume) ``suite`` into ``out_dir``; see the module docstring.

    ``KeyboardInterrupt`` is caught: the summary comes back with
    ``interrupted=True`` and every finished trial is on disk.

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as out:
    ...     summary = run_suite("selftest", out, methods=["stratified"], seeds=1, trials=100, progress=False)
    >>> summary.ok, summary.records[0]["metrics"]["pi"]
    (True, 3.16)
    """
    suite = get_suite(suite) if isinstance(suite, str) else suite
    if not isinstance(suite, Suite):
        raise TypeError(f"suite must be a name or a Suite, got {type(suite).__name__}")
    request = build_request(suite, envs=envs, methods=methods, seeds=seeds, trials=trials, params=params)
    plan = plan_trials(suite, request)
    runner = make_executor(executor, workers, address) if isinstance(executor, str) else executor
    summary = RunSummary(suite.name, Path(out_dir), planned=len(plan.trials), skipped=0, completed=0)
    summary.notes.extend(plan.notes)
    with ResultStore(out_dir, suite.name) as store:
        summary.notes.extend(store.notes)
        done = store.finished_keys
        todo: list[Trial] = [t for t in plan.trials if t.key not in done]
        summary.skipped = len(plan.trials) - len(todo)
        store.start_session(
            {
                "argv": list(argv) if argv is not None else None,
                "executor": runner.name,
                "request": {
                    "envs": list(request.envs),
                    "methods": list(request.methods),
                    "seeds": None if request.seeds is None else list(request.seeds),
                    "trials": request.trials,
                    "params": dict(request.params),
                },
                "planned": len(plan.trials),
                "skipped": summary.skipped,
                "notes": list(summary.notes),
            }
        )
        for note in summary.notes:
            _write(None, f"note: {note}")
        bar = _progress_bar(suite.name, len(todo), enabled=progress and bool(todo))
        try:
            with runner:
                for outcome in runner.map(todo):
                    outcome = check_metrics(outcome)
                    if outcome.ok:
                        store.append(outcome.record)  # type: ignore[arg-type]
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
                    if bar is not None:
                        bar.update(1)
                        bar.set_postfix_str(f"failed={len(summary.failures)}" if summary.failures else "")
        except KeyboardInterrupt:
            summary.interrupted = True
        finally:
            if bar is not None:
                bar.close()
        summary.records = list(store.records)
    return summary


def _progress_bar(name: str, total: int, *, enabled: bool) -> Any:
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=name, unit="trial", file=sys.stderr, dynamic_ncols=True)


def _write(bar: Any, message: str) -> None:
    if bar is not None:
        bar.write(message, file=sys.stderr)
    else:
        print(message, file=sys.stderr)
