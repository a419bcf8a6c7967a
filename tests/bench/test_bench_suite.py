"""Suite/Trial declarations, parameter handling and the registry."""

from __future__ import annotations

import math

import pytest

from steer_envs.bench.runner import build_request, plan_trials
from steer_envs.bench.suite import (
    Metric,
    Reference,
    Suite,
    Trial,
    get_suite,
    load_plugins,
    register_suite,
    resolve_function,
    suites,
)
from steer_envs.bench.suites.selftest import run_selftest_trial

FN = "steer_envs.bench.suites.selftest:run_selftest_trial"


def test_trial_key_is_stable_and_ignores_param_order_and_fn():
    a = Trial("s", "e", "m", 3, {"x": 1, "y": [1, 2]}, FN)
    b = Trial("s", "e", "m", 3, {"y": [1, 2], "x": 1}, "other.module:fn")
    assert a.key == b.key
    assert a.key != Trial("s", "e", "m", 4, {"x": 1, "y": [1, 2]}, FN).key
    assert a.key != Trial("s", "e", "m", 3, {"x": 2, "y": [1, 2]}, FN).key


def test_trial_rejects_bad_input():
    with pytest.raises(TypeError, match="seed"):
        Trial("s", None, None, 1.5, {}, FN)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="module:function"):
        Trial("s", None, None, 1, {}, "nofn")
    with pytest.raises(ValueError, match="JSON"):
        Trial("s", None, None, 1, {"x": object()}, FN)
    with pytest.raises(ValueError, match="JSON"):
        Trial("s", None, None, 1, {"x": math.nan}, FN)


def test_suite_validation():
    with pytest.raises(ValueError, match="module-level"):
        Suite("bad", "d", (), run_trial=lambda t: {})
    with pytest.raises(ValueError, match="unknown metric"):
        Suite("bad", "d", (Metric("a"),), run_selftest_trial, references=(Reference("b", 1.0),))
    with pytest.raises(ValueError, match="duplicate"):
        Suite("bad", "d", (Metric("a"), Metric("a")), run_selftest_trial)
    with pytest.raises(ValueError, match="trials_param"):
        Suite("bad", "d", (), run_selftest_trial, trials_param="n")
    with pytest.raises(ValueError, match="needs run_trial"):
        Suite("bad", "d", ())
    with pytest.raises(ValueError, match="identifier"):
        Metric("not a name")
    with pytest.raises(ValueError, match="kind"):
        Metric("a", kind="other")  # type: ignore[arg-type]


def test_params_are_checked_and_coerced():
    suite = get_suite("selftest")
    assert suite.resolve_params({"sleep": 1})["sleep"] == 1.0  # int -> float, so keys hash equally
    assert isinstance(suite.resolve_params({"sleep": 1})["sleep"], float)
    assert suite.resolve_params({}, trials=7)["samples"] == 7
    with pytest.raises(ValueError, match="no parameter 'speed'"):
        suite.resolve_params({"speed": 1})
    with pytest.raises(ValueError, match="'samples' must be int"):
        suite.resolve_params({"samples": "many"})
    with pytest.raises(ValueError, match="'samples' must be int"):
        suite.resolve_params({"samples": True})


def test_request_filters_envs_and_methods(toy_suite):
    request = build_request(toy_suite, envs=["toy/B-v0"], methods=["b", "a"], seeds=3)
    assert request.envs == ("toy/B-v0",) and request.methods == ("a", "b") and request.seeds == (0, 1, 2)
    plan = plan_trials(toy_suite, request)
    assert len(plan.trials) == 6
    with pytest.raises(ValueError, match="unknown env 'toy/C-v0'"):
        build_request(toy_suite, envs=["toy/C-v0"])
    with pytest.raises(ValueError, match="unknown method"):
        build_request(toy_suite, methods=["z"])
    with pytest.raises(ValueError, match="seeds must be >= 1"):
        build_request(toy_suite, seeds=0)
    with pytest.raises(ValueError, match="no per-trial count"):
        plan_trials(toy_suite, build_request(toy_suite, trials=3))
    assert build_request(toy_suite, seeds=[5, 9]).seeds == (5, 9)


def test_references_most_specific_wins(toy_suite):
    assert toy_suite.references_for("toy/A-v0", "b")["value"].value == 1.0
    assert toy_suite.references_for("toy/B-v0", "b")["value"].value == 1.5
    assert toy_suite.references_for("toy/B-v0", "a")["value"].source == "toy ref a"


def test_registry(toy_suite):
    names = [s.name for s in suites()]
    assert {"selftest", "smoke", "quick", "toy"} <= set(names) and names == sorted(names)
    with pytest.raises(KeyError, match="known suites"):
        get_suite("nope")
    with pytest.raises(ValueError, match="already registered"):
        register_suite(Suite("toy", "again", (), run_selftest_trial))
    with pytest.raises(TypeError):
        register_suite("toy")  # type: ignore[arg-type]
    with pytest.raises(ImportError, match="no_such_plugin_module"):
        load_plugins(["no_such_plugin_module"])
    assert resolve_function(FN) is run_selftest_trial


def test_metric_goal_direction():
    assert Metric("a", goal=20).meets_goal(25) is True
    assert Metric("a", goal=20).meets_goal(19) is False
    assert Metric("a", goal=0.1, higher_is_better=False).meets_goal(0.05) is True
    assert Metric("a").meets_goal(1) is None
