"""sb3 suite: declaration, tiny sac and sac-her trials end to end (with resume), findings, the figure, bad params."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("stable_baselines3")

from bench_helpers import check_figures

from steer_envs.baselines.sb3 import GOAL_ENVS
from steer_envs.bench.executors import execute_trial
from steer_envs.bench.report import summarize
from steer_envs.bench.runner import build_request, plan_trials
from steer_envs.bench.suite import BUILTIN_SUITE_MODULES, Trial, get_suite
from steer_envs.bench.suites.sb3.plots import plot_learning_curves
from steer_envs.bench.suites.sb3.suite import Sb3Params, dense_envs, sb3_findings

DENSE = [
    "SoupScoopDense",
    "ConvexModeDense",
    "CookingDense",
    "InspectionLineDense",
    "PolygonNav-3ModeDense",
    "PolygonNav-4ModeDense",
    "PolygonNav-5ModeDense",
    "Maze2D-UmazeDense",
    "Maze2D-MediumDense",
    "Maze2D-LargeDense",
]


def _trial(env: str, method: str, **overrides: Any) -> Trial:
    suite = get_suite("sb3")
    return suite.trial(f"steer_envs/{env}-v0", method, 0, suite.resolve_params(overrides))


def test_declaration_and_plan() -> None:
    assert "steer_envs.bench.suites.sb3.suite" in BUILTIN_SUITE_MODULES
    suite = get_suite("sb3")
    envs = dense_envs()  # from the registry: a new 2D env's dense id joins by itself
    assert {f"steer_envs/{e}-v0" for e in DENSE} <= set(envs)
    assert all(e.endswith("Dense-v0") and not e.endswith("GoalDense-v0") for e in envs)
    assert suite.env_list() == [*dense_envs(), *GOAL_ENVS] and suite.method_list() == ["sac", "sac-her"]
    assert suite.quick is None and suite.default_seeds == 1
    plan = plan_trials(suite, build_request(suite))
    pairs = [(t.env, t.method) for t in plan.trials]
    assert pairs == [(e, "sac") for e in dense_envs()] + [("steer_envs/Maze2D-UmazeGoal-v0", "sac-her")]
    assert plan.notes  # the pairs that do not fit are said, not silently dropped
    with pytest.raises(ValueError, match="no env fits"):
        plan_trials(suite, build_request(suite, envs=["SoupScoopDense-v0"], methods=["sac-her"]))


def test_tiny_trials_resume_findings_and_figure(tmp_path: Path, saved: list[Any]) -> None:
    fast = {"eval_episodes": 2, "cache_dir": str(tmp_path / "cache")}
    sac = execute_trial(_trial("PolygonNav-3ModeDense", "sac", timesteps=200, eval_every=100, **fast))
    assert sac.ok, sac.error
    m, extra = sac.record["metrics"], sac.record["extra"]
    assert m["timesteps"] == 200 and 0 <= m["success"] <= 100 and m["steps_per_s"] > 0
    assert [p[0] for p in extra["curve"]] == [0, 100, 200] and extra["resumed_from"] == 0
    # a longer budget continues the finished trial's checkpoint
    longer = execute_trial(_trial("PolygonNav-3ModeDense", "sac", timesteps=300, eval_every=100, **fast))
    assert longer.ok, longer.error
    assert longer.record["extra"]["resumed_from"] == 200
    assert [p[0] for p in longer.record["extra"]["curve"]] == [0, 100, 200, 300]
    # HER needs a finished episode before it samples: learning starts after Umaze's 300-step limit
    her = execute_trial(_trial("Maze2D-UmazeGoal", "sac-her", timesteps=320, eval_every=320, checkpoint=False, **fast))
    assert her.ok, her.error
    assert her.record["extra"]["learning_starts"] == 300 and her.record["metrics"]["timesteps"] == 320
    maze = execute_trial(_trial("Maze2D-UmazeDense", "sac", timesteps=120, eval_every=120, checkpoint=False, **fast))
    assert maze.ok, maze.error
    assert maze.record["extra"]["train_env"] == "steer_envs/Maze2D-UmazeGoalDense-v0"
    (table,) = summarize([sac.record, her.record])
    sac_holds, her_holds = (f.holds for f in table.findings)
    assert sac_holds is None and her_holds in (None, True)  # cut short of the budgets: no failure verdict
    records = [sac.record, her.record, maze.record]
    paths = plot_learning_curves(get_suite("sb3"), records, str(tmp_path), methods=("sac", "sac-her"), target=80.0)
    assert [Path(p).name for p in paths] == ["sb3_learning_curves.png"] and Path(paths[0]).is_file()
    check_figures(saved, 1)


def _record(env: str, method: str, success: float, timesteps: float) -> dict[str, Any]:
    return {
        "config": {"suite": "sb3", "env": env, "method": method, "params": {}},
        "seed": 0,
        "metrics": {"success": success, "timesteps": timesteps},
    }


def test_findings_on_a_synthetic_table() -> None:
    def verdicts(records: list[dict[str, Any]]) -> list[bool | None]:
        (table,) = summarize(records)
        return [f.holds for f in sb3_findings(table)]

    good = [_record(e, "sac", 90.0, 100_000) for e in dense_envs()]
    her = _record(GOAL_ENVS[0], "sac-her", 85.0, 50_000)
    assert verdicts([*good, her]) == [True, True]
    miss = [*good[:-1], _record(dense_envs()[-1], "sac", 40.0, 100_000)]
    assert verdicts([*miss, _record(GOAL_ENVS[0], "sac-her", 10.0, 50_000)]) == [False, False]
    assert verdicts(good[:3]) == [None, None]  # every measured env made it, the others did not run
    assert verdicts([*good[:2], _record(dense_envs()[2], "sac", 0.0, 100_000)])[0] is False
    assert verdicts([_record(GOAL_ENVS[0], "sac-her", 95.0, 200_000)])[1] is None  # past the budget: no verdict
    assert verdicts([_record(GOAL_ENVS[0], "sac-her", 50.0, 20_000)])[1] is None  # cut short below 80: no verdict
    assert verdicts([_record(GOAL_ENVS[0], "sac-her", 85.0, 20_000)])[1] is True  # stopped early at 80 %


@pytest.mark.parametrize(
    "overrides",
    [
        {"timesteps": 0},
        {"eval_episodes": 0},
        {"eval_every": 0},
        {"threads": 0},
        {"stop_success": 120.0},
        {"timesteps": "many"},
        {"normalize_actions": "yes"},
        {"max_episode_steps": -1},
    ],
)
def test_bad_parameters_are_refused(overrides: dict[str, Any]) -> None:
    with pytest.raises(ValueError):
        get_suite("sb3").resolve_params(overrides)


def test_params_make_the_library_settings(tmp_path: Path) -> None:
    settings = Sb3Params(timesteps=500, cache_dir=str(tmp_path), stop_success=80.0).settings("sac")
    assert (settings.timesteps, settings.cache, settings.stop_success) == (500, tmp_path, 80.0)
    assert Sb3Params().settings("sac-her").timesteps == 50_000
    with pytest.raises(ValueError, match="method"):
        Sb3Params().budget("ppo")
