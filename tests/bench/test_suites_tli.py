"""The TLI suites: declarations, tiny trials end to end, the figure data and the plot hooks."""

from __future__ import annotations

import json

import numpy as np
import pytest
from bench_helpers import suite_trial

from steer_envs.bench.executors import execute_trial
from steer_envs.bench.runner import build_request, plan_trials
from steer_envs.bench.suite import BUILTIN_SUITE_MODULES, get_suite
from steer_envs.bench.suites.tli.plots import plot_scoop, plot_single_mode, single_mode_figure_data
from steer_envs.bench.suites.tli.protocol import THESIS_SUCCESS, single_mode_trial
from steer_envs.bench.suites.tli.suite import THESIS_SINGLE_MODE

PNG = b"\x89PNG\r\n\x1a\n"


def test_suites_are_declared_with_the_thesis_numbers() -> None:
    assert "steer_envs.bench.suites.tli.suite" in BUILTIN_SUITE_MODULES
    single = get_suite("tli-single-mode")
    assert single.method_list() == ["bc", "bc+mod", "ds", "ds+mod"] and single.default_seeds == 50
    assert dict(THESIS_SINGLE_MODE) == {k: tuple(v) for k, v in THESIS_SUCCESS.items()}
    refs = single.references_for("steer_envs/ConvexMode-v0", "ds+mod")
    assert {k: r.value for k, r in refs.items()} == {
        "success_0": 100.0,
        "success_5": 100.0,
        "success_30": 100.0,
        "cuts_30": 4.0,
    }
    assert single.references_for("steer_envs/ConvexMode-v0", "bc")["success_5"].value == 72.4
    assert len(plan_trials(single, build_request(single)).trials) == 4 * 50
    scoop = get_suite("tli-scoop")
    assert scoop.method_list() == ["ltl-ds", "ltl-ds+mod"] and scoop.default_seeds == 10
    assert scoop.references_for("steer_envs/SoupScoop-v0", "ltl-ds+mod")["success"].value == 100.0
    assert "success" not in scoop.references_for("steer_envs/SoupScoop-v0", "ltl-ds")
    for s in (single, scoop, get_suite("tli-ds-fit")):
        assert s.quick is not None


def test_single_mode_trial_end_to_end_with_plot(tmp_path) -> None:
    outcome = execute_trial(suite_trial("tli-single-mode", "ds+mod", 0, n_starts=12, max_cuts=2))
    assert outcome.ok, outcome.error
    rec = outcome.record
    m = rec["metrics"]
    assert m["success_0"] == 100.0 and 0 <= m["success_30"] <= 100.0
    assert m["cuts_30"] is not None and 0 <= m["cuts_30"] <= 2
    assert rec["extra"]["per_noise"]["30"]["num_cuts"] == m["cuts_30"]
    figure = rec["extra"]["figure"]
    assert set(figure) == {"0.0", "1.0", "5.0"}
    assert figure["5.0"]["success_rate"] * 100 == pytest.approx(m["success_30"])  # the plot shows the trial
    json.dumps(rec, allow_nan=False)
    bc = execute_trial(suite_trial("tli-single-mode", "bc", 1, n_starts=10, bc_epochs=20, plot_seeds=0))
    assert bc.ok, bc.error
    assert bc.record["metrics"]["cuts_30"] is None and "figure" not in bc.record.get("extra", {})
    paths = plot_single_mode(get_suite("tli-single-mode"), [rec, bc.record], str(tmp_path))
    assert [p.endswith("tli-single-mode_rollouts_layout0.png") for p in paths] == [True]
    assert open(paths[0], "rb").read(8) == PNG
    bad = execute_trial(suite_trial("tli-single-mode", "dmp", 0))
    assert not bad.ok and "unknown method" in (bad.error or "")


