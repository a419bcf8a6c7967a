"""``itps-maze2d``: skipped until the checkpoints exist; Table 2.1 metrics and plots with an exact test policy."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")
diffusers = pytest.importorskip("diffusers")

from stub_policies import Corridor  # noqa: E402

from steer_envs.bench.executors import execute_trial  # noqa: E402
from steer_envs.bench.runner import build_request, plan_trials  # noqa: E402
from steer_envs.bench.suite import Trial, get_suite  # noqa: E402
from steer_envs.bench.suites.itps import suite as suites_itps  # noqa: E402
from steer_envs.bench.suites.itps.plots import plot_itps  # noqa: E402

LOADER = f"{__name__}:load_test_policy"
FAST = {"dp_loader": LOADER, "act_loader": LOADER, "batch": 8, "plot_seeds": 1}


def _corridor() -> Corridor:
    """Exact diffusion policy: straight plans 4 long from the agent along the four grid directions."""
    return Corridor(horizon=16, length=4.0)


class SamplerOnly:
    """An ACT-like policy: only ``sample`` (no denoiser to steer)."""

    def __init__(self, inner: Corridor) -> None:
        self.inner = inner
        self.horizon, self.action_dim, self.exec_start = inner.horizon, inner.action_dim, 0

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        return self.inner.sample(obs, n, generator=generator)


def load_test_policy(kind: str) -> Any:
    return _corridor() if kind == "dp" else SamplerOnly(_corridor())


def load_sampler_only(kind: str) -> Any:
    return SamplerOnly(_corridor())


def missing_checkpoint(kind: str) -> Any:
    raise FileNotFoundError(f"no {kind} checkpoint")


@pytest.fixture
def suite() -> Any:
    return get_suite("itps-maze2d")


def test_methods_are_skipped_with_a_note_while_policies_are_missing(suite: Any) -> None:
    params = {"dp_loader": "steer_envs.no_such_module:load_pretrained", "act_loader": f"{__name__}:missing_checkpoint"}
    plan = plan_trials(suite, build_request(suite, seeds=2, params=params))
    assert plan.trials == ()
    assert any("DP methods" in n and "ModuleNotFoundError" in n for n in plan.notes)
    assert any("ACT methods" in n and "no act checkpoint" in n for n in plan.notes)
    only_act = plan_trials(suite, build_request(suite, methods=["ACT-PR"], seeds=1, params={"act_loader": LOADER}))
    assert [t.method for t in only_act.trials] == ["ACT-PR"]


def test_a_dp_without_a_denoiser_runs_only_rs_pr_op(suite: Any) -> None:
    params = {"dp_loader": f"{__name__}:load_sampler_only", "act_loader": LOADER}
    plan = plan_trials(suite, build_request(suite, seeds=1, params=params))
    assert {t.method for t in plan.trials} == {"DP-RS", "DP-PR", "DP-OP", "ACT-RS", "ACT-PR", "ACT-OP"}
    assert sum("does not expose its denoiser" in n for n in plan.notes) == 3


def test_trials_report_table_2_1_metrics_on_shared_scenes(suite: Any, tmp_path: Path) -> None:
    plan = plan_trials(suite, build_request(suite, seeds=2, params=FAST))
    assert len(plan.trials) == 2 * len(suites_itps.METHODS)
    records = []
    for trial in plan.trials:
        outcome = execute_trial(trial)
        assert outcome.ok, outcome.error
        records.append(outcome.record)
    by = {(r["config"]["method"], r["seed"]): r for r in records}
    for seed in (0, 1):
        rs, pr = by["DP-RS", seed]["metrics"], by["DP-PR", seed]["metrics"]
        assert rs["avg_l2"] == pr["avg_l2"] and pr["min_l2"] <= rs["min_l2"]  # same batch, PR picks its best
        assert (
            by["DP-SS", seed]["metrics"]["network_evals"] == 40 and by["DP-GD", seed]["metrics"]["network_evals"] == 10
        )
        assert by["DP-BI", seed]["metrics"]["network_evals"] == 6
        # a timing: measured, positive and finite (its size under load is the benchmark's business, not a test's)
        ratio = by["DP-SS", seed]["metrics"]["ss_gd_latency"]
        assert isinstance(ratio, float) and 0.0 < ratio < float("inf")
        assert by["DP-RS", seed]["metrics"]["network_evals"] is None
        starts = {tuple(by[m, seed]["extra"]["start"]) for m in suites_itps.METHODS}
        assert len(starts) == 1  # every method steers from the same start with the same sketch
        for m in suites_itps.METHODS:
            metrics = by[m, seed]["metrics"]
            if not m.endswith("RS"):  # every other sampler picks the batch's closest plan
                assert 0.0 <= metrics["min_l2"] <= metrics["avg_l2"] + 1e-12
            assert 0.0 <= metrics["collision"] <= 1.0 and metrics["latency_ms"] > 0
    seed0 = [by[m, 0]["extra"] for m in suites_itps.METHODS]
    assert all(e["sketch"] == seed0[0]["sketch"] for e in seed0)
    assert np.asarray(seed0[0]["plans"]).shape == (8, 15, 2)  # executed waypoints (exec_start = 1)
    assert "plans" not in by["DP-RS", 1]["extra"]  # only the first plot_seeds trials keep their plans
    assert by["DP-OP", 0]["extra"]["perturbed_state"] is not None

    written = plot_itps(suite, records, str(tmp_path))
    assert sorted(Path(p).name for p in written) == ["itps-maze2d_qualitative.png", "itps-maze2d_tradeoff.png"]
    assert all(Path(p).stat().st_size > 10_000 for p in written)


def test_references_and_quick_settings(suite: Any) -> None:
    refs = suite.references_for(suites_itps.ENV_ID, "DP-SS")
    assert {k: v.value for k, v in refs.items()} == {"min_l2": 0.10, "avg_l2": 0.12, "collision": 0.01}
    assert suite.references_for(suites_itps.ENV_ID, "ACT-OP")["collision"].value == 0.35
    assert suite.quick is not None and suite.default_seeds == 100 and suite.defaults.batch == 32
    with pytest.raises(ValueError, match="unknown method"):
        suites_itps.split_method("DP-XX")
    with pytest.raises(ValueError, match="batch"):
        plan_trials(suite, build_request(suite, params={**FAST, "batch": 0}))
    trial = Trial(suite.name, suites_itps.ENV_ID, "ACT-OP", 0, {**suite.defaults.to_json(), **FAST}, suite.fn)
    assert execute_trial(trial).record["metrics"]["collision"] >= 0.0  # type: ignore[index]


def _tiny_dp_checkpoint(folder: Path) -> Path:
    """An untrained tiny Maze2D DP saved in ``folder`` (a stand-in for a trained checkpoint file)."""
    from steer_envs.baselines.diffusion.modeling import DiffusionConfig, DiffusionPolicy

    tiny = DiffusionConfig(
        obs_dim=2, action_dim=2, horizon=16, down_dims=(8, 16), step_embed_dim=16, kernel_size=3, obs_embed_dim=16
    )
    bounds = {"min": [0.5, 0.5], "max": [7.5, 10.5]}
    return DiffusionPolicy(tiny, {"observation": bounds, "action": bounds}).save(folder / "dp.safetensors")


def test_a_checkpoint_file_replaces_the_shipped_policy(suite: Any, tmp_path: Path) -> None:
    """--param dp_checkpoint=FILE runs the suite on another trained checkpoint (e.g. a GPU run)."""
    path = _tiny_dp_checkpoint(tmp_path)
    params = {**FAST, "dp_loader": "steer_envs.no_such_module:f", "dp_checkpoint": str(path)}
    plan = plan_trials(suite, build_request(suite, methods=["DP-GD"], seeds=1, params=params))
    outcome = execute_trial(plan.trials[0])
    assert outcome.ok, outcome.error
    assert np.asarray(outcome.record["extra"]["plans"]).shape == (8, 15, 2)  # the tiny net's horizon, not 64
    with pytest.raises(ValueError, match="no checkpoint file"):
        plan_trials(suite, build_request(suite, methods=["DP-GD"], seeds=1, params={**params, "dp_checkpoint": "x"}))


def test_dp_accelerate_reaches_the_policy_with_the_same_plans(suite: Any, tmp_path: Path) -> None:
    """--param dp_accelerate=trace: the DP's denoiser is traced; plans and metrics as in eager mode."""
    from steer_envs.baselines.pretrained import shared_policy

    path = _tiny_dp_checkpoint(tmp_path)
    base = {**FAST, "dp_checkpoint": str(path)}
    records = {}
    for mode in ("none", "trace"):
        params = {**base, "dp_accelerate": mode}
        assert shared_policy("dp", str(path), mode, loader=LOADER).acceleration == mode
        plan = plan_trials(suite, build_request(suite, methods=["DP-SS"], seeds=1, params=params))
        outcome = execute_trial(plan.trials[0])
        assert outcome.ok, outcome.error
        records[mode] = outcome.record
    fast, eager = records["trace"], records["none"]
    np.testing.assert_allclose(fast["extra"]["plans"], eager["extra"]["plans"], atol=1e-3)  # stored to 3 decimals
    for metric in ("min_l2", "avg_l2", "collision"):
        assert fast["metrics"][metric] == pytest.approx(eager["metrics"][metric], abs=1e-6)
    assert fast["metrics"]["latency_ms"] > 0 and fast["metrics"]["ss_gd_latency"] > 0
    with pytest.raises(ValueError, match="dp_accelerate"):
        plan_trials(suite, build_request(suite, params={**base, "dp_accelerate": "jit"}))
    with pytest.raises(TypeError, match="accelerate"):  # the exact test policy has no accelerate method
        plan_trials(suite, build_request(suite, methods=["DP-RS"], params={**FAST, "dp_accelerate": "trace"}))


