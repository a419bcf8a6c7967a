"""run_suite: records, resume, failures, interruption; executors give identical results."""

from __future__ import annotations

import sys
from collections.abc import Iterator, Sequence

import numpy as np
import pytest

from steer_envs.bench.executors import (
    Executor,
    Outcome,
    ProcessPoolExecutor,
    SequentialExecutor,
    execute_trial,
    make_executor,
)
from steer_envs.bench.records import read_jsonl
from steer_envs.bench.runner import run_suite
from steer_envs.bench.store import FAILURES_FILE
from steer_envs.bench.suite import Trial


def _values(records: Sequence[dict]) -> dict[str, float]:
    return {r["key"]: r["metrics"]["value"] for r in records}


def test_run_writes_one_complete_record_per_trial(tmp_path, toy_suite):
    summary = run_suite(toy_suite, tmp_path, progress=False)
    assert summary.ok and summary.planned == summary.completed == 8 and summary.skipped == 0
    records, report = read_jsonl(tmp_path / "results.jsonl")
    assert report.clean and len(records) == 8 and len({r["key"] for r in records}) == 8
    rec = records[0]
    assert set(rec) >= {"key", "config", "seed", "metrics", "timings", "versions", "host", "executor", "fn"}
    assert set(rec["versions"]) >= {"python", "numpy", "gymnasium", "steer_envs", "git_commit"}
    assert rec["timings"]["wall_s"] >= 0 and rec["metrics"]["flag"] is None
    assert len(rec["extra"]["points"]) == 3
    # method b adds exactly 1 to the same seeded number
    by = {(r["config"]["env"], r["config"]["method"], r["seed"]): r["metrics"]["value"] for r in records}
    assert by[("toy/A-v0", "b", 1)] == pytest.approx(by[("toy/A-v0", "a", 1)] + 1.0)


def test_resume_skips_finished_trials_and_adds_new_seeds(tmp_path, toy_suite):
    first = run_suite(toy_suite, tmp_path, seeds=2, progress=False)
    again = run_suite(toy_suite, tmp_path, seeds=2, progress=False)
    assert again.completed == 0 and again.skipped == 8
    more = run_suite(toy_suite, tmp_path, seeds=3, progress=False)
    assert more.completed == 4 and more.skipped == 8
    records, _ = read_jsonl(tmp_path / "results.jsonl")
    assert len(records) == 12 == len({r["key"] for r in records})
    assert _values(first.records).items() <= _values(records).items()  # nothing rewritten


def test_failed_trials_are_logged_and_rerun_on_resume(tmp_path, toy_suite):
    flag = tmp_path / "fail.flag"
    flag.write_text("x")
    out = tmp_path / "out"
    params = {"fail_flag": str(flag)}
    failed = run_suite(toy_suite, out, envs=["toy/A-v0"], params=params, progress=False)
    assert not failed.ok and failed.completed == 0 and len(failed.failures) == 4
    assert "fail flag" in failed.failures[0].error
    assert len(read_jsonl(out / FAILURES_FILE, key=None)[0]) == 4
    flag.unlink()
    fixed = run_suite(toy_suite, out, envs=["toy/A-v0"], params=params, progress=False)
    assert fixed.ok and fixed.completed == 4 and fixed.skipped == 0


def test_undeclared_metric_is_a_failure(tmp_path, toy_suite):
    summary = run_suite("toy_typo", tmp_path, progress=False)
    assert summary.completed == 0 and "undeclared metrics ['valu']" in summary.failures[0].error


class _InterruptAfter(Executor):
    """Runs ``n`` trials, then behaves like Ctrl-C."""

    def __init__(self, n: int) -> None:
        self.n = n

    def map(self, trials: Sequence[Trial]) -> Iterator[Outcome]:
        for i, trial in enumerate(trials):
            if i == self.n:
                raise KeyboardInterrupt
            yield execute_trial(trial)


def test_interrupt_keeps_finished_trials(tmp_path, toy_suite):
    summary = run_suite(toy_suite, tmp_path, executor=_InterruptAfter(3), progress=False)
    assert summary.interrupted and summary.completed == 3
    resumed = run_suite(toy_suite, tmp_path, progress=False)
    assert resumed.skipped == 3 and resumed.completed == 5


