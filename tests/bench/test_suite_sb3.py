"""sb3 suite: declaration, tiny sac / ppo / sac-her trials end to end (with resume), findings, figure, bad params."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("stable_baselines3")

from bench_helpers import check_figures

from steer_envs.baselines.sb3 import GOAL_ENVS, Sb3Run
from steer_envs.bench.executors import execute_trial
from steer_envs.bench.report import summarize
from steer_envs.bench.runner import build_request, plan_trials
from steer_envs.bench.suite import BUILTIN_SUITE_MODULES, Trial, get_suite
from steer_envs.bench.suites.sb3.plots import learning_curves, plot_learning_curves
from steer_envs.bench.suites.sb3.suite import Sb3Params, dense_envs, reached_within_budget, sb3_findings

DENSE = [
    "SoupScoopDense",
    "ConvexModeDense",
    "ColorTracingDense",
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
    assert {f"steer_envs/{e}-v0" for e in DENSE} <= set(envs) and len(envs) == 11
    assert all(e.endswith("Dense-v0") and not e.endswith("GoalDense-v0") for e in envs)
    assert suite.env_list() == [*dense_envs(), *GOAL_ENVS] and suite.method_list() == ["sac", "ppo", "sac-her"]
    assert suite.quick is None and suite.default_seeds == 5
    plan = plan_trials(suite, build_request(suite))
    trials = [(t.env, t.method, t.seed) for t in plan.trials]
    expected = [(e, m, s) for e in dense_envs() for m in ("sac", "ppo") for s in range(5)]
    assert trials == expected + [("steer_envs/Maze2D-UmazeGoal-v0", "sac-her", s) for s in range(5)]
    # each id as registered: no env option is set by the suite's defaults
    params = plan.trials[0].params
    assert params["normalize_actions"] is None and params["observe_sensors"] is None
    assert params["maze_goal_obs"] is False
    assert plan.notes  # the pairs that do not fit are said, not silently dropped
    with pytest.raises(ValueError, match="no env fits"):
        plan_trials(suite, build_request(suite, envs=["SoupScoopDense-v0"], methods=["sac-her"]))


def test_tiny_trials_resume_findings_and_figure(tmp_path: Path, saved: list[Any]) -> None:
    fast = {"eval_episodes": 2, "cache_dir": str(tmp_path / "cache")}
    short = {**fast, "max_episode_steps": 50}  # short evaluation episodes on PolygonNav
    sac = execute_trial(_trial("PolygonNav-3ModeDense", "sac", timesteps=200, eval_every=100, **short))
    assert sac.ok, sac.error
    m, extra = sac.record["metrics"], sac.record["extra"]
    assert m["timesteps"] == 200 and 0 <= m["success"] <= 100 and m["steps_per_s"] > 0
    assert m["reached_80"] is None  # cut short of the 100k budget below 80 %: no verdict
    assert [p[0] for p in extra["curve"]] == [0, 100, 200] and extra["resumed_from"] == 0
    assert extra["train_env"] == "steer_envs/PolygonNav-3ModeDense-v0"
    # a longer budget continues the finished trial's checkpoint
    longer = execute_trial(_trial("PolygonNav-3ModeDense", "sac", timesteps=300, eval_every=100, **short))
    assert longer.ok, longer.error
    assert longer.record["extra"]["resumed_from"] == 200
    assert [p[0] for p in longer.record["extra"]["curve"]] == [0, 100, 200, 300]
    # PPO learns in whole 2048-step rollouts: it evaluates after the rollout that crosses a multiple of eval_every
    ppo = execute_trial(_trial("PolygonNav-3ModeDense", "ppo", timesteps=100, eval_every=100, **short))
    assert ppo.ok, ppo.error
    assert ppo.record["metrics"]["timesteps"] == 2048 and ppo.record["extra"]["learning_starts"] == 0
    assert [p[0] for p in ppo.record["extra"]["curve"]] == [0, 2048]
    ((folder, *_),) = [list((tmp_path / "cache").glob("PolygonNav-3ModeDense-v0-ppo-seed0-*"))]
    assert sorted(p.name for p in (folder / "checkpoint").iterdir()) == ["model.zip", "state.json"]  # no buffer
    again = execute_trial(_trial("PolygonNav-3ModeDense", "ppo", timesteps=100, eval_every=100, **short))
    assert again.ok and again.record["extra"]["resumed_from"] == 2048  # finished: its checkpoint, not a new run
    assert again.record["extra"]["curve"] == ppo.record["extra"]["curve"]
    # HER needs a finished episode before it samples: learning starts after Umaze's 300-step limit
    her = execute_trial(_trial("Maze2D-UmazeGoal", "sac-her", timesteps=320, eval_every=320, checkpoint=False, **fast))
    assert her.ok, her.error
    assert her.record["extra"]["learning_starts"] == 300 and her.record["metrics"]["timesteps"] == 320
    maze = execute_trial(_trial("Maze2D-UmazeDense", "sac", timesteps=120, eval_every=120, checkpoint=False, **fast))
    assert maze.ok, maze.error
    assert maze.record["extra"]["train_env"] == "steer_envs/Maze2D-UmazeDense-v0"  # the id as registered
    flat = _trial("Maze2D-UmazeDense", "sac", timesteps=120, eval_every=120, checkpoint=False, maze_goal_obs=True)
    goal = execute_trial(flat)
    assert goal.ok and goal.record["extra"]["train_env"] == "steer_envs/Maze2D-UmazeGoalDense-v0"
    (table,) = summarize([sac.record, her.record, ppo.record])
    sac_holds, her_holds, ppo_holds = (f.holds for f in table.findings)
    assert sac_holds is None and her_holds in (None, True)  # cut short of the budgets: no failure verdict
    assert ppo_holds is None and "PolygonNav-3ModeDense" in table.findings[2].detail  # reported, no verdict
    records = [sac.record, her.record, maze.record, ppo.record]
    paths = plot_learning_curves(get_suite("sb3"), records, str(tmp_path), methods=("sac", "sac-her"), target=80.0)
    assert [Path(p).name for p in paths] == ["sb3_learning_curves.png"] and Path(paths[0]).is_file()
    check_figures(saved, 1)
    fig = saved[0]
    titles = [ax.get_title() for ax in fig.axes if ax.get_visible()]
    assert titles == [
        "PolygonNav-3ModeDense-v0 (1 seed)",
        "Maze2D-UmazeDense-v0 (1 seed)",
        "Maze2D-UmazeGoal-v0 (1 seed)",
    ]
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend[:3] == ["SAC (SB3 defaults)", "SAC + HER", "PPO (SB3 defaults)"]  # methods first, then the rest


def test_learning_curves_band_spans_the_seeds() -> None:
    def rec(seed: int, method: str, curve: list[list[float]]) -> dict[str, Any]:
        return {"config": {"env": "steer_envs/X-v0", "method": method}, "seed": seed, "extra": {"curve": curve}}

    records = [
        rec(0, "sac", [[0, 0.0], [10, 100.0], [20, 100.0]]),
        rec(1, "sac", [[0, 10.0], [10, 40.0], [20, 80.0]]),
        rec(2, "sac", [[0, 20.0], [10, 100.0]]),  # stopped early: the band narrows to the seeds left
        rec(0, "ppo", [[0, 0.0], [2048, 5.0]]),
    ]
    curves = learning_curves(records)
    sac = curves["sac"]["steer_envs/X-v0"]
    assert sac.steps.tolist() == [0, 10, 20] and sac.seeds.tolist() == [3, 3, 2]
    assert sac.low.tolist() == [0.0, 40.0, 80.0] and sac.high.tolist() == [20.0, 100.0, 100.0]
    assert sac.mean.tolist() == pytest.approx([10.0, 80.0, 90.0])
    assert curves["ppo"]["steer_envs/X-v0"].steps.tolist() == [0, 2048]


def _record(env: str, method: str, success: float, timesteps: float, seed: int = 0) -> dict[str, Any]:
    reached = 1.0 if success >= 80 else (0.0 if timesteps >= 100_000 else None)
    return {
        "config": {"suite": "sb3", "env": env, "method": method, "params": {}},
        "seed": seed,
        "metrics": {"success": success, "timesteps": timesteps, "reached_80": reached},
    }


def _seeds(env: str, successes: list[float], timesteps: float = 100_000, method: str = "sac") -> list[dict[str, Any]]:
    return [_record(env, method, s, timesteps, seed) for seed, s in enumerate(successes)]


def test_findings_on_a_synthetic_table() -> None:
    def verdicts(records: list[dict[str, Any]]) -> list[bool | None]:
        (table,) = summarize(records)
        return [f.holds for f in sb3_findings(table)]

    envs = dense_envs()
    good = [r for e in envs for r in _seeds(e, [90.0, 100.0, 85.0, 95.0, 40.0])]  # 4 of 5 seeds each
    her = _record(GOAL_ENVS[0], "sac-her", 85.0, 50_000)
    assert verdicts([*good, her]) == [True, True, None]
    (table,) = summarize([*good, her])
    assert "PolygonNav-3ModeDense-v0 4/5" in table.findings[0].detail
    # one env with 2 of 5 seeds below 80 % at the budget fails the claim
    miss = [r for r in good if r["config"]["env"] != envs[-1]] + _seeds(envs[-1], [90.0, 90.0, 90.0, 10.0, 0.0])
    assert verdicts([*miss, _record(GOAL_ENVS[0], "sac-her", 10.0, 50_000)])[:2] == [False, False]
    assert verdicts(good[:15])[0] is None  # every measured env made it, the others did not run
    assert verdicts(_seeds(envs[0], [90.0, 90.0, 90.0]))[0] is None  # 3 of 3 seeds: too few to judge
    assert verdicts(_seeds(envs[0], [90.0, 10.0, 0.0]))[0] is False  # 2 seeds missed: 4 of 5 is out of reach
    cut = [*good[:-5], *_seeds(envs[-1], [90.0, 90.0, 90.0, 10.0, 0.0], timesteps=20_000)]
    assert verdicts(cut)[0] is None  # cut short below 80 %: no verdict, not a failure
    assert verdicts([_record(GOAL_ENVS[0], "sac-her", 95.0, 200_000)])[1] is None  # past the budget: no verdict
    assert verdicts([_record(GOAL_ENVS[0], "sac-her", 50.0, 20_000)])[1] is None  # cut short below 80: no verdict
    assert verdicts([_record(GOAL_ENVS[0], "sac-her", 85.0, 20_000)])[1] is True  # stopped early at 80 %
    # PPO is reported whatever it reached, never judged
    ppo = _seeds(envs[0], [0.0, 0.0, 100.0, 0.0, 0.0], method="ppo")
    (table,) = summarize([*good, *ppo])
    finding = table.findings[2]
    assert finding.holds is None and finding.detail.startswith(
        "SoupScoopDense-v0 1/5 seeds, final 20 % (min 0, max 100)"
    )


def test_reached_within_budget_reads_the_curve() -> None:
    def run(curve: list[list[float]], timesteps: int, unit: int = 1) -> Sb3Run:
        return Sb3Run(curve, timesteps, 1.0, 1.0, "x", 0, 0, False, "2", step_unit=unit)

    assert reached_within_budget(run([[0, 0.0], [100_000, 80.0]], 100_000), 100_000) == 1.0
    assert reached_within_budget(run([[0, 0.0], [100_000, 79.0], [110_000, 95.0]], 110_000), 100_000) == 0.0
    assert reached_within_budget(run([[0, 0.0], [50_000, 90.0]], 50_000), 100_000) == 1.0  # stopped early at 80 %
    assert reached_within_budget(run([[0, 0.0], [50_000, 10.0]], 50_000), 100_000) is None  # cut short
    # PPO's last evaluation comes after the rollout that crosses the budget: it counts
    assert reached_within_budget(run([[0, 0.0], [100_352, 90.0]], 100_352, unit=2048), 100_000) == 1.0


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
        {"observe_sensors": 1},
        {"max_episode_steps": -1},
    ],
)
def test_bad_parameters_are_refused(overrides: dict[str, Any]) -> None:
    with pytest.raises(ValueError):
        get_suite("sb3").resolve_params(overrides)


def test_params_make_the_library_settings(tmp_path: Path) -> None:
    settings = Sb3Params(timesteps=500, cache_dir=str(tmp_path), stop_success=80.0).settings("sac")
    assert (settings.timesteps, settings.cache, settings.stop_success) == (500, tmp_path, 80.0)
    assert (settings.normalize_actions, settings.observe_sensors) == (None, None)  # the ids' registered values
    assert Sb3Params().settings("sac-her").timesteps == 50_000 and Sb3Params().settings("ppo").timesteps == 100_000
    explicit = get_suite("sb3").resolve_params({"observe_sensors": False}).settings("ppo")
    assert explicit.observe_sensors is False
    with pytest.raises(ValueError, match="method"):
        Sb3Params().budget("a2c")
