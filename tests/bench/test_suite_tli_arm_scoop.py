"""tli-arm-scoop: declaration, tiny trials per method, findings, cuts bounding the scoop DS, figure, bad input."""

from __future__ import annotations

import json
from functools import partial
from typing import Any

import numpy as np
import pytest
from bench_helpers import suite_trial

from steer_envs.baselines.lpv_ds.cuts import FailureRecord, resolve_cuts
from steer_envs.baselines.lpv_ds.episodes import sampled_exits
from steer_envs.baselines.lpv_ds.ltl_ds import repeated_failures
from steer_envs.baselines.lpv_ds.task_policies import ARM_CUT_MARGIN, arm_scoop_policy
from steer_envs.bench.executors import execute_trial
from steer_envs.bench.plots import figure_problems
from steer_envs.bench.report import summarize
from steer_envs.bench.suite import BUILTIN_SUITE_MODULES, get_suite
from steer_envs.bench.suites.tli_arm_scoop.params import ArmScoopParams
from steer_envs.bench.suites.tli_arm_scoop.plots import _wrong_exit, plot_arm_scoop
from steer_envs.bench.suites.tli_arm_scoop.protocol import scoop_trial
from steer_envs.data.pushes import ARM_PUSH_MODES, ARM_PUSH_SCALE, push_plan

PNG = b"\x89PNG\r\n\x1a\n"


_trial = partial(suite_trial, "tli-arm-scoop")


def test_suite_is_registered_with_the_thesis_reference() -> None:
    assert "steer_envs.bench.suites.tli_arm_scoop.suite" in BUILTIN_SUITE_MODULES
    suite = get_suite("tli-arm-scoop")
    assert suite.method_list() == ["ltl-ds", "ltl-ds+mod"] and suite.quick is not None
    assert suite.defaults.to_json()["n_episodes"] == 30
    assert {(r.metric, r.method, r.value) for r in suite.references} == {("success", "ltl-ds+mod", 100.0)}


def test_trials_end_to_end_with_findings_and_figure(tmp_path, saved: list[Any]) -> None:
    records = []
    for method in ("ltl-ds", "ltl-ds+mod"):
        out = execute_trial(_trial(method, 0, n_episodes=1, n_pushes=1, max_steps=300))
        assert out.ok and out.record is not None, out.error
        m = out.record["metrics"]
        assert m["success"] == 100.0 and 0 < m["steps"] <= 300 and m["failures"] >= 0
        assert 0.0 <= m["sampled_exits_modulated"] <= 100.0 and m["sampled_exits_nominal"] > 0.0
        records.append(out.record)
    assert records[0]["metrics"]["num_cuts"] == 0.0  # no modulation: failures are recorded, never cut
    json.dumps(records, allow_nan=False)
    (table,) = summarize(records)
    assert len(table.findings) == 4 and table.findings[0].holds is True
    paths = plot_arm_scoop(get_suite("tli-arm-scoop"), records, str(tmp_path))
    assert len(paths) == 1 and open(paths[0], "rb").read(8) == PNG
    assert len(saved) == 1 and figure_problems(saved[0]) == []
    assert plot_arm_scoop(None, [], str(tmp_path)) == []


def test_cuts_from_invariance_failures_bound_the_scoop_dynamics() -> None:
    """Cuts through two failures of the nominal scoop DS: fewer sampled flows leave the mode (the modulation works)."""
    policy = arm_scoop_policy(0, modulation=True)
    nominal, traces = sampled_exits(policy, 0, modulated=False, keep=400)
    assert nominal > 0.05  # the learned DS does leave the soup wrongly from some pushed states
    wrong = [np.asarray(t) for t in traces if _wrong_exit(np.asarray(t[-1]))]
    assert abs(len(wrong) - nominal * len(traces)) <= 3  # the traces are rounded to 0.1 mm
    records = [FailureRecord(t[-2], t[-1], t[0]) for t in wrong[:2]]  # last in-mode state, failure, entry
    policy.cut_sets["b"].set_cuts(resolve_cuts(records, policy.dynamics["b"].attractor, ARM_CUT_MARGIN))
    modulated, kept = sampled_exits(policy, 0, modulated=True, keep=3)
    assert modulated < nominal and len(kept) == 3 and len(kept[0][0]) == 3
    assert sampled_exits(policy, 0, modulated=False)[0] == nominal  # the cuts act only through the modulation
    first = records[0]
    inward = 0.3 * (policy.dynamics["b"].attractor - first.last_in_mode)  # the attractor is inside every cut
    again = FailureRecord(first.last_in_mode + inward, first.last_in_mode - inward, first.entry)
    policy.failures["b"] = [first, again]  # from inside the first failure's cut to beyond it
    assert repeated_failures(policy) == 1
    policy.failures["b"] = [first, FailureRecord(first.last_in_mode + inward, first.last_in_mode + 2 * inward,
                                                 first.entry)]  # fmt: skip
    assert repeated_failures(policy) == 0


def test_push_plan_scoops_then_carries() -> None:
    plan = push_plan(np.random.default_rng(0), 4, 5)
    assert [mode for mode, _, _ in plan[:2]] == list(ARM_PUSH_MODES) and all(m in "abc" for m, _, _ in plan)
    for _, dwell, delta in plan:
        assert 1 <= dwell <= 5 and 0.5 - 1e-9 <= np.linalg.norm(delta / ARM_PUSH_SCALE) <= 1 + 1e-9
    assert push_plan(np.random.default_rng(0), 0, 5) == []


def test_bad_input_names_the_argument() -> None:
    bad = execute_trial(_trial("ds", 0))
    assert not bad.ok and "unknown method" in (bad.error or "")
    with pytest.raises(ValueError, match="method"):
        scoop_trial(0, "bc", ArmScoopParams())
    with pytest.raises(TypeError, match="seed"):
        scoop_trial("0", "ltl-ds", ArmScoopParams())  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="max_dwell"):
        push_plan(np.random.default_rng(0), 2, 0)
    with pytest.raises(ValueError, match="n_episodes"):
        get_suite("tli-arm-scoop").resolve_params({"n_episodes": 0})
