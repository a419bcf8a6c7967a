"""kill -9 of a running ``steer-bench run``: workers die with it, a resume loses and repeats no trial."""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from bench_helpers import bench_env, descendants, kill_all, run_cli, wait_gone

from steer_envs.bench.runner import build_request, plan_trials
from steer_envs.bench.store import DISCARDED_FILE, RESULTS_FILE
from steer_envs.bench.suite import get_suite

SEEDS = 12
SLEEP = 0.05


def _argv(out: Path, *extra: str) -> list[str]:
    return ["run", "selftest", "--seeds", str(SEEDS), "--trials", "200", "--param", f"sleep={SLEEP}",
            "--out", str(out), "--no-progress", *extra]  # fmt: skip


def _planned_keys() -> set[str]:
    suite = get_suite("selftest")
    request = build_request(suite, seeds=SEEDS, trials=200, params={"sleep": SLEEP})
    return {t.key for t in plan_trials(suite, request).trials}


def _start(argv: list[str]) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "steer_envs.bench", *argv],
        env=bench_env(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )


def _wait_lines(proc: subprocess.Popen[bytes], results: Path, n: int, timeout: float = 60) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if results.exists() and results.read_bytes().count(b"\n") >= n:
            return
        if proc.poll() is not None:
            pytest.fail(f"run exited early ({proc.returncode}): {proc.stderr.read().decode()[-2000:]}")
        time.sleep(0.01)
    proc.kill()
    pytest.fail(f"no {n} result lines within {timeout} s")


def _kill(proc: subprocess.Popen[bytes]) -> None:
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    proc.stderr.close()


def _check_complete(results: Path, before: bytes) -> list[dict]:
    data = results.read_bytes()
    good_before = before[: before.rfind(b"\n") + 1]
    assert data.startswith(good_before), "a line written before the kill was changed"
    lines = data.split(b"\n")
    assert lines[-1] == b""
    records = [json.loads(line) for line in lines[:-1]]
    keys = [r["key"] for r in records]
    assert len(keys) == len(set(keys)), "a trial was recorded twice"
    assert set(keys) == _planned_keys(), "a trial is missing"
    return records


# ---------------------------------------------------------------- issue class 3: orphans
def test_pool_workers_and_resource_tracker_die_with_a_killed_run(tmp_path):
    out = tmp_path / "pool"
    proc = _start(_argv(out, "--workers", "2"))
    _wait_lines(proc, out / RESULTS_FILE, 2)  # both workers are up and have run trials
    children = descendants(proc.pid)
    assert len(children) >= 2, children  # two workers (+ the multiprocessing resource tracker)
    _kill(proc)
    survivors = wait_gone(children, timeout=5.0)
    kill_all(survivors)
    assert not survivors, f"processes outlived the killed run: {sorted(survivors)}"
    resumed = run_cli(*_argv(out, "--workers", "2"))
    assert resumed.returncode == 0, resumed.stderr
    assert len(_check_complete(out / RESULTS_FILE, b"")) == 2 * SEEDS


def test_the_watchdog_ends_a_worker_whose_parent_died_without_prctl(tmp_path):
    """The portable fallback alone (no PR_SET_PDEATHSIG): the worker exits once its parent is gone."""
    pid_file = tmp_path / "child.pid"
    parent_code = textwrap.dedent(
        f"""
        import os, subprocess, sys, time
        child = subprocess.Popen([sys.executable, "-c",
            "import os; from steer_envs.bench.executors import _watch_parent; "
            "open({str(pid_file)!r}, 'w').write(str(os.getpid())); _watch_parent(os.getppid(), 0.05)"])
        time.sleep(600)
        """
    )
    parent = subprocess.Popen([sys.executable, "-c", parent_code], env=bench_env())
    deadline = time.monotonic() + 30
    while not (pid_file.exists() and pid_file.read_text()) and time.monotonic() < deadline:
        time.sleep(0.02)
    child = int(pid_file.read_text())
    os.kill(parent.pid, signal.SIGKILL)
    parent.wait(timeout=10)
    survivors = wait_gone({child}, timeout=5.0)
    kill_all(survivors)
    assert not survivors


# ---------------------------------------------------------------- kill at a random moment, then resume
@pytest.mark.parametrize(
    ("workers", "seed", "damage"),
    [
        (1, 11, "torn"),
        (1, 13, "no-newline"),
        pytest.param(2, 12, "torn", marks=pytest.mark.slow),  # pool start-up is slow: more kills in tests/fuzz
        pytest.param(2, 14, "no-newline", marks=pytest.mark.slow),
    ],
)
def test_kill_at_a_random_moment_then_resume_gives_exactly_the_plan(tmp_path, workers, seed, damage):
    rng = random.Random(seed)
    out = tmp_path / "run"
    extra = ["--workers", str(workers)] if workers > 1 else []
    results = out / RESULTS_FILE
    proc = _start(_argv(out, *extra))
    _wait_lines(proc, results, 1)
    time.sleep(rng.uniform(0.0, 0.4))  # a random moment of the run
    children = descendants(proc.pid)
    _kill(proc)
    kill_all(wait_gone(children))
    before = results.read_bytes()
    done_before = before.count(b"\n")
    assert 1 <= done_before < 2 * SEEDS, "the kill must land mid-run"
    if damage == "torn":  # and a writer killed in the middle of a line
        with results.open("ab") as fh:
            fh.write(b'{"config":{"env":null,"method":"mc","par')
    elif damage == "no-newline":  # killed after a record, before its newline
        results.write_bytes(before[:-1])
    resumed = run_cli(*_argv(out, *extra))
    assert resumed.returncode == 0, resumed.stderr
    assert f"{done_before} already done, {2 * SEEDS - done_before} run now, 0 failed" in resumed.stderr
    _check_complete(results, before)
    if damage == "torn":
        assert "torn last line" in resumed.stderr
        quarantined = [json.loads(line) for line in (out / DISCARDED_FILE).read_text().splitlines()]
        assert [q["reason"] for q in quarantined] == ["torn last line"]
    elif damage == "no-newline":
        assert "newline appended" in resumed.stderr and not (out / DISCARDED_FILE).exists()
