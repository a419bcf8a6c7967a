"""Suite/Trial declarations, parameter handling and the registry."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import pytest

from steer_envs.bench.params import SuiteParams
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
    assert suite.resolve_params({"sleep": 1}).sleep == 1.0  # int -> float, so keys hash equally
    assert isinstance(suite.resolve_params({"sleep": 1}).sleep, float)
    assert suite.resolve_params({}, trials=7).samples == 7
    assert suite.resolve_params({"fail_seeds": [1, 2]}).to_json()["fail_seeds"] == [1, 2]  # JSON list, as stored
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
    with pytest.raises(ValueError, match=r"seeds must be an int in \[1, inf\], got 0"):
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


@dataclass(frozen=True)
class _CoinParams(SuiteParams):
    suite_name: ClassVar[str] = "coin"
    flips: int = 10
    bias: float = 0.5
    tag: str | None = None
    skip: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        self.require_at_least(1, "flips")
        self.require("bias", 0.0 <= self.bias <= 1.0, "in [0, 1]")


def test_typed_params_coerce_validate_and_round_trip_as_json():
    p = _CoinParams.from_json({"flips": 4.0, "bias": 1, "skip": [3, 5]})
    assert p == _CoinParams(flips=4, bias=1.0, skip=(3, 5)) and isinstance(p.bias, float)
    assert p.to_json() == {"flips": 4, "bias": 1.0, "tag": None, "skip": [3, 5]}
    assert _CoinParams.from_json(p.to_json()) == p and p.replace(flips=2).flips == 2
    assert _CoinParams.field_names() == ("flips", "bias", "tag", "skip")
    with pytest.raises(ValueError, match="suite 'coin' has no parameter 'flip'; parameters:"):
        _CoinParams.from_json({"flip": 3})
    with pytest.raises(ValueError, match=r"'flips' must be int, got 2\.5"):
        _CoinParams.from_json({"flips": 2.5})
    with pytest.raises(ValueError, match="'tag' must be str or null, got 3"):
        _CoinParams.from_json({"tag": 3})
    with pytest.raises(ValueError, match="'skip' must be a list of int"):
        _CoinParams.from_json({"skip": ["a"]})
    with pytest.raises(ValueError, match=r"coin: parameter 'bias' must be in \[0, 1\], got 2.0"):
        _CoinParams.from_json({"bias": 2})
    with pytest.raises(TypeError, match="mapping"):
        _CoinParams.from_json([("flips", 1)])  # type: ignore[arg-type]


def test_suite_with_typed_params_plans_json_trials_and_checks_values_early():
    suite = Suite("coin", "d", (Metric("pi"),), run_selftest_trial, params=_CoinParams(), trials_param="flips")
    assert suite.param_names == ("flips", "bias", "tag", "skip") and suite.defaults == _CoinParams()
    plan = suite.plan(build_request(suite, seeds=2, trials=3, params={"bias": 1}))
    assert [t.params for t in plan.trials] == [{"bias": 1.0, "flips": 3, "tag": None, "skip": []}] * 2
    with pytest.raises(ValueError, match="coin: parameter 'flips' must be >= 1, got 0"):
        suite.plan(build_request(suite, params={"flips": 0}))
    with pytest.raises(TypeError, match="params must be _CoinParams"):
        suite.trial(None, None, 0, get_suite("selftest").defaults)
    with pytest.raises(ValueError, match="coin: parameter 'flips' must be >= 1"):
        Suite("coin", "d", (), run_selftest_trial, params=_CoinParams(), quick={"flips": 0})
    with pytest.raises(ValueError, match="quick overrides unknown params"):
        Suite("coin", "d", (), run_selftest_trial, params=_CoinParams(), quick={"coins": 1})

    @dataclass
    class Mutable(SuiteParams):
        n: int = 1

    with pytest.raises(TypeError, match="frozen dataclass"):
        Suite("coin", "d", (), run_selftest_trial, params=Mutable())

    @dataclass(frozen=True)
    class Shadowing(SuiteParams):
        replace: int = 1

    with pytest.raises(TypeError, match=r"'replace' shadows SuiteParams\.replace"):
        Suite("coin", "d", (), run_selftest_trial, params=Shadowing())


def test_a_mapping_of_defaults_still_declares_params(toy_suite):
    assert toy_suite.param_names == ("scale", "sleep", "fail_flag")
    assert toy_suite.resolve_params({"scale": 2}).to_json() == {"scale": 2.0, "sleep": 0.0, "fail_flag": ""}
    with pytest.raises(ValueError, match="suite 'toy': parameter 'fail_flag' must be str"):
        toy_suite.resolve_params({"fail_flag": 1})
