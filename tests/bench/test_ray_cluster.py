"""The Ray executor on a real two-node cluster that loses a node, and its failure handling.

The ``slow`` tests start a cluster the way users do: ``ray start --head`` and
a second node with ``ray start --address``, both on this machine, each in a
session of its own (its processes are found, and killed, by session id: a
``ray stop`` would also stop other Ray instances of the machine). The cluster
uses token authentication with a token of its own. The fast tests check the
executor's side of it against a stand-in for the ``ray`` module.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from bench_helpers import bench_env

from steer_envs.bench.executors import (
    RAY_GCS_CONNECT_ATTEMPTS,
    RAY_TASK_RETRIES,
    ExecutorStartError,
    RayExecutor,
    execute_trial,
)
from steer_envs.bench.runner import build_request, plan_trials
from steer_envs.bench.suite import Suite, Trial

PLUGIN = "steer_bench_testplugin"
GCS_WAIT_ENV = "RAY_gcs_server_port_wait_time_s"
BIN = Path(sys.executable).parent
SEEDS = 4  # toy: 2 envs x 2 methods x 4 seeds = 16 trials
SLEEP = 1.0  # seconds per trial
START_TIMEOUT_S = 180  # a `ray start` on a busy 2-core machine takes 10-20 s
RUN_TIMEOUT_S = 300


# --------------------------------------------------------------------------- a stand-in for ray (fast tests)
class _LostTask(Exception):
    """What ``ray.get`` raises for a task Ray gave up on (its node died more often than it retries)."""


class _FakeRay:
    """Just enough of ``ray`` for :class:`RayExecutor`: tasks run at once, in this process."""

    def __init__(self, lost: frozenset[str] = frozenset(), init_error: Exception | None = None) -> None:
        self.lost, self.init_error = lost, init_error
        self.exceptions = SimpleNamespace(RayError=_LostTask)
        self.options: dict[str, Any] = {}
        self.gcs_wait_at_init: str | None = "init not called"
        self.initialized = False
        self.results: dict[object, Any] = {}
        self.submitted: list[str] = []

    def is_initialized(self) -> bool:
        return self.initialized

    def init(self, **kwargs: Any) -> None:
        self.gcs_wait_at_init = os.environ.get(GCS_WAIT_ENV)
        if self.init_error is not None:
            raise self.init_error
        self.initialized = True

    def shutdown(self) -> None:
        self.initialized = False

    def cluster_resources(self) -> dict[str, float]:
        return {"CPU": 2.0}

    def remote(self, **options: Any) -> Any:
        self.options = options

        def wrap(fn: Any) -> Any:
            def submit(trial: Trial, executor: str) -> object:
                ref = object()
                self.submitted.append(trial.key)
                lost = trial.key in self.lost
                self.results[ref] = _LostTask("NodeDiedError: the node died") if lost else fn(trial, executor)
                return ref

            return SimpleNamespace(remote=submit)

        return wrap

    def wait(self, refs: list[object], num_returns: int = 1) -> tuple[list[object], list[object]]:
        return refs[:num_returns], refs[num_returns:]

    def get(self, ref: object) -> Any:
        result = self.results.pop(ref)
        if isinstance(result, Exception):
            raise result
        return result


def _toy_trials(suite: Suite, n_seeds: int = 2) -> list[Trial]:
    return list(plan_trials(suite, build_request(suite, seeds=n_seeds)).trials)


@pytest.fixture
def fake_ray(monkeypatch: pytest.MonkeyPatch) -> Iterator[_FakeRay]:
    fake = _FakeRay()
    monkeypatch.setitem(sys.modules, "ray", fake)
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    monkeypatch.delenv(GCS_WAIT_ENV, raising=False)
    yield fake


def test_ray_retries_trials_whose_worker_or_node_died_and_yields_each_trial_once(fake_ray, toy_suite):
    trials = _toy_trials(toy_suite)
    lost = trials[1]
    fake_ray.lost = frozenset({lost.key})
    with RayExecutor(workers=1) as executor:
        outcomes = list(executor.map(trials))
    # system failures (a dead worker or node) are retried by Ray; a trial that raises is final (it would raise again)
    assert fake_ray.options["max_retries"] == RAY_TASK_RETRIES >= 1 and fake_ray.options["retry_exceptions"] is False
    assert sorted(o.trial.key for o in outcomes) == sorted(t.key for t in trials) == sorted(fake_ray.submitted)
    failed = [o for o in outcomes if not o.ok]
    assert [o.trial for o in failed] == [lost]  # Ray gave up on it: a failure, re-run by the next `run`
    assert failed[0].error.startswith("_LostTask: NodeDiedError") and "re-run on resume" in failed[0].error


def test_joining_a_cluster_bounds_rays_connect_attempts_and_restores_the_setting(fake_ray, monkeypatch):
    with socket.socket() as server:  # something listens: the TCP check passes, ray.init decides
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        address = f"127.0.0.1:{server.getsockname()[1]}"
        RayExecutor(address=address).start()
        assert fake_ray.gcs_wait_at_init == str(RAY_GCS_CONNECT_ATTEMPTS)
        assert GCS_WAIT_ENV not in os.environ  # a later local Ray start keeps Ray's own patience
        fake_ray.initialized = False
        RayExecutor(workers=1).start()  # a private local instance: Ray's setting untouched
        assert fake_ray.gcs_wait_at_init is None
        fake_ray.initialized = False
        monkeypatch.setenv(GCS_WAIT_ENV, "7")  # the user's own value wins and stays
        RayExecutor(address=address).start()
        assert fake_ray.gcs_wait_at_init == "7" and os.environ[GCS_WAIT_ENV] == "7"


@pytest.mark.parametrize(
    ("scheme", "names"), [("", "--port PORT"), ("ray://", "--ray-client-server-port")], ids=["gcs", "client"]
)
def test_a_cluster_that_refuses_the_driver_says_what_to_check(fake_ray, scheme, names):
    fake_ray.init_error = ConnectionError("Failed to connect to Ray cluster")
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        address = f"{scheme}127.0.0.1:{server.getsockname()[1]}"
        with pytest.raises(ExecutorStartError) as info:
            RayExecutor(address=address).start()
    message = str(info.value)
    assert message.startswith(f"cannot start the Ray cluster at {address}: ConnectionError: Failed to connect")
    assert names in message and "RAY_AUTH_MODE=token" in message
    assert GCS_WAIT_ENV not in os.environ


def test_a_trial_module_missing_on_a_worker_says_it_must_be_on_every_node(fake_ray):
    trial = Trial("toy", None, "a", 0, {}, "steer_bench_no_such_module:run")
    with RayExecutor(workers=1) as executor:
        (outcome,) = executor.map([trial])
    first = outcome.error.splitlines()[0]
    assert first.startswith("ModuleNotFoundError: No module named 'steer_bench_no_such_module'")
    assert "importable on every node" in first and "PYTHONPATH" in first
    assert "Traceback" in outcome.error  # the traceback is kept under the hint
    assert execute_trial(trial).error.splitlines()[0] == "ModuleNotFoundError: No module named " + (
        "'steer_bench_no_such_module'"
    )  # the hint is the Ray executor's: a local run names only the module


# --------------------------------------------------------------------------- a real two-node cluster (slow)
def _free_ports(n: int) -> list[int]:
    """``n`` distinct ports free on every interface now (held open together so none repeats)."""
    sockets = [socket.socket() for _ in range(n)]
    try:
        for s in sockets:
            s.bind(("", 0))
        return [s.getsockname()[1] for s in sockets]
    finally:
        for s in sockets:
            s.close()


def _session_processes(sid: int) -> dict[int, str]:
    """pid -> command title of every living process of session ``sid`` (Ray workers show ``ray::TASK``)."""
    found: dict[int, str] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        pid = int(entry.name)
        try:
            if os.getsid(pid) != sid:
                continue
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
            title = (entry / "cmdline").read_bytes().split(b"\0")[0].decode(errors="replace")
        except (OSError, IndexError):
            continue
        if state not in ("Z", "X"):
            found[pid] = title
    return found


def _kill_session(sid: int, timeout: float = 15.0) -> dict[int, str]:
    """SIGKILL every process of session ``sid`` until none is left; returns what was killed first."""
    first = _session_processes(sid)
    deadline = time.monotonic() + timeout
    while (left := _session_processes(sid)) and time.monotonic() < deadline:
        for pid in left:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        time.sleep(0.1)
    return first


#: flags of both nodes: loopback, one CPU, workers on ports the system picks (no clash with other Ray instances)
NODE_FLAGS = "--node-ip-address 127.0.0.1 --num-cpus 1 --min-worker-port 0 --max-worker-port 0 --disable-usage-stats"
#: the ports each node listens on (two nodes on one machine must not share one); the head's GCS first
HEAD_PORTS = ("port", "dashboard-port", "ray-client-server-port", "node-manager-port", "object-manager-port",
              "dashboard-agent-listen-port", "dashboard-agent-grpc-port", "runtime-env-agent-port",
              "metrics-export-port")  # fmt: skip
WORKER_PORTS = HEAD_PORTS[3:]


def _port_flags(names: tuple[str, ...], ports: list[int]) -> list[str]:
    """``--NAME PORT`` for each of ``names`` and ``ports``."""
    return [arg for name, port in zip(names, ports, strict=True) for arg in (f"--{name}", str(port))]


@dataclass
class Cluster:
    """A running two-node cluster: its GCS address, the environment that joins it, each node's session."""

    address: str
    env: dict[str, str]
    head_sid: int
    worker_sid: int
    temp_dir: Path


