"""tli-cooking and tli-inspection: declarations, tiny trials end to end, findings and figures."""

from __future__ import annotations

import json

import numpy as np
import pytest
from bench_helpers import suite_trial

from steer_envs.baselines.lpv_ds.transition_ds import learned_skills, skills_fingerprint
from steer_envs.bench.executors import execute_trial
from steer_envs.bench.report import summarize
from steer_envs.bench.suite import BUILTIN_SUITE_MODULES, get_suite
from steer_envs.bench.suites.tli_cooking.plots import plot_cooking
from steer_envs.bench.suites.tli_inspection.plots import plot_inspection
from steer_envs.data.pushes import push_schedule

PNG = b"\x89PNG\r\n\x1a\n"


def test_suites_are_registered_with_quick_settings() -> None:
    for module in ("tli_cooking", "tli_inspection"):
        assert f"steer_envs.bench.suites.{module}.suite" in BUILTIN_SUITE_MODULES
    cooking, inspection = get_suite("tli-cooking"), get_suite("tli-inspection")
    assert cooking.method_list() == ["phi_cb", "phi_bc", "phi_c", "phi_cc"] and cooking.quick is not None
    assert inspection.method_list() == ["vanilla-ds", "ltl-ds", "ltl-ds+mod"] and inspection.quick is not None


def test_cooking_skills_are_learned_once_and_shared() -> None:
    skills = learned_skills(0)
    assert {("w", "y"), ("y", "d"), ("w", "g"), ("g", "d")} <= set(skills)
    assert skills_fingerprint(skills) == skills_fingerprint(learned_skills(0))
    with pytest.raises(ValueError, match="window"):
        push_schedule(np.random.default_rng(0), 3, 2, 1.0)


def test_cooking_trials_end_to_end_with_findings_and_plot(tmp_path) -> None:
    records = []
    for method in ("phi_cb", "phi_cc"):
        out = execute_trial(suite_trial("tli-cooking", method, 0, n_starts=1, horizon=1500, deliveries=2))
        assert out.ok, out.error
        m = out.record["metrics"]
        assert m["success"] == 100.0 and m["invalid"] == 0.0  # unperturbed runs from the start box
        assert 0.0 <= m["success_push"] <= 100.0
        records.append(out.record)
    assert records[0]["extra"]["fingerprint"] == records[1]["extra"]["fingerprint"]  # no retraining
    assert records[1]["metrics"]["deliveries"] == 2.0
    json.dumps(records, allow_nan=False)
    (table,) = summarize(records)
    assert [f.holds for f in table.findings] == [None, None]  # phi_bc and phi_c are missing
    paths = plot_cooking(get_suite("tli-cooking"), records, str(tmp_path))
    assert len(paths) == 1 and open(paths[0], "rb").read(8) == PNG
    bad = execute_trial(suite_trial("tli-cooking", "phi_x", 0))
    assert not bad.ok and "unknown method" in (bad.error or "")


def test_inspection_trials_end_to_end_with_findings_and_plot(tmp_path) -> None:
    records = []
    for method in ("vanilla-ds", "ltl-ds+mod"):
        out = execute_trial(suite_trial("tli-inspection", method, 0, n_episodes=3))
        assert out.ok, out.error
        records.append(out.record)
    vanilla, ltl = (r["metrics"] for r in records)
    assert vanilla["reached"] == 100.0 and vanilla["uninspected"] > 0  # the attractor, but not the task
    assert ltl["success"] == 100.0 and ltl["inspections"] > 1.0  # re-inspected after the push
    (table,) = summarize(records)
    assert [f.holds for f in table.findings] == [True, True]
    paths = plot_inspection(get_suite("tli-inspection"), records, str(tmp_path))
    assert len(paths) == 1 and open(paths[0], "rb").read(8) == PNG
