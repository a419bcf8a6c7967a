"""Executors: run trials in-process, in a local process pool, or on a Ray cluster.

Every executor calls the same :func:`execute_trial` on the same
:class:`~steer_envs.bench.suite.Trial` objects and yields :class:`Outcome`
objects as trials finish (completion order, not submission order). Because a
trial is a pure function of its config and seed, the ``value`` metrics are
identical whichever executor runs them.

Ray is optional (``pip install 'steer-envs[ray]'``) and imported only when
the Ray executor is created.

>>> from steer_envs.bench.runner import build_request, plan_trials
>>> from steer_envs.bench.suite import get_suite
>>> suite = get_suite("selftest")
>>> plan = plan_trials(suite, build_request(suite, methods=["stratified"], seeds=2, trials=100))
>>> with make_executor("local") as executor:
...     [o.record["metrics"]["pi"] for o in executor.map(plan.trials)]
[3.16, 3.12]
"""

from __future__ import annotations

import concurrent.futures as cf
import math
import multiprocessing
import numbers
import os
import signal
import time
import traceback
from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from steer_envs.bench.provenance import host, versions
from steer_envs.bench.store import SCHEMA_VERSION, utc_now
from steer_envs.bench.suite import Trial, TrialResult, resolve_function

EXECUTORS: tuple[str, ...] = ("local", "ray")


@dataclass(frozen=True)
class Outcome:
    """A finished trial: the record to store, or the error it raised."""

    trial: Trial
    record: dict[str, Any] | None
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.record is not None


def _as_metric(name: str, value: Any) -> float | None:
    if value is None:
        return None
    if isinstance(value, (bool, numbers.Real)) or hasattr(value, "item"):
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = math.nan
        if math.isfinite(number):
            return number
        raise ValueError(f"metric {name!r} is {value!r}; return a finite number, or None when it does not apply")
    raise TypeError(f"metric {name!r} must be a number or None, got {type(value).__name__}")


def execute_trial(trial: Trial, executor: str = "local") -> Outcome:
    """Run one trial and build its record; exceptions become an error :class:`Outcome`.

    The record holds the config, seed, metrics, optional ``extra`` data,
    timings (wall and CPU seconds, start/end UTC) and provenance (versions,
    git commit, host).

    >>> from steer_envs.bench.suite import Trial
    >>> fn = "steer_envs.bench.suites.selftest:run_selftest_trial"
    >>> ok = execute_trial(Trial("selftest", None, "mc", 0, {"samples": 100}, fn))
    >>> ok.ok, sorted(ok.record["metrics"])
    (True, ['abs_error', 'pi', 'samples_per_s'])
    >>> failed = execute_trial(Trial("selftest", None, "mc", 1, {"samples": 100, "fail_seeds": [1]}, fn))
    >>> failed.error.splitlines()[0]
    'RuntimeError: selftest: seed 1 is listed in fail_seeds'
    """
    started = utc_now()
    wall0, cpu0 = time.perf_counter(), time.process_time()
    try:
        out = resolve_function(trial.fn)(trial)
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        if isinstance(out, TrialResult):
            raw_metrics, extra = out.metrics, dict(out.extra)
        elif isinstance(out, Mapping):
            raw_metrics, extra = out, {}
        else:
            raise TypeError(f"{trial.fn} must return a mapping of metrics or a TrialResult, got {type(out).__name__}")
        metrics = {str(k): _as_metric(str(k), v) for k, v in raw_metrics.items()}
    except Exception as exc:  # a failing trial must not take the run down
        detail = "".join(traceback.format_exception(exc)).rstrip()
        return Outcome(trial, None, f"{type(exc).__name__}: {exc}\n{detail}")
    record: dict[str, Any] = {
        "schema": SCHEMA_VERSION,
        "key": trial.key,
        "config": trial.config,
        "seed": trial.seed,
        "fn": trial.fn,
        "metrics": metrics,
        "timings": {"wall_s": wall, "cpu_s": cpu, "started": started, "finished": utc_now()},
        "versions": versions(),
        "host": host(),
        "executor": executor,
    }
    if extra:
        record["extra"] = extra
    return Outcome(trial, record)


class Executor(ABC):
    """Runs trials and yields their outcomes as they finish."""

    name: str = "executor"

    @abstractmethod
    def map(self, trials: Sequence[Trial]) -> Iterator[Outcome]:
        """Outcomes of ``trials`` in completion order."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release workers (idempotent)."""

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SequentialExecutor(Executor):
    """One trial after the other in this process (``--workers 1``)."""

    name = "sequential"

    def map(self, trials: Sequence[Trial]) -> Iterator[Outcome]:
        for trial in trials:
            yield execute_trial(trial, self.name)


