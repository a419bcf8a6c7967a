"""The ltl-translation suite: one trial per thesis spec, deterministic automaton sizes."""

from __future__ import annotations

import pytest

from steer_envs.bench.executors import execute_trial
from steer_envs.bench.runner import build_request, plan_trials
from steer_envs.bench.suite import Trial, get_suite
from steer_envs.ltl.specs import all_specs


def test_plan_has_one_trial_per_spec_and_is_in_the_quick_tour():
    suite = get_suite("ltl-translation")
    plan = plan_trials(suite, build_request(suite))
    assert sorted(t.method for t in plan.trials) == sorted(all_specs())
    assert suite.quick == {"repeats": 3}


def test_trial_reports_time_and_the_soup_automaton_size():
    suite = get_suite("ltl-translation")
    (trial,) = [
        t
        for t in plan_trials(suite, build_request(suite, params={"repeats": 1})).trials
        if t.method == "soup_scoop_public"
    ]
    first, again = (execute_trial(trial) for _ in range(2))
    assert first.ok and again.ok, first.error
    first, again = first.record["metrics"], again.record["metrics"]
    assert first["translate_ms"] > 0
    assert first["states"] >= 4 and first["edges"] >= first["states"]  # a, b, c, d at least
    assert {k: first[k] for k in ("states", "edges", "acceptance_sets")} == {
        k: again[k] for k in ("states", "edges", "acceptance_sets")
    }


def test_unknown_spec_is_a_clear_error():
    from steer_envs.bench.suites.ltl import run_translation_trial

    with pytest.raises(ValueError, match="unknown spec"):
        run_translation_trial(
            Trial(suite="ltl-translation", env=None, method="nope", seed=0, params={"repeats": 1}, fn="x:y")
        )
