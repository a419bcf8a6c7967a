"""Executors: run trials in-process, in a local process pool, or on a Ray cluster.

Every executor calls the same :func:`execute_trial` on the same
:class:`~steer_envs.bench.suite.Trial` objects and yields :class:`Outcome`
objects as trials finish (completion order, not submission order). Because a
trial is a pure function of its config and seed, the ``value`` metrics are
identical whichever executor runs them.

Ray is optional (``pip install "steer-envs[ray]"``) and imported only when
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
import contextlib
import ctypes
import math
import multiprocessing
import numbers
import os
import signal
import socket
import sys
import threading
import time
import traceback
from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.bench.provenance import host, versions
from steer_envs.bench.records import SCHEMA_VERSION, encode_record, utc_now
from steer_envs.bench.suite import Trial, TrialResult, resolve_function
from steer_envs.core.extras import require
from steer_envs.core.validation import describe

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


class ExecutorStartError(RuntimeError):
    """An executor that cannot start (Ray not reachable or failing to initialise); the message says why."""


def _as_metric(name: str, value: Any) -> float | None:
    """A metric as a float: real numbers, bools and one-element arrays/tensors (``.item()``); ``None`` passes.

    Complex numbers, strings and other objects raise ``TypeError``; NaN and
    inf ``ValueError`` (a metric that does not apply is ``None``).
    """
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)):
        return float(value)
    if not isinstance(value, numbers.Real) and hasattr(value, "item"):
        try:
            value = value.item()
        except Exception:  # an array of several numbers, a tensor that cannot be read
            raise TypeError(f"metric {name!r} must be a number or None, got {describe(value)}") from None
        if isinstance(value, bool):
            return float(value)
    if not isinstance(value, numbers.Real):
        raise TypeError(f"metric {name!r} must be a real number or None, got {describe(value)}")
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if math.isfinite(number):
        return number
    raise ValueError(f"metric {name!r} is {value!r}; return a finite number, or None when it does not apply")


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
    except (Exception, SystemExit) as exc:  # a failing trial must not take the run down
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
    try:
        encode_record(record)  # the record must be strict JSON before it leaves the worker
    except (TypeError, ValueError) as exc:
        return Outcome(trial, None, f"{type(exc).__name__}: the trial's result is not JSON: {exc}")
    return Outcome(trial, record)


class Executor(ABC):
    """Runs trials and yields their outcomes as they finish."""

    name: str = "executor"

    @abstractmethod
    def map(self, trials: Sequence[Trial]) -> Iterator[Outcome]:
        """Outcomes of ``trials`` in completion order."""

    def start(self) -> None:  # noqa: B027 - optional hook
        """Acquire what :meth:`map` needs (idempotent); :class:`ExecutorStartError` when it cannot."""

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


#: seconds between two checks of the parent by a worker's watchdog thread
WATCHDOG_INTERVAL_S = 0.5
_PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>


def _init_worker(parent_pid: int) -> None:
    """Initializer of a pool worker: ignore Ctrl-C (the parent cancels the pool) and die with the parent."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent_pid)


def die_with_parent(parent_pid: int, interval: float = WATCHDOG_INTERVAL_S) -> None:
    """Make this process end as soon as ``parent_pid`` (its parent) does, however the parent ends.

    On Linux the kernel sends ``SIGKILL`` on the parent's death
    (``prctl(PR_SET_PDEATHSIG)``); everywhere a daemon thread also checks
    ``os.getppid()`` every ``interval`` seconds and exits the process when the
    parent is gone (a portable fallback, and a guard for a parent that died
    before the ``prctl`` call). Orphaned workers would otherwise keep the
    multiprocessing resource tracker alive too.
    """
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # pragma: no cover - no libc prctl: the watchdog still runs
            pass
    if os.getppid() != parent_pid:  # the parent died before the prctl call
        os._exit(1)
    threading.Thread(
        target=_watch_parent, args=(parent_pid, interval), name="steer-bench-parent-watchdog", daemon=True
    ).start()


def _watch_parent(parent_pid: int, interval: float) -> None:
    while True:
        time.sleep(interval)
        if os.getppid() != parent_pid:
            os._exit(1)


def _pool_failure(trial: Trial, exc: BaseException) -> Outcome:
    if isinstance(exc, cf.process.BrokenProcessPool):
        return Outcome(trial, None, f"BrokenProcessPool: a worker process died (crash or kill) while {trial.label} "
                       f"was in flight; it is re-run on resume: {exc}")  # fmt: skip
    return Outcome(trial, None, f"{type(exc).__name__}: {exc}")