def test_execute_trial_turns_exceptions_into_outcomes(tmp_path, toy_suite):
    flag = tmp_path / "f"
    flag.touch()
    trial = Trial("toy", "toy/A-v0", "a", 0, {"scale": 1.0, "sleep": 0.0, "fail_flag": str(flag)}, toy_suite.fn)
    outcome = execute_trial(trial)
    assert not outcome.ok and outcome.error.startswith("RuntimeError: fail flag")


def test_make_executor_choices_and_validation():
    assert isinstance(make_executor("local"), SequentialExecutor)
    assert isinstance(make_executor("local", 1), SequentialExecutor)
    assert isinstance(make_executor("local", 3), ProcessPoolExecutor)
    with pytest.raises(ValueError, match="executor must be one of"):
        make_executor("dask")
    with pytest.raises(ValueError, match="workers must be a positive int"):
        make_executor("local", 0)
    with pytest.raises(ValueError, match="only used by the ray executor"):
        make_executor("local", 1, address="auto")


def test_missing_ray_gives_an_actionable_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # makes `import ray` raise ImportError
    with pytest.raises(ImportError, match=r'pip install "steer-envs\[ray\]"'):
        make_executor("ray", 1)


def test_process_pool_gives_the_same_results_as_sequential(tmp_path, toy_suite):
    seq = run_suite(toy_suite, tmp_path / "seq", seeds=2, progress=False)
    pool = run_suite(toy_suite, tmp_path / "pool", seeds=2, workers=2, progress=False)
    assert pool.ok and {r["executor"] for r in pool.records} == {"process"}
    assert _values(pool.records) == _values(seq.records)
    assert len({r["host"]["pid"] for r in pool.records} - {r["host"]["pid"] for r in seq.records}) >= 1


def test_ray_gives_the_same_results_as_sequential(tmp_path):
    pytest.importorskip("ray")
    seq = run_suite("selftest", tmp_path / "seq", seeds=3, params={"samples": 2000}, progress=False)
    ray_run = run_suite(
        "selftest", tmp_path / "ray", seeds=3, params={"samples": 2000}, executor="ray", workers=1, progress=False
    )
    assert ray_run.ok and ray_run.completed == 6 and {r["executor"] for r in ray_run.records} == {"ray"}
    pis = {r["key"]: r["metrics"]["pi"] for r in seq.records}
    assert {r["key"]: r["metrics"]["pi"] for r in ray_run.records} == pis
    import ray

    assert not ray.is_initialized()  # the executor shut down the instance it started


FAULT_ERRORS = {
    "raise": "ValueError: this trial raises on purpose",
    "exit": "SystemExit: 3",
    "nonjson": "the trial's result is not JSON",
    "nan": "metric 'value' is nan",
    "complex": "metric 'value' must be a real number or None, got complex (1+2j)",
    "text": "metric 'value' must be a real number or None, got str",
}


def test_a_trial_that_fails_in_any_way_is_recorded_and_the_run_goes_on(tmp_path, toy_suite):
    methods = ["ok", *FAULT_ERRORS]
    summary = run_suite("toy_faults", tmp_path, methods=methods, progress=False)
    assert summary.completed == 2 and {r["config"]["method"] for r in summary.records} == {"ok"}
    errors = {f.trial.method: f.error for f in summary.failures}
    assert set(errors) == set(FAULT_ERRORS) and len(summary.failures) == 2 * len(FAULT_ERRORS)
    for method, message in FAULT_ERRORS.items():
        assert message in errors[method], (method, errors[method])
    logged = read_jsonl(tmp_path / FAILURES_FILE, key=None)[0]
    assert len(logged) == len(summary.failures) and all(r["error"] for r in logged)
    again = run_suite("toy_faults", tmp_path, methods=methods, progress=False)
    assert again.skipped == 2 and len(again.failures) == len(summary.failures)  # failures are re-run