def _ray_start(args: list[str], env: dict[str, str], log: Path) -> int:
    """Run ``ray start ARGS`` in a new session; the session id of the node's processes (they keep it)."""
    with log.open("wb") as out:
        proc = subprocess.Popen(
            [str(BIN / "ray"), "start", *args], env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True
        )
    try:
        status = proc.wait(timeout=START_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        _kill_session(proc.pid)
        pytest.fail(
            f"`ray start {' '.join(args[:2])}` did not finish in {START_TIMEOUT_S} s: {log.read_text()[-3000:]}"
        )
    if status != 0:
        _kill_session(proc.pid)
        pytest.fail(f"`ray start {' '.join(args[:2])}` failed ({status}): {log.read_text()[-3000:]}")
    return proc.pid


@pytest.fixture(scope="module")
def ray_cluster() -> Iterator[Cluster]:
    """``ray start --head`` plus a worker node (one CPU each, small object stores, loopback address); torn down
    by killing both nodes' sessions, whatever the tests did."""
    pytest.importorskip("ray")
    if not sys.platform.startswith("linux") or not (BIN / "ray").exists():
        pytest.skip("needs Linux (/proc) and the `ray` command next to this Python")
    temp_dir = Path(tempfile.mkdtemp(prefix="sbray-", dir="/tmp"))  # short: Ray's socket paths must fit 107 bytes
    token = temp_dir / "token"
    token.write_text(secrets.token_hex(32))
    env = bench_env()  # tests/bench on PYTHONPATH: the plugin is importable on every node, as a user installs it
    env.pop("RAY_ADDRESS", None)
    env.update(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN_PATH=str(token), RAY_USAGE_STATS_ENABLED="0", OMP_NUM_THREADS="1")
    env.pop("RAY_AUTH_TOKEN", None)
    common = [*NODE_FLAGS.split(), "--object-store-memory", str(80 * 2**20)]
    sids: list[int] = []
    try:
        ports = _free_ports(len(HEAD_PORTS) + len(WORKER_PORTS))  # all at once: the two nodes share none
        head = _port_flags(HEAD_PORTS, ports[: len(HEAD_PORTS)])
        worker = _port_flags(WORKER_PORTS, ports[len(HEAD_PORTS) :])
        head_args = ["--head", "--temp-dir", str(temp_dir), "--include-dashboard=false", *head, *common]
        sids.append(_ray_start(head_args, env, temp_dir / "head.log"))
        address = f"127.0.0.1:{head[1]}"  # head[0] is "--port"
        sids.append(_ray_start(["--address", address, *worker, *common], env, temp_dir / "worker.log"))
        yield Cluster(address, env, sids[0], sids[1], temp_dir)
    finally:
        for sid in reversed(sids):
            _kill_session(sid)
        shutil.rmtree(temp_dir, ignore_errors=True)


def _steer_bench(*args: str) -> list[str]:
    script = BIN / "steer-bench"
    return [str(script), *args] if script.exists() else [sys.executable, "-m", "steer_envs.bench", *args]


def _selftest_on(address: str, out: Path) -> list[str]:
    """``steer-bench run selftest`` on the Ray cluster at ``address``, into ``out``."""
    ray = ("--executor", "ray", "--address", address)
    return _steer_bench("run", "selftest", *ray, "--out", str(out), "--no-progress")


def _toy_run(out: Path, *extra: str) -> list[str]:
    return _steer_bench(
        "run",
        "toy",
        "--plugin",
        PLUGIN,
        "--seeds",
        str(SEEDS),
        "--param",
        f"sleep={SLEEP}",
        "--out",
        str(out),
        "--no-progress",
        *extra,
    )


def _result_lines(out: Path) -> list[dict[str, Any]]:
    path = out / "results.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def _finish(proc: subprocess.Popen[str], what: str) -> str:
    try:
        _, err = proc.communicate(timeout=RUN_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
        pytest.fail(f"{what} did not finish in {RUN_TIMEOUT_S} s: {err[-3000:]}")
    assert proc.returncode == 0, f"{what} exited {proc.returncode}: {err[-3000:]}"
    return err


@pytest.mark.slow
def test_a_run_survives_losing_a_node_and_matches_a_local_run(ray_cluster, tmp_path, capsys):
    planned = 2 * 2 * SEEDS
    ray_out, local_out = tmp_path / "ray", tmp_path / "local"
    local = subprocess.Popen(
        _toy_run(local_out), env=ray_cluster.env, text=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    run = subprocess.Popen(
        _toy_run(ray_out, "--executor", "ray", "--address", ray_cluster.address),
        env=ray_cluster.env,
        text=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        # kill the worker node once a few trials are recorded and it is running one of them
        deadline = time.monotonic() + RUN_TIMEOUT_S
        while True:
            before = len(_result_lines(ray_out))
            busy = [t for t in _session_processes(ray_cluster.worker_sid).values() if t == "ray::execute_trial"]
            if before >= 4 and busy:
                break
            if run.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"the worker node ran no trial while {before} finished: {run.communicate()[1][-3000:]}")
            time.sleep(0.05)
        killed = _kill_session(ray_cluster.worker_sid)
        before = len(_result_lines(ray_out))  # finished before the node died (the driver has written them)
        assert any(t.endswith("/raylet") for t in killed.values()), killed
        in_flight = sum(t == "ray::execute_trial" for t in killed.values())
        err = _finish(run, "the Ray run")
        _finish(local, "the local run")
    finally:
        for proc in (run, local):
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    records = _result_lines(ray_out)
    keys = [r["key"] for r in records]
    assert len(keys) == len(set(keys)) == planned, (
        f"lost or duplicated trials: {len(keys)} lines, {len(set(keys))} keys"
    )
    assert not (ray_out / "failures.jsonl").exists(), (ray_out / "failures.jsonl").read_text()[-3000:]
    assert {r["executor"] for r in records} == {"ray"}
    assert f"{planned} trials planned: 0 already done, {planned} run now, 0 failed" in err
    local_records = {r["key"]: (r["metrics"], r["extra"]) for r in _result_lines(local_out)}
    assert {r["key"]: (r["metrics"], r["extra"]) for r in records} == local_records
    with capsys.disabled():
        print(
            f"\ntwo-node Ray run of {planned} trials: {before} finished before the worker node was killed "
            f"({in_flight} in flight on it, {len(killed)} processes killed), {planned - before} after, on the "
            "head alone; exit 0, no trial lost or duplicated, results equal the local run's"
        )


@pytest.mark.slow
def test_a_driver_without_the_clusters_token_exits_2_with_a_hint(ray_cluster, tmp_path):
    env = dict(ray_cluster.env)
    wrong = tmp_path / "wrong-token"
    wrong.write_text(secrets.token_hex(32))
    env["RAY_AUTH_TOKEN_PATH"] = str(wrong)
    started = time.monotonic()
    proc = subprocess.run(
        _selftest_on(ray_cluster.address, tmp_path / "o"),
        env=env,
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
    )
    last = proc.stderr.strip().splitlines()[-1]
    assert proc.returncode == 2, proc.stderr[-3000:]
    assert last.startswith(f"steer-bench: error: cannot start the Ray cluster at {ray_cluster.address}"), last
    assert "RAY_AUTH_MODE=token" in last and time.monotonic() - started < 120
    results = tmp_path / "o" / "results.jsonl"
    assert not results.exists() or results.stat().st_size == 0  # nothing ran


@pytest.mark.slow
def test_an_address_where_no_ray_head_listens_exits_2_within_a_minute(tmp_path):
    pytest.importorskip("ray")
    with socket.socket() as server:  # accepts connections, speaks no Ray: ray.init alone would retry for minutes
        server.bind(("", 0))
        server.listen(64)
        address = f"127.0.0.1:{server.getsockname()[1]}"
        started = time.monotonic()
        proc = subprocess.run(
            _selftest_on(address, tmp_path / "o"),
            env=bench_env(),
            capture_output=True,
            text=True,
            timeout=RUN_TIMEOUT_S,
        )
        elapsed = time.monotonic() - started
    last = proc.stderr.strip().splitlines()[-1]
    assert proc.returncode == 2, proc.stderr[-3000:]
    assert last.startswith(f"steer-bench: error: cannot start the Ray cluster at {address}"), last
    assert "--port PORT" in last and elapsed < 90, (elapsed, last)
