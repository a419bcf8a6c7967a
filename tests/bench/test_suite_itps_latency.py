"""``itps-latency``: methods, parameters, the CPU note, one real trial per kind of path, and the findings."""

from __future__ import annotations

from typing import Any

import pytest

from steer_envs.bench.executors import execute_trial
from steer_envs.bench.runner import build_request, plan_trials
from steer_envs.bench.suite import get_suite
from steer_envs.bench.suites.itps_latency import suite as latency_suite


def test_methods_cover_every_path_for_rs_gd_and_ss() -> None:
    assert len(latency_suite.METHODS) == 3 * 7
    assert latency_suite.split_method("GD-openvino-bf16") == ("GD", "openvino-bf16")
    with pytest.raises(ValueError, match="unknown method 'SS-cuda'"):
        latency_suite.split_method("SS-cuda")
    for bad in ({"calls": 0}, {"batch": 0}, {"mcmc_steps": -1}, {"ddim_steps": 101}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            latency_suite.LatencyParams.from_json(bad)


@pytest.mark.parametrize("method", ["RS-eager", "SS-onnx"])
def test_a_trial_times_a_session_and_names_the_cpu(method: str) -> None:
    pytest.importorskip("onnxruntime")
    suite = get_suite("itps-latency")
    params = {"batch": 4, "calls": 2, "warmup": 1, "ddim_steps": 3, "mcmc_steps": 2}
    plan = plan_trials(suite, build_request(suite, methods=[method], seeds=1, params=params))
    assert any(note.startswith("CPU: ") and "AVX2" in note for note in plan.notes)
    (trial,) = plan.trials
    outcome = execute_trial(trial)
    assert outcome.ok, outcome.error
    m = outcome.record["metrics"]
    assert m["latency_ms"] > 0 and m["network_ms"] > 0
    assert m["latency_ms"] == pytest.approx(m["network_ms"] + m["sampler_ms"] + m["other_ms"], rel=0.3)
    if method.startswith("SS"):
        assert m["network_evals"] == 3 * 2 and m["within_target"] in (0.0, 1.0)  # DDIM steps x MCMC steps
    assert outcome.record["extra"]["acceleration"] == ("none" if method.endswith("eager") else "onnx")


class Means:
    def __init__(self, rows: dict[str, dict[str, float]]) -> None:
        self.rows = rows

    def means(self, metric: str, methods: list[str]) -> dict[str, float] | None:
        if any(m not in self.rows or metric not in self.rows[m] for m in methods):
            return None
        return {m: self.rows[m][metric] for m in methods}


def test_findings_judge_the_target_and_the_speed_up() -> None:
    fast = {"SS-fastest": {"latency_ms": 120.0, "within_target": 1.0}, "SS-eager": {"latency_ms": 900.0}}
    assert [f.holds for f in latency_suite.latency_findings(Means(fast))] == [True, True]
    slow = {"SS-fastest": {"latency_ms": 400.0, "within_target": 0.0}, "SS-eager": {"latency_ms": 300.0}}
    findings = latency_suite.latency_findings(Means(slow))
    assert [f.holds for f in findings] == [False, False] and "400 ms" in findings[0].detail
    assert [f.holds for f in latency_suite.latency_findings(Means({}))] == [None, None]


def test_steering_latency_refuses_bad_counts() -> None:
    from steer_envs.ui.latency import steering_latency

    session: Any = object()
    with pytest.raises(ValueError, match="calls"):
        steering_latency(session, None, calls=0)
    with pytest.raises(TypeError, match="warmup"):
        steering_latency(session, None, warmup=1.5)