def test_a_worker_that_dies_fails_its_trials_and_the_pool_goes_on(tmp_path, toy_suite):
    summary = run_suite("toy_faults", tmp_path, methods=["ok", "die"], seeds=2, workers=2, progress=False)
    assert summary.completed + len(summary.failures) == summary.planned == 4
    failed = {(f.trial.method, f.trial.seed) for f in summary.failures}
    assert {("die", 0), ("die", 1)} <= failed
    assert all("BrokenProcessPool" in f.error for f in summary.failures)
    resumed = run_suite("toy_faults", tmp_path, methods=["ok"], seeds=2, progress=False)
    assert resumed.ok and {r["seed"] for r in resumed.records} == {0, 1}


def test_metrics_accept_numbers_bools_and_one_element_arrays():
    from steer_envs.bench.executors import _as_metric

    assert _as_metric("m", True) == 1.0 and _as_metric("m", np.float32(0.5)) == 0.5
    assert _as_metric("m", np.array([2.0])) == 2.0 and _as_metric("m", None) is None
    assert _as_metric("m", 3) == 3.0
    with pytest.raises(TypeError, match="got ndarray"):
        _as_metric("m", np.zeros(3))
    with pytest.raises(ValueError, match="finite number"):
        _as_metric("m", 10**400)


def test_run_suite_argument_errors(tmp_path, toy_suite):
    with pytest.raises(TypeError, match="envs must be a list of names"):
        run_suite(toy_suite, tmp_path, envs="toy/A-v0", progress=False)
    with pytest.raises(ValueError, match="seeds\\[1\\] must be an int in \\[0, inf\\]"):
        run_suite(toy_suite, tmp_path, seeds=[0, -1], progress=False)
    with pytest.raises(ValueError, match="seeds must be distinct"):
        run_suite(toy_suite, tmp_path, seeds=[1, 1], progress=False)
    with pytest.raises(TypeError, match="seeds must be an int count or a sequence"):
        run_suite(toy_suite, tmp_path, seeds="3", progress=False)
    with pytest.raises(TypeError, match="progress must be True, False or None"):
        run_suite(toy_suite, tmp_path, progress="no")
    with pytest.raises(TypeError, match="params must be a mapping"):
        run_suite(toy_suite, tmp_path, params=[("scale", 2)], progress=False)
    with pytest.raises(ValueError, match="at most 100000 trials per run"):
        run_suite(toy_suite, tmp_path, seeds=50_000, progress=False)  # 2 envs x 2 methods x 50000
    with pytest.raises(ValueError, match="must not be empty"):
        run_suite(toy_suite, "", progress=False)
    assert not (tmp_path / "results.jsonl").exists()


class _NeverRun(Executor):
    """An executor that must not be touched: a run with nothing to do starts nothing."""

    name = "never"

    def start(self) -> None:
        raise AssertionError("started")

    def map(self, trials: Sequence[Trial]) -> Iterator[Outcome]:
        raise AssertionError(f"asked to run {len(trials)} trials")


def test_all_done_starts_no_executor_and_fresh_starts_over(tmp_path, toy_suite):
    first = run_suite(toy_suite, tmp_path, progress=False)
    assert not first.all_done and first.previous is None
    again = run_suite(toy_suite, tmp_path, progress=False, executor=_NeverRun())
    assert again.all_done and again.ok and (again.skipped, again.completed) == (8, 0)
    assert _values(again.records) == _values(first.records)
    fresh = run_suite(toy_suite, tmp_path, progress=False, fresh=True)
    assert not fresh.all_done and (fresh.skipped, fresh.completed) == (0, 8)
    assert fresh.previous is not None and fresh.previous.parent == tmp_path / "previous"
    assert _values(read_jsonl(fresh.previous / "results.jsonl")[0]) == _values(first.records)
    assert _values(fresh.records) == _values(first.records)  # trials are pure functions of config and seed
    assert any(note.startswith("started over (fresh): moved the earlier results (8 trials;") for note in fresh.notes)
    with pytest.raises(TypeError, match="fresh must be a bool"):
        run_suite(toy_suite, tmp_path, progress=False, fresh="yes")


def test_ray_executor_with_no_trials_does_not_start_ray(monkeypatch):
    import types

    from steer_envs.bench.executors import RayExecutor

    def boom(**kwargs: object) -> None:
        raise AssertionError("ray.init called")

    monkeypatch.setitem(sys.modules, "ray", types.SimpleNamespace(is_initialized=lambda: False, init=boom))
    assert list(RayExecutor(workers=1).map([])) == []
