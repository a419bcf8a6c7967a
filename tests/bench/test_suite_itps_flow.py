"""``itps-flow-safety``: methods, skipped flow rows, a trial per policy kind, and its findings."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from steer_envs.bench.executors import execute_trial
from steer_envs.bench.runner import build_request, plan_trials
from steer_envs.bench.suite import get_suite
from steer_envs.bench.suites.itps_flow import suite as flow_suite


@pytest.fixture
def suite() -> Any:
    return get_suite("itps-flow-safety")


@pytest.fixture(scope="module")
def tiny_flow(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An untrained flow policy of Maze2D's layout: the plumbing, not the quality."""
    from steer_envs.baselines.flow import FlowConfig, FlowPolicy

    box = {"min": (0.5, 0.5), "max": (7.5, 10.5)}
    config = FlowConfig(obs_dim=2, action_dim=2, obs_indices=(0, 1), action_obs_indices=(0, 1), relative=True,
                        horizon=16, down_dims=(8, 16), obs_embed_dim=8, obs_octaves=1)  # fmt: skip
    policy = FlowPolicy(config, {"observation": box, "action": box})
    return policy.save(tmp_path_factory.mktemp("flow") / "flow.safetensors")


def test_methods_and_names() -> None:
    assert len(flow_suite.METHODS) == 2 * (6 + 5)  # RS picks at random: no RS+safe
    assert flow_suite.split_method("DP-GD+safe") == ("dp", "GD", True)
    with pytest.raises(ValueError, match="unknown method"):
        flow_suite.split_method("FLOW-RS+safe")


def test_flow_rows_are_skipped_with_a_note_without_a_checkpoint(suite: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(flow_suite, "FLOW_FILE", ("checkpoints", "maze2d_large", "no-such-flow.safetensors"))
    plan = plan_trials(suite, build_request(suite, methods=["FLOW-GD", "DP-PR"], seeds=1))
    assert [t.method for t in plan.trials] == ["DP-PR"]
    assert any("FLOW methods" in note and "train_maze_flow_checkpoint.sh" in note for note in plan.notes)


def test_flow_steps_set_the_flows_euler_steps(suite: Any, tiny_flow: Path) -> None:
    params = flow_suite.FlowSafetyParams(flow_checkpoint=str(tiny_flow), flow_steps=3)
    assert params.policy("flow").num_inference_steps == 3
    assert flow_suite.FlowSafetyParams(flow_checkpoint=str(tiny_flow)).policy("flow").num_inference_steps == 10
    with pytest.raises(ValueError, match="flow_steps"):
        flow_suite.FlowSafetyParams(flow_steps=-1)


def test_a_named_flow_file_that_is_missing_is_an_error(suite: Any, tmp_path: Path) -> None:
    params = {"flow_checkpoint": str(tmp_path / "missing.safetensors")}
    with pytest.raises(ValueError, match=r"missing\.safetensors"):
        plan_trials(suite, build_request(suite, methods=["FLOW-GD"], seeds=1, params=params))


@pytest.mark.parametrize("method", ["DP-GD+safe", "FLOW-SS+safe", "FLOW-BI"])
def test_a_trial_of_each_kind_runs(suite: Any, tiny_flow: Path, method: str) -> None:
    params = {"flow_checkpoint": str(tiny_flow), "batch": 4}
    (trial,) = plan_trials(suite, build_request(suite, methods=[method], seeds=1, params=params)).trials
    outcome = execute_trial(trial)
    assert outcome.ok, outcome.error
    metrics = outcome.record["metrics"]
    assert 0.0 <= metrics["collision"] <= 1.0 and metrics["min_l2"] >= 0.0 and metrics["latency_ms"] > 0


class Means:
    """What the findings read of a report table: per-method means (``None`` for a method or metric without a row)."""

    def __init__(self, rows: dict[str, tuple[float, float, float]]) -> None:
        self.rows = rows

    def means(self, metric: str, methods: list[str]) -> dict[str, float] | None:
        if metric not in ("min_l2", "collision", "latency_ms") or any(m not in self.rows for m in methods):
            return None
        column = ("min_l2", "collision", "latency_ms").index(metric)
        return {m: self.rows[m][column] for m in methods}


def test_findings_judge_the_safety_cost_and_the_flow_latency() -> None:
    rows = {
        "DP-GD": (0.067, 0.09, 200.0),
        "DP-GD+safe": (0.067, 0.02, 230.0),
        "DP-SS": (0.062, 0.03, 800.0),
        "DP-SS+safe": (0.075, 0.00, 900.0),
        "FLOW-SS": (0.06, 0.03, 700.0),
    }
    findings = flow_suite.flow_safety_findings(Means(rows))
    verdicts = {f.claim.split(" ")[0]: f.holds for f in findings}
    assert verdicts["DP-GD+safe"] is True and verdicts["DP-SS+safe"] is False  # SS+safe lost alignment here
    assert verdicts["FLOW-GD+safe"] is None and verdicts["the"] is True
    on_flow = [f for f in findings if f.claim.startswith("flow policy: ")]
    assert len(on_flow) == 4 and all(f.holds is None for f in on_flow)  # Table 2.1 needs every FLOW sampler