def test_dp_accelerate_openvino_runs_the_ss_benchmark(suite: Any, tmp_path: Path) -> None:
    """--param dp_accelerate=openvino: a DP-SS trial with its GD benchmark, in OpenVINO's precision here."""
    pytest.importorskip("openvino")
    path = _tiny_dp_checkpoint(tmp_path)
    params = {**FAST, "dp_checkpoint": str(path), "dp_accelerate": "openvino"}
    plan = plan_trials(suite, build_request(suite, methods=["DP-SS"], seeds=1, params=params))
    outcome = execute_trial(plan.trials[0])
    assert outcome.ok, outcome.error
    metrics = outcome.record["metrics"]
    assert 0.0 <= metrics["collision"] <= 1.0 and metrics["min_l2"] <= metrics["avg_l2"]
    assert metrics["latency_ms"] > 0 and metrics["ss_gd_latency"] > 0 and metrics["network_evals"] == 40


def _summary_record(method: str, seed: int, min_l2: float, avg_l2: float, collision: float) -> dict[str, Any]:
    metrics = {"min_l2": min_l2, "avg_l2": avg_l2, "collision": collision}
    config = {"suite": "itps-maze2d", "env": suites_itps.ENV_ID, "method": method, "params": {}}
    return {"config": config, "seed": seed, "metrics": metrics, "key": f"{method}-{seed}"}


