"""steer-ui suite: both trials end to end (tiny settings, socket client), findings, parameter checks."""

from __future__ import annotations

import pytest

pytest.importorskip("fastapi")

from steer_envs.bench.executors import execute_trial
from steer_envs.bench.report import summarize
from steer_envs.bench.suite import BUILTIN_SUITE_MODULES, Trial, get_suite
from steer_envs.bench.suites.ui.suite import UIParams


def _trial(method: str, **overrides: object) -> Trial:
    suite = get_suite("steer-ui")
    return suite.trial(None, method, 0, suite.resolve_params(overrides))


def test_registered_with_quick_settings() -> None:
    assert "steer_envs.bench.suites.ui.suite" in BUILTIN_SUITE_MODULES
    suite = get_suite("steer-ui")
    assert suite.method_list() == ["roundtrip", "load"] and suite.quick is not None


def test_roundtrip_and_load_trials_with_findings() -> None:
    fast = {"sampler": "GD", "batch": 4, "browser": "no", "target_ms": 60_000.0}
    roundtrip = execute_trial(_trial("roundtrip", roundtrips=2, **fast))
    assert roundtrip.ok, roundtrip.error
    m = roundtrip.record["metrics"]
    assert m["browser"] == 0 and m["network_ms"] > 0 and m["roundtrip_ms"] >= m["network_ms"]
    assert m["under_target"] == 100.0 and m["steer_calls"] is None and m["push_ms"] is None
    assert roundtrip.record["extra"]["domain"] == "maze2d" and roundtrip.record["extra"]["cpu"]
    assert m["first_ratio"] > 0  # the first steering call after ready, over the later ones
    load = execute_trial(_trial("load", connections=2, duration_s=3.0, malformed=30, **fast))
    assert load.ok, load.error
    m = load.record["metrics"]
    assert m["steer_calls"] >= 2 and m["dropped"] == 0 and m["errors"] == 0
    assert m["malformed_unanswered"] == 0 and m["server_crashes"] == 0
    (table,) = summarize([roundtrip.record, load.record])
    verdicts = [f.holds for f in table.findings]
    assert verdicts[1] in (True, False) and verdicts[2] is True and len(verdicts) == 4


def test_a_push_domain_round_trip() -> None:
    pushed = execute_trial(_trial("roundtrip", domain="soup-scoop", roundtrips=2, browser="no", target_ms=60_000.0))
    assert pushed.ok, pushed.error
    m = pushed.record["metrics"]
    assert m["network_ms"] is None and m["sampler_ms"] is None and 0 < m["push_ms"] <= m["server_ms"]
    assert m["roundtrip_ms"] >= m["server_ms"] and pushed.record["extra"]["domain"] == "soup-scoop"
    assert m["first_ratio"] is None  # a push is no steering call
    (table,) = summarize([pushed.record])
    assert table.findings[0].holds is True and "push" in table.findings[0].detail
    refused = execute_trial(_trial("load", domain="soup-scoop", duration_s=1.0))
    assert not refused.ok and "maze2d" in str(refused.error)


@pytest.mark.parametrize(
    "overrides",
    [{"sampler": "XX"}, {"browser": "maybe"}, {"batch": -1}, {"duration_s": 0.1}, {"mcmc_steps": 0}, {"domain": "x"}],
)
def test_bad_parameters_are_refused(overrides: dict[str, object]) -> None:
    with pytest.raises(ValueError):
        UIParams(**overrides)  # type: ignore[arg-type]