def test_figure_data_reproduces_the_protocol() -> None:
    """The plot's rollouts are the trial's: same success rate and cuts as single_mode_trial."""
    res = single_mode_trial(0, 5.0, "ds+mod", n_starts=30, seed=0)
    fig = single_mode_figure_data(0, 5.0, "ds+mod", res["n_demos"], n_starts=30, seed=0, n_paths=10, every=50)
    assert fig["success_rate"] == res["success_rate"] and fig["num_cuts"] == res["num_cuts"]
    assert np.asarray(fig["paths"]).shape == (10, 1000 // 50 + 1, 2)
    assert len(fig["cut_points"]) == res["num_cuts"] == len(fig["cuts"])
    assert len(fig["failures"]) == sum(fig["left"])
    with pytest.raises(ValueError, match="policy_kind"):
        single_mode_figure_data(0, 1.0, "mlp", 1)


def test_scoop_trials_and_plot(tmp_path) -> None:
    records = []
    for method in ("ltl-ds", "ltl-ds+mod"):
        outcome = execute_trial(suite_trial("tli-scoop", method, 0, n_perturbations=2, max_steps=2500, plot_seeds=1))
        assert outcome.ok, outcome.error
        m = outcome.record["metrics"]
        assert m["success"] in (0.0, 100.0) and m["pushes"] <= 2 and m["steps"] <= 2500
        assert (m["num_cuts"] == 0) if method == "ltl-ds" else (m["num_cuts"] <= m["loops"])
        assert outcome.record["extra"]["figure"]["segments"]
        records.append(outcome.record)
    paths = plot_scoop(get_suite("tli-scoop"), records, str(tmp_path))
    assert len(paths) == 1 and open(paths[0], "rb").read(8) == PNG
    assert plot_scoop(get_suite("tli-scoop"), [], str(tmp_path)) == []


def test_ds_fit_timing_trial() -> None:
    outcome = execute_trial(suite_trial("tli-ds-fit", None, 0))
    assert outcome.ok, outcome.error
    m = outcome.record["metrics"]
    assert 0 < m["fit_seconds"] < 5.0  # the metric's goal
    assert m["worst_margin"] < 0 and m["n_components"] >= 1


@pytest.mark.slow
def test_single_mode_reproduction_ordering() -> None:
    """The Done-when ordering on 10 layouts: BC <= BC+mod, DS <= DS+mod (strict at 30 %); DS 100 % at noise 0."""
    run = get_suite("tli-single-mode").run_trial
    assert run is not None
    mean: dict[str, dict[str, float]] = {}
    for method in ("bc", "bc+mod", "ds", "ds+mod"):
        ms = [run(suite_trial("tli-single-mode", method, seed, plot_seeds=0)).metrics for seed in range(10)]
        mean[method] = {k: float(np.mean([m[k] for m in ms])) for k in ("success_0", "success_5", "success_30")}
    for level in ("success_5", "success_30"):
        assert mean["bc"][level] <= mean["bc+mod"][level]
        assert mean["ds"][level] <= mean["ds+mod"][level]
    assert mean["ds"]["success_30"] < mean["ds+mod"]["success_30"]
    assert mean["ds"]["success_0"] == 100.0 and mean["ds+mod"]["success_0"] == 100.0
    assert mean["ds+mod"]["success_30"] >= 97.0


def test_single_mode_findings_check_fig_3_5_claims() -> None:
    from steer_envs.bench.report import Table, render_markdown, summarize
    from steer_envs.bench.suites.tli.suite import CONVEX_ENV

    def table(success: dict[str, tuple[float, float, float]]) -> Table:
        records = [
            {
                "config": {"suite": "tli-single-mode", "env": CONVEX_ENV, "method": m, "params": {}},
                "seed": 0,
                "metrics": {"success_0": v[0], "success_5": v[1], "success_30": v[2]},
                "key": m,
            }
            for m, v in success.items()
        ]
        (out,) = summarize(records)
        return out

    assert [f.holds for f in table(dict(THESIS_SINGLE_MODE)).findings] == [True, True, True]
    worse = {**THESIS_SINGLE_MODE, "ds+mod": (100.0, 96.0, 99.8)}
    assert [f.holds for f in table(worse).findings] == [True, False, False]
    md = render_markdown([table(worse)])
    assert "on these it fails): DS+mod succeeds from every start at every noise level (ds+mod 100.0/96.0/99.8)" in md
    partial = {"bc": THESIS_SINGLE_MODE["bc"]}
    assert [f.holds for f in table(partial).findings] == [None, None, None]
