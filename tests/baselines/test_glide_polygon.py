"""GLiDE on PolygonNav end to end: a quick learning check, and the thesis reproductions (slow)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from steer_envs.baselines.glide import (
    POLYGON_ENV_IDS,
    GlideSetup,
    GlideTrainConfig,
    evaluate_polygon_policy,
    grounding_scores,
    learn_grounding,
    make_polygon_policy,
)


def grounding_trial(env_id: str, layout: int, variant: str, seed: int, **kwargs: Any) -> dict[str, Any]:
    """The scores of one variant's grounding on the grid, with its training info."""
    grounding = learn_grounding(env_id, layout, variant, seed, **kwargs)
    scores, _ = grounding_scores(env_id, layout, grounding.predictor)
    return {**scores, **grounding.info}


def success_rate(env_id: str, method: str, perturbed: bool, seed: int, **kwargs: Any) -> float:
    """One method's success rate over 1000 episodes of 1000 steps on layout 0."""
    policy, _ = make_polygon_policy(method, env_id, 0, seed, **kwargs)
    res = evaluate_polygon_policy(policy, env_id, 0, n_rollouts=1000, perturbed=perturbed, seed=seed, max_steps=1000)
    return float(res["success_rate"])


def test_small_run_learns_the_polygon_chain_better_than_the_baselines(tmp_path: object) -> None:
    """Less data, short training: loose but clear learning progress on 3-mode layout 0."""
    setup = GlideSetup(n_success=300, n_failure=300, train=GlideTrainConfig(epochs=800, n_heads=2))
    env_id = "steer_envs/PolygonNav-3Mode-v0"
    full = grounding_trial(env_id, 0, "full", 0, setup=setup, cache_dir=tmp_path)
    km = grounding_trial(env_id, 0, "kmeans", 0, setup=setup)
    # a short run does not reach the reproduction's numbers (slow test below), but it must find both
    # polygons and beat similarity-based segmentation clearly
    assert full["mean_iou"] > km["mean_iou"] + 0.15, (full, km)
    assert full["iou"][1] > 0.1 and full["iou"][2] > 0.1, full
    assert full["overlap"] > km["overlap"] + 0.2
    # the cached classifier gives the same answer without retraining
    again = grounding_trial(env_id, 0, "full", 0, setup=setup, cache_dir=tmp_path)
    assert again["overlap"] == full["overlap"] and again.get("cached") is True
    # a corrupt cache entry (a torn copy, a disk error) is a miss: rebuilt, same answer, no crash
    cached = sorted(Path(str(tmp_path)).glob("*.safetensors")) + sorted(Path(str(tmp_path)).glob("*.npz"))
    assert len(cached) == 2, cached
    for path in cached:
        path.write_bytes(path.read_bytes()[:100])
    with pytest.warns(RuntimeWarning, match="cached"):
        rebuilt = grounding_trial(env_id, 0, "full", 0, setup=setup, cache_dir=tmp_path)
    assert rebuilt["overlap"] == full["overlap"] and not rebuilt.get("cached")


@pytest.mark.slow
@pytest.mark.parametrize("env_id", POLYGON_ENV_IDS)
def test_full_loss_overlap_reaches_095_and_ablations_are_worse(env_id: str, tmp_path: object) -> None:
    """Issue 6 'done when': mean overlap over 5 layouts >= 0.95; every ablation measurably worse.

    "Worse" is read on both grid metrics: a lower mean overlap, and a mean IoU at least 0.05 lower.
    The IoU is what can show a missed mode: the one-mode-short plan (``wrong_feasibility``) can lose
    at most the goal polygon's share of the grid in overlap (under 1 % on the 5-mode layouts).
    """
    results: dict[str, list[dict]] = {}
    for variant in ("full", "no_counterfactuals", "wrong_feasibility", "no_prediction_loss", "kmeans"):
        results[variant] = [grounding_trial(env_id, layout, variant, 0, cache_dir=tmp_path) for layout in range(5)]

    def mean(variant: str, metric: str) -> float:
        return float(np.mean([r[metric] for r in results[variant]]))

    summary = {v: (mean(v, "overlap"), mean(v, "mean_iou")) for v in results}
    assert mean("full", "overlap") >= 0.95, summary
    for variant in results:
        if variant != "full":
            assert mean(variant, "overlap") < mean("full", "overlap"), (variant, summary)
            assert mean(variant, "mean_iou") < mean("full", "mean_iou") - 0.05, (variant, summary)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", POLYGON_ENV_IDS)
def test_glide_planning_beats_bc_under_perturbations(env_id: str, tmp_path: object) -> None:
    """Issue 6 'done when' as glide-polygon checks it: GLiDE+Planning >= 0.98 with and without perturbations
    (mean over 3 training seeds, 1000-step episodes), above BC perturbed."""
    setup = GlideSetup()
    plan = {
        p: np.mean([success_rate(env_id, "glide_planning", p, s, setup=setup, cache_dir=tmp_path) for s in range(3)])
        for p in (False, True)
    }
    bc = success_rate(env_id, "bc", True, 0, setup=setup)
    assert plan[False] >= 0.98 and plan[True] >= 0.98, plan
    assert plan[True] > bc