def _ignore_sigint() -> None:
    # Ctrl-C is handled by the parent, which cancels the pool; workers just stop.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class ProcessPoolExecutor(Executor):
    """``workers`` local processes (spawned, so workers start clean on every platform)."""

    name = "process"

    def __init__(self, workers: int) -> None:
        self.workers = _check_workers(workers)
        self._pool: cf.ProcessPoolExecutor | None = None

    def map(self, trials: Sequence[Trial]) -> Iterator[Outcome]:
        if self._pool is None:
            self._pool = cf.ProcessPoolExecutor(
                max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"), initializer=_ignore_sigint
            )
        queue = list(trials)[::-1]
        pending: dict[cf.Future[Outcome], Trial] = {}
        max_in_flight = 2 * self.workers
        while queue or pending:
            while queue and len(pending) < max_in_flight:
                trial = queue.pop()
                pending[self._pool.submit(execute_trial, trial, self.name)] = trial
            done, _ = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
            for future in done:
                trial = pending.pop(future)
                try:
                    yield future.result()
                except cf.process.BrokenProcessPool as exc:
                    raise RuntimeError(f"a worker process died while running {trial.label}: {exc}") from exc

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def import_ray() -> Any:
    """``import ray`` with an actionable message when it is missing."""
    try:
        import ray
    except ImportError as exc:
        raise ImportError("the Ray executor needs the optional dependency ray: pip install 'steer-envs[ray]'") from exc
    return ray


class RayExecutor(Executor):
    """Trials as Ray tasks (one CPU each) on a cluster at ``address``.

    ``address=None`` starts a private local Ray instance with ``workers`` CPUs
    (shut down again by :meth:`close`) unless Ray is already initialised or
    ``RAY_ADDRESS`` is set; ``"auto"`` or ``"ray://host:10001"`` joins a
    running cluster. Trial functions must be importable on the workers.
    """

    name = "ray"

    def __init__(self, workers: int | None = None, address: str | None = None) -> None:
        self.workers = None if workers is None else _check_workers(workers)
        self.address = address
        self._ray = import_ray()
        self._started = False
        self._remote: Any = None

    def _ensure_started(self) -> None:
        ray = self._ray
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"address": self.address, "include_dashboard": False, "logging_level": "WARNING"}
            if self.address is None and not os.environ.get("RAY_ADDRESS"):
                kwargs["num_cpus"] = self.workers or os.cpu_count() or 1
            ray.init(**kwargs)
            self._started = True
        if self._remote is None:
            self._remote = ray.remote(num_cpus=1, max_retries=0)(execute_trial)

    def map(self, trials: Sequence[Trial]) -> Iterator[Outcome]:
        self._ensure_started()
        ray = self._ray
        in_flight = 2 * (self.workers or max(1, int(ray.cluster_resources().get("CPU", 1))))
        queue = list(trials)[::-1]
        pending: dict[Any, Trial] = {}
        while queue or pending:
            while queue and len(pending) < in_flight:
                trial = queue.pop()
                pending[self._remote.remote(trial, self.name)] = trial
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                trial = pending.pop(ref)
                try:
                    yield ray.get(ref)
                except ray.exceptions.RayError as exc:  # worker crash, lost node, unpicklable result
                    yield Outcome(trial, None, f"{type(exc).__name__}: {exc}")

    def close(self) -> None:
        if self._started:
            self._ray.shutdown()
            self._started = False
        self._remote = None


def _check_workers(workers: Any) -> int:
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be a positive int, got {workers!r}")
    return workers


def make_executor(kind: str = "local", workers: int | None = None, address: str | None = None) -> Executor:
    """The executor for ``--executor kind --workers N [--address A]``.

    ``local`` with one worker (the default): in-process; ``local`` with more:
    a process pool; ``ray``: Ray tasks (``workers`` defaults to every CPU).

    >>> make_executor().name, make_executor("local", workers=2).name
    ('sequential', 'process')
    """
    if kind not in EXECUTORS:
        raise ValueError(f"executor must be one of {EXECUTORS}, got {kind!r}")
    if workers is not None:
        workers = _check_workers(workers)
    if kind == "ray":
        return RayExecutor(workers=workers, address=address)
    if address is not None:
        raise ValueError("address is only used by the ray executor (--executor ray)")
    return SequentialExecutor() if workers in (None, 1) else ProcessPoolExecutor(workers)
