"""tli-color-tracing: declaration, tiny trials end to end per automaton, findings, the figure, bad input."""

from __future__ import annotations

import json
from functools import partial
from typing import Any

import numpy as np
import pytest
from bench_helpers import suite_trial

from steer_envs.baselines.lpv_ds.task_policies import ReentryFlow, color_policy, fit_tile_dynamics
from steer_envs.bench.executors import execute_trial
from steer_envs.bench.plots import figure_problems
from steer_envs.bench.report import summarize
from steer_envs.bench.suite import BUILTIN_SUITE_MODULES, get_suite
from steer_envs.bench.suites.tli_color_tracing.params import ColorTracingParams
from steer_envs.bench.suites.tli_color_tracing.plots import plot_color_tracing
from steer_envs.bench.suites.tli_color_tracing.protocol import color_trial
from steer_envs.data.pushes import tile_push_schedule
from steer_envs.envs.color_tracing import REENTRY, TILES

PNG = b"\x89PNG\r\n\x1a\n"


_trial = partial(suite_trial, "tli-color-tracing")


def test_suite_is_registered_with_quick_settings() -> None:
    assert "steer_envs.bench.suites.tli_color_tracing.suite" in BUILTIN_SUITE_MODULES
    suite = get_suite("tli-color-tracing")
    assert suite.method_list() == ["a", "b", "c"] and suite.quick is not None
    assert {(r.metric, r.method) for r in suite.references} >= {("success", "a"), ("reentry_ok", "c")}


def test_tile_dynamics_are_fitted_once_and_shared_by_every_automaton() -> None:
    dyn = fit_tile_dynamics(0)
    assert set(dyn) == set(TILES) and dyn["red"].source == "pink"  # red reuses pink's DS
    a, c = color_policy(0, "a"), color_policy(0, "c")
    assert a.dynamics["blue"].policy is c.dynamics["blue"].policy  # the same DS, no retraining
    assert a.dynamics["dark2"].policy.tile == "yellow" and c.dynamics["dark2"].policy.tile == "pink"


def test_trials_end_to_end_with_findings_and_figure(tmp_path, saved: list[Any]) -> None:
    records = []
    for method in ("a", "b", "c"):
        out = execute_trial(_trial(method, 0, n_episodes=1, n_pushes=2))
        assert out.ok, out.error
        m = out.record["metrics"]
        assert m["success_clean"] == 100.0 and m["success"] == 100.0 and 0 < m["pushes"] <= 2.0
        assert m["reentry_ok"] == 100.0 and m["tracked_ok"] == 100.0 and m["replans"] >= 2.0
        for push in out.record["extra"]["pushes"]:  # each push re-entered where the automaton says
            assert push["reentered"] == REENTRY[method][push["env_mode"]] == push["expected"]
        records.append(out.record)
    json.dumps(records, allow_nan=False)
    (table,) = summarize(records)
    assert [f.holds for f in table.findings] == [True] * 5
    paths = plot_color_tracing(get_suite("tli-color-tracing"), records, str(tmp_path))
    assert len(paths) == 1 and open(paths[0], "rb").read(8) == PNG
    assert len(saved) == 1 and figure_problems(saved[0]) == []
    assert plot_color_tracing(None, [], str(tmp_path)) == []


def test_missing_automata_leave_their_findings_open() -> None:
    out = execute_trial(_trial("a", 0, n_episodes=1, n_pushes=1, plot_seeds=0))
    assert out.ok, out.error
    assert "figure" not in out.record["extra"]
    (table,) = summarize([out.record])
    assert [f.holds for f in table.findings] == [True, None, None, None, None]


def test_bad_input_names_the_argument() -> None:
    bad = execute_trial(_trial("d", 0))
    assert not bad.ok and "unknown method" in (bad.error or "")
    with pytest.raises(ValueError, match="automaton"):
        color_trial(0, "x", ColorTracingParams())
    with pytest.raises(TypeError, match="seed"):
        color_trial("0", "a", ColorTracingParams())  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="tile"):
        ReentryFlow("purple")
    with pytest.raises(ValueError, match="n_episodes"):
        get_suite("tli-color-tracing").resolve_params({"n_episodes": 0})
    schedule = tile_push_schedule(np.random.default_rng(0), 5, 3)
    assert {t for t, _ in schedule} == set(TILES[:-1]) and all(1 <= d <= 3 for _, d in schedule)
    assert len(tile_push_schedule(np.random.default_rng(0), 7, 3)) == 7
    with pytest.raises(ValueError, match="max_dwell"):
        tile_push_schedule(np.random.default_rng(0), 2, 0)