class ProcessPoolExecutor(Executor):
    """``workers`` local processes (spawned, so workers start clean on every platform).

    Workers die with this process (:func:`die_with_parent`), also after a
    ``kill -9``. A worker that dies mid-trial fails the trials in flight (they
    are re-run on resume) and the pool is restarted for the rest.
    """

    name = "process"

    def __init__(self, workers: int) -> None:
        self.workers = _check_workers(workers, high=max_local_workers())
        self._pool: cf.ProcessPoolExecutor | None = None

    def start(self) -> None:
        if self._pool is None:
            self._pool = cf.ProcessPoolExecutor(
                max_workers=self.workers,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_init_worker,
                initargs=(os.getpid(),),
            )

    def map(self, trials: Sequence[Trial]) -> Iterator[Outcome]:
        queue = list(trials)[::-1]
        pending: dict[cf.Future[Outcome], Trial] = {}
        max_in_flight = 2 * self.workers
        while queue or pending:
            self.start()
            assert self._pool is not None
            while queue and len(pending) < max_in_flight:
                trial = queue.pop()
                pending[self._pool.submit(execute_trial, trial, self.name)] = trial
            done, _ = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
            broken = False
            for future in done:
                trial = pending.pop(future)
                try:
                    outcome = future.result()
                except Exception as exc:  # a result that cannot be unpickled, a dead worker
                    broken |= isinstance(exc, cf.process.BrokenProcessPool)
                    outcome = _pool_failure(trial, exc)
                yield outcome
            if broken:  # every trial in flight is lost with the pool: fail them, start a new pool
                for trial in list(pending.values()):
                    yield _pool_failure(trial, cf.process.BrokenProcessPool("the pool was broken by a dead worker"))
                pending.clear()
                self._pool.shutdown(wait=False, cancel_futures=True)
                self._pool = None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def import_ray() -> Any:
    """``import ray``; without it an ``ImportError`` naming ``pip install "steer-envs[ray]"``."""
    return require("ray", "ray", "the Ray executor")


class RayExecutor(Executor):
    """Trials as Ray tasks (one CPU each) on a cluster at ``address``.

    ``address=None`` starts a private local Ray instance with ``workers`` CPUs
    (shut down again by :meth:`close`) unless Ray is already initialised or
    ``RAY_ADDRESS`` is set; ``"host:port"`` (the head's ``--port``), ``"auto"``
    or ``"ray://host:10001"`` joins a running cluster. Trial functions (and
    ``--plugin`` modules) must be importable on every node.

    A trial whose worker process or node dies is re-run by Ray on a live node
    (up to :data:`RAY_TASK_RETRIES` times); a trial that raises is not re-run
    (trials are deterministic: it would raise again). Each trial yields one
    :class:`Outcome`, however often Ray ran it. A cluster that does not answer
    fails :meth:`start` with :class:`ExecutorStartError` (``steer-bench``:
    exit 2) within :data:`RAY_CONNECT_TIMEOUT_S` seconds when nothing listens
    there, or within about a minute (:data:`RAY_GCS_CONNECT_ATTEMPTS` of Ray's
    attempts) when something that is not a Ray head does; never a hang.
    """

    name = "ray"

    def __init__(self, workers: int | None = None, address: str | None = None) -> None:
        self.workers = None if workers is None else _check_workers(workers)
        if address is not None and (not isinstance(address, str) or not address.strip()):
            raise ValueError(f"address must be a non-empty str ('auto', 'ray://host:10001') or None, got {address!r}")
        self.address = address
        self._ray = import_ray()
        self._started = False
        self._remote: Any = None

    def start(self) -> None:
        ray = self._ray
        if not ray.is_initialized():
            _check_reachable(self.address or os.environ.get("RAY_ADDRESS"))
        try:
            if not ray.is_initialized():
                kwargs: dict[str, Any] = {
                    "address": self.address,
                    "include_dashboard": False,
                    "logging_level": "WARNING",
                }
                target = self.address or os.environ.get("RAY_ADDRESS")
                if not target:
                    kwargs["num_cpus"] = self.workers or os.cpu_count() or 1
                with _bounded_gcs_wait(target not in (None, "", "local")):
                    ray.init(**kwargs)
                self._started = True
            if self._remote is None:
                self._remote = ray.remote(num_cpus=1, max_retries=RAY_TASK_RETRIES, retry_exceptions=False)(
                    execute_trial
                )
        except Exception as exc:  # Ray raises ConnectionError, RuntimeError, ValueError, ... when it cannot start
            where = f"the Ray cluster at {self.address}" if self.address else "a local Ray instance"
            detail = " ".join(str(exc).split())[:300] or type(exc).__name__
            hint = f"; {_join_hint(self.address)}" if self.address and isinstance(exc, ConnectionError) else ""
            raise ExecutorStartError(f"cannot start {where}: {type(exc).__name__}: {detail}{hint}") from exc

    def map(self, trials: Sequence[Trial]) -> Iterator[Outcome]:
        if not trials:  # nothing to run: no reason to start Ray
            return
        self.start()
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
                    outcome = ray.get(ref)
                except ray.exceptions.RayError as exc:  # retries used up (worker crash, lost node), unpicklable result
                    outcome = Outcome(trial, None, f"{type(exc).__name__}: {exc}\n(it is re-run on resume)")
                yield _with_import_hint(outcome)

    def close(self) -> None:
        if self._started:
            self._ray.shutdown()
            self._started = False
        self._remote = None