def test_findings_check_table_2_1_claims() -> None:
    """The report checks Table 2.1's claims: thesis-like numbers pass; BI colliding less than SS fails two."""
    from steer_envs.bench.report import render, render_markdown, summarize

    def verdicts(table_2_1: dict[str, tuple[float, float, float]]) -> list[bool | None]:
        records = [_summary_record(m, s, *v) for m, v in table_2_1.items() for s in (0, 1)]
        (table,) = summarize(records)
        return [f.holds for f in table.findings]

    thesis = {m: suites_itps.TABLE_2_1[m] for m in suites_itps.METHODS if m.startswith("DP")}
    assert verdicts(thesis) == [True, True, True, True]
    measured = {  # an itps-maze2d run where BI collides less than SS and SS sits 0.025 above RS
        "DP-RS": (0.247, 0.234, 0.295),
        "DP-PR": (0.095, 0.234, 0.295),
        "DP-OP": (0.128, 0.282, 0.375),
        "DP-BI": (0.061, 0.085, 0.235),
        "DP-GD": (0.054, 0.126, 0.452),
        "DP-SS": (0.048, 0.059, 0.320),
    }
    assert verdicts(measured) == [True, False, False, True]
    partial = [_summary_record("DP-SS", 0, 0.1, 0.1, 0.0)]
    (table,) = summarize(partial)
    assert [f.holds for f in table.findings] == [None] * 4
    assert "finding not checked: SS has the best" in render_markdown([table])
    (table,) = summarize([_summary_record(m, 0, *v) for m, v in measured.items()])
    md = render_markdown([table])
    # one seed of the suite's 100: the verdicts print as not judged, with the way they lean
    assert "finding FAILS" not in md
    need = "1 of the 100 seeds it needs"
    assert f"finding not judged ({need}; on these it fails): GD and BI collide more than SS (GD 0.452" in md
    assert f"finding not judged ({need}; on these it holds): PR improves Min L2 over RS but not Avg L2" in md
    findings = json.loads(render([table], "json"))["findings"]
    assert [f["holds"] for f in findings] == [True, False, False, True] and findings[0]["suite"] == "itps-maze2d"
    assert not any(f["judged"] for f in findings)
    (full,) = summarize([_summary_record(m, s, *v) for m, v in measured.items() for s in range(100)])
    assert "finding FAILS: GD and BI collide more than SS" in render_markdown([full])
