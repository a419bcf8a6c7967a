"""The GLiDE suites: declarations, tiny end-to-end runs through the runner, report and figure."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from steer_envs.bench.report import render_markdown, summarize
from steer_envs.bench.runner import build_request, plan_trials, run_suite
from steer_envs.bench.suite import BUILTIN_SUITE_MODULES, Trial, get_suite
from steer_envs.bench.suites.glide.suite import (
    ENV_IDS,
    EVAL_STARTS,
    FREE_SPACE_PLANNERS,
    METHODS,
    THESIS_TABLE_4_1,
    VARIANTS,
    run_grounding_trial,
)

PNG = b"\x89PNG\r\n\x1a\n"
ENV3 = "steer_envs/PolygonNav-3Mode-v0"
#: a tiny GLiDE setup: a few demos and replays, a few epochs
TINY = {"n_demos": 3, "n_success": 8, "n_failure": 8, "epochs": 5, "n_heads": 1}


def test_suites_are_declared_with_the_thesis_numbers() -> None:
    from steer_envs.baselines import glide

    assert "steer_envs.bench.suites.glide.suite" in BUILTIN_SUITE_MODULES
    grounding = get_suite("glide-polygon-grounding")
    assert grounding.env_list() == list(ENV_IDS) == list(glide.POLYGON_ENV_IDS)
    assert grounding.method_list() == list(VARIANTS) == list(glide.POLYGON_VARIANTS)
    assert grounding.default_seeds == 5  # the target is a mean over 5 layouts
    assert plan_trials(grounding, build_request(grounding)).trials.__len__() == 3 * 5 * 5
    assert grounding.references_for(ENV3, "full")["overlap"].value == 0.95
    assert "overlap" not in grounding.references_for(ENV3, "kmeans")
    assert grounding.metric("train_seconds").goal == 120.0

    table = get_suite("glide-polygon")
    assert list(THESIS_TABLE_4_1) == list(METHODS) == list(glide.POLYGON_METHODS)
    assert EVAL_STARTS == glide.EVAL_STARTS  # kept twice so the suite imports no torch
    assert FREE_SPACE_PLANNERS == glide.FREE_SPACE_PLANNERS
    refs = table.references_for("steer_envs/PolygonNav-4Mode-v0", "glide_planning")
    assert (refs["success"].value, refs["success_perturbed"].value) == (0.987, 0.966)
    assert table.references_for("steer_envs/PolygonNav-5Mode-v0", "bc")["success_perturbed"].value == 0.596
    plan = plan_trials(table, build_request(table))
    per_method = {m: sum(t.method == m for t in plan.trials) for m in METHODS}
    assert per_method == {"bc": 3 * 10, "glide_bc": 3 * 3, "glide_planning": 3 * 3}  # BC: 10 seeds, as the thesis
    assert {t.params["n_rollouts"] for t in plan.trials} == {1000}
    explicit = plan_trials(table, build_request(table, methods=["bc", "glide_planning"], seeds=[3, 4], trials=7))
    assert sorted((t.method, t.seed) for t in explicit.trials if t.env == ENV3) == [
        ("bc", 3),
        ("bc", 4),
        ("glide_planning", 3),
        ("glide_planning", 4),
    ]
    with pytest.raises(ValueError, match="bc_seeds"):
        plan_trials(table, build_request(table, params={"bc_seeds": 0}))
    with pytest.raises(ValueError, match="n_success"):
        plan_trials(table, build_request(table, params={"n_success": 0}))


def test_grounding_suite_runs_tiny_through_the_runner_with_report_and_figure(tmp_path: Path) -> None:
    params = {**TINY, "grid_resolution": 24, "cache_dir": str(tmp_path / "cache"), "plot_seeds": 1}
    summary = run_suite(
        "glide-polygon-grounding", tmp_path / "run", envs=[ENV3], seeds=[0], params=params, workers=1, progress=False
    )
    assert summary.ok, [f.error for f in summary.failures]
    assert summary.completed == len(VARIANTS)
    by = {r["config"]["method"]: r for r in summary.records}
    for variant, rec in by.items():
        m = rec["metrics"]
        assert 0.0 <= m["overlap"] <= 1.0 and 0.0 <= m["mean_iou"] <= 1.0, variant
        assert m["free_only_overlap"] > 0.5 and m["train_seconds"] >= 0.0
        assert len(rec["extra"]["iou"]) == 3
        assert len(rec["extra"]["figure"]["labels"]) == 24 * 24
    # the data set is built once (full runs first) and reused by the other variants that need it
    assert by["full"]["metrics"]["data_seconds"] > 0.0
    assert all(by[v]["metrics"]["data_seconds"] is None for v in VARIANTS if v != "full")
    assert (
        by["full"]["extra"]["n_trajectories"]
        > TINY["n_demos"]
        > by["no_counterfactuals"]["extra"]["n_trajectories"] - 1
    )

    text = render_markdown(summarize(summary.records))
    assert "glide-polygon-grounding" in text and "overlap (ref)" in text and "target (full loss)" in text
    suite = get_suite("glide-polygon-grounding")
    (figure,) = suite.figures(summary.records, str(tmp_path / "plots"))
    assert figure.endswith("glide-polygon-grounding_layout0.png")
    assert Path(figure).read_bytes()[:8] == PNG

    # the classifiers are cached: a second run elsewhere retrains nothing and measures the same overlaps
    again = run_suite(
        "glide-polygon-grounding",
        tmp_path / "run2",
        envs=[ENV3],
        methods=["full", "wrong_feasibility"],
        seeds=[0],
        params={**params, "plot_seeds": 0},
        workers=1,
        progress=False,
    )
    assert again.ok
    for rec in again.records:
        assert rec["extra"]["cached"] is True and "figure" not in rec["extra"]
        assert rec["metrics"]["overlap"] == by[rec["config"]["method"]]["metrics"]["overlap"]
        assert rec["metrics"]["train_seconds"] == by[rec["config"]["method"]]["metrics"]["train_seconds"]


def test_policy_suite_runs_tiny_through_the_runner(tmp_path: Path) -> None:
    params = {**TINY, "bc_seeds": 2, "glide_seeds": 1, "bc_steps": 5, "cache_dir": str(tmp_path / "cache")}
    summary = run_suite("glide-polygon", tmp_path, envs=[ENV3], trials=3, params=params, workers=1, progress=False)
    assert summary.ok, [f.error for f in summary.failures]
    assert sorted((r["config"]["method"], r["seed"]) for r in summary.records) == [
        ("bc", 0),
        ("bc", 1),
        ("glide_bc", 0),
        ("glide_planning", 0),
    ]
    for rec in summary.records:
        m = rec["metrics"]
        for name in ("success", "success_perturbed", "violation", "violation_perturbed", "timeout_perturbed"):
            assert m[name] in {0.0, 1 / 3, 2 / 3, 1.0}, (name, m)
        assert m["train_seconds"] > 0.0 and m["eval_seconds"] > 0.0
        assert rec["extra"]["unperturbed"]["perturbations"] == 0
    glide = [r for r in summary.records if r["config"]["method"] != "bc"]
    assert [r["extra"]["classifier_cached"] for r in glide] == [False, True]  # GLiDE+BC and +Planning share it
    text = render_markdown(summarize(summary.records))
    assert "success_perturbed (ref)" in text and "0.908" in text and "thesis Table 4.1" in text


def test_bc_from_spread_demo_starts_runs_and_bad_starts_are_refused(tmp_path: Path) -> None:
    from steer_envs.bench.suites.glide.suite import DEMO_STARTS, run_policy_trial
    from steer_envs.data.demo_starts import DEMO_STARTS as LIBRARY_DEMO_STARTS

    assert DEMO_STARTS == LIBRARY_DEMO_STARTS
    suite = get_suite("glide-polygon")
    assert suite.resolve_params({}).bc_demo_starts == "uniform"  # type: ignore[attr-defined]
    params = {**TINY, "bc_steps": 5, "n_rollouts": 2, "max_steps": 50, "bc_demo_starts": "spread"}
    params = suite.resolve_params(params).to_json()
    result = run_policy_trial(Trial(suite.name, ENV3, "bc", 0, params, suite.fn))
    assert result.metrics["success"] in {0.0, 0.5, 1.0} and result.metrics["train_seconds"] > 0.0
    with pytest.raises(ValueError, match="bc_demo_starts"):
        plan_trials(suite, build_request(suite, params={"bc_demo_starts": "edge"}))


def test_trials_reject_unknown_variants_and_envs() -> None:
    suite = get_suite("glide-polygon-grounding")
    params = suite.resolve_params(TINY).to_json()
    with pytest.raises(ValueError, match="unknown variant"):
        run_grounding_trial(Trial(suite.name, ENV3, "oracle", 0, params, suite.fn))
    with pytest.raises(ValueError, match="unknown env"):
        run_grounding_trial(Trial(suite.name, "steer_envs/PolygonNav-9Mode-v0", "full", 0, params, suite.fn))
    with pytest.raises(ValueError, match="grid_resolution"):
        run_grounding_trial(Trial(suite.name, ENV3, "full", 0, {**params, "grid_resolution": 1}, suite.fn))
    policy_suite = get_suite("glide-polygon")
    with pytest.raises(ValueError, match="free_space_planner"):
        plan_trials(policy_suite, build_request(policy_suite, params={"free_space_planner": "astar"}))
    with pytest.raises(ValueError, match="max_steps"):
        plan_trials(policy_suite, build_request(policy_suite, params={"max_steps": 0}))
    with pytest.raises(ValueError, match="start"):
        plan_trials(policy_suite, build_request(policy_suite, params={"start": "goal"}))


def _glide_record(suite: str, env: str, method: str, metrics: dict) -> dict:
    config = {"suite": suite, "env": env, "method": method, "params": {}}
    return {"config": config, "seed": 0, "metrics": metrics, "key": f"{env}-{method}"}


def test_findings_check_the_grounding_and_table_4_1_claims() -> None:
    from steer_envs.bench.report import render_markdown, summarize
    from steer_envs.bench.suites.glide.suite import ENV_IDS, VARIANTS

    def grounding(overlap_of: dict, iou_of: dict) -> list:
        records = [
            _glide_record("glide-polygon-grounding", e, v, {"overlap": overlap_of[v], "mean_iou": iou_of[v]})
            for e in ENV_IDS
            for v in VARIANTS
        ]
        (table,) = summarize(records)
        return table.findings

    overlap = {
        "full": 0.96,
        "no_counterfactuals": 0.7,
        "wrong_feasibility": 0.955,
        "no_prediction_loss": 0.7,
        "kmeans": 0.3,
    }
    iou = {"full": 0.6, "no_counterfactuals": 0.3, "wrong_feasibility": 0.5, "no_prediction_loss": 0.2, "kmeans": 0.1}
    assert [f.holds for f in grounding(overlap, iou)] == [True, True]
    close = grounding(overlap, {**iou, "wrong_feasibility": 0.58})  # within 0.05 IoU: not measurably worse
    assert [f.holds for f in close] == [True, False] and "closest: wrong_feasibility" in close[1].detail
    assert [f.holds for f in grounding({**overlap, "full": 0.94, "wrong_feasibility": 0.93}, iou)] == [False, True]

    def policy(gp: tuple[float, float], bc_perturbed: float) -> list:
        records = [
            _glide_record("glide-polygon", e, m, {"success": s, "success_perturbed": p})
            for e in ENV_IDS
            for m, (s, p) in (("bc", (0.8, bc_perturbed)), ("glide_planning", gp))
        ]
        (table,) = summarize(records)
        return table.findings

    assert [f.holds for f in policy((0.99, 0.985), 0.7)] == [True, True]
    findings = policy((0.99, 0.6), 0.7)
    assert [f.holds for f in findings] == [False, False]
    (table,) = summarize([_glide_record("glide-polygon", ENV_IDS[0], "bc", {"success": 1.0, "success_perturbed": 1.0})])
    assert "finding not checked: GLiDE+Planning beats BC" in render_markdown([table])


class _Oracle:
    """The ground-truth modes as a 'classifier'."""

    def __init__(self, model: Any) -> None:
        self.model = model

    def predict(self, states: np.ndarray) -> np.ndarray:
        return self.model.mode_of(np.asarray(states, dtype=np.float64))


def test_plot_writes_a_png_atomically(tmp_path: Path) -> None:
    import gymnasium as gym

    from steer_envs.baselines.glide import polygon_demonstrations
    from steer_envs.bench.suites.glide.plots import plot_groundings

    env = gym.make("steer_envs/PolygonNav-4Mode-v0", layout_seed=0)
    model = env.unwrapped.model  # type: ignore[attr-defined]
    env.close()
    demos = polygon_demonstrations("steer_envs/PolygonNav-4Mode-v0", 0, 2, 0)
    path = plot_groundings(
        model,
        {"oracle": _Oracle(model)},
        tmp_path / "modes.png",
        resolution=40,
        trajectories=[d.states for d in demos],
        title="PolygonNav-4Mode",
    )
    assert path.read_bytes()[:8] == PNG
    assert [p.name for p in path.parent.iterdir()] == ["modes.png"]
    with pytest.raises(ValueError, match=r"\.png"):
        plot_groundings(model, {}, tmp_path / "modes.jpg")
    with pytest.raises(TypeError, match="predict"):
        plot_groundings(model, {"x": object()}, tmp_path / "m.png")  # type: ignore[dict-item]