#: times Ray re-runs a trial whose worker process or node died (system failures only: a trial that raises is final)
RAY_TASK_RETRIES = 3
#: seconds to wait for the TCP connection to a Ray cluster's address before giving up
RAY_CONNECT_TIMEOUT_S = 10.0
#: attempts ``ray.init`` makes to reach a cluster's GCS (Ray's default is 20, each up to ~40 s: minutes of silence)
RAY_GCS_CONNECT_ATTEMPTS = 1
#: Ray's setting for those attempts (read by ``ray.init`` when it joins a cluster)
_GCS_WAIT_ENV = "RAY_gcs_server_port_wait_time_s"


def _join_hint(address: str) -> str:
    """What to check when ``ray.init(address)`` could not connect."""
    if address.startswith("ray://"):
        where = "the head's Ray Client address (`ray start --head --ray-client-server-port`, 10001 by default)"
    else:
        where = "the head's GCS address (`ray start --head --port PORT` prints it)"
    return (
        f"is it {where}, and, when the cluster uses token authentication, are RAY_AUTH_MODE=token and the "
        "cluster's token (RAY_AUTH_TOKEN, RAY_AUTH_TOKEN_PATH or ~/.ray/auth_token) set here too?"
    )


@contextlib.contextmanager
def _bounded_gcs_wait(joining: bool) -> Iterator[None]:
    """While joining a cluster, cap ``ray.init``'s GCS attempts at :data:`RAY_GCS_CONNECT_ATTEMPTS`.

    The setting is an environment variable that Ray reads at connect time; it
    is restored afterwards, so a later local Ray start in this process keeps
    Ray's own patience. A value the user set is left alone.
    """
    if not joining or _GCS_WAIT_ENV in os.environ:
        yield
        return
    os.environ[_GCS_WAIT_ENV] = str(RAY_GCS_CONNECT_ATTEMPTS)
    try:
        yield
    finally:
        os.environ.pop(_GCS_WAIT_ENV, None)


def _with_import_hint(outcome: Outcome) -> Outcome:
    """A trial whose module is missing on a Ray worker: say that it must be importable on every node."""
    if outcome.error is None or not outcome.error.startswith("ModuleNotFoundError"):
        return outcome
    first, _, rest = outcome.error.partition("\n")
    hint = (
        " (on a Ray worker: the trial's module and --plugin modules must be importable on every node; "
        "install them there, or start the node with their folder on PYTHONPATH)"
    )
    return Outcome(outcome.trial, None, f"{first}{hint}\n{rest}")


def _check_reachable(address: str | None, timeout: float = RAY_CONNECT_TIMEOUT_S) -> None:
    """:class:`ExecutorStartError` unless ``host:port`` (or ``ray://host:port``) accepts a TCP connection.

    ``ray.init`` retries an unreachable address for minutes; this check
    fails within ``timeout`` seconds instead. ``None``, ``"auto"`` and
    ``"local"`` are left to Ray (which answers those at once).
    """
    if not address or address in ("auto", "local"):
        return
    target = address.removeprefix("ray://")
    host, sep, port = target.rpartition(":")
    if not sep or not port.isdigit() or not host:
        return
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            pass
    except (OSError, ValueError, OverflowError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        raise ExecutorStartError(f"cannot reach the Ray cluster at {address}: {reason}") from None


def max_local_workers() -> int:
    """The most processes a local pool may start: ``max(256, 4 x CPUs)`` (a typo must not fork-bomb the machine)."""
    return max(256, 4 * (os.cpu_count() or 1))


def _check_workers(workers: Any, high: int | None = None) -> int:
    if isinstance(workers, (bool, np.bool_)) or not isinstance(workers, (int, np.integer)):
        raise TypeError(f"workers must be a positive int, got {describe(workers)}")
    if workers < 1 or (high is not None and workers > high):
        span = "a positive int" if high is None else f"an int in [1, {high}] for a local pool"
        raise ValueError(f"workers must be {span}, got {workers!r}")
    return int(workers)


def make_executor(kind: str = "local", workers: int | None = None, address: str | None = None) -> Executor:
    """The executor for ``--executor kind --workers N [--address A]``.

    ``local`` with one worker (the default): in-process; ``local`` with more:
    a process pool; ``ray``: Ray tasks (``workers`` defaults to every CPU).

    >>> make_executor().name, make_executor("local", workers=2).name
    ('sequential', 'process')
    """
    if not isinstance(kind, str) or kind not in EXECUTORS:
        raise ValueError(f"executor must be one of {EXECUTORS}, got {kind!r}")
    if workers is not None:
        workers = _check_workers(workers)
    if kind == "ray":
        return RayExecutor(workers=workers, address=address)
    if address is not None:
        raise ValueError("address is only used by the ray executor (--executor ray)")
    return SequentialExecutor() if workers in (None, 1) else ProcessPoolExecutor(workers)
