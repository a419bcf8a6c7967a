"""``ltl-translation``: how fast the native translator turns each thesis spec into an automaton.

Methods are the spec names (the thesis's specs, ch. 3 appendix); each trial
times ``repeats`` cold translations (simplifier caches cleared) and reports
the median against the goal of 50 ms, plus the size of the automaton, which
is deterministic and so identical on every executor.

>>> from steer_envs.bench.suite import Trial
>>> trial = Trial("ltl-translation", None, "soup_scoop_public", 0, LtlParams(repeats=1).to_json(), LTL_TRANSLATION.fn)
>>> run_translation_trial(trial)["states"] >= 4
True
"""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass
from typing import ClassVar

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Metric, Suite, Trial, register_suite


@dataclass(frozen=True)
class LtlParams(SuiteParams):
    """Parameters of ``ltl-translation``: cold translations timed per trial (1 to 10^4)."""

    suite_name: ClassVar[str] = "ltl-translation"
    repeats: int = 5

    def __post_init__(self) -> None:
        self.require_at_least(1, "repeats")
        self.require_at_most(10_000, "repeats")


def _spec_names() -> list[str]:
    from steer_envs.ltl.specs import all_specs

    return list(all_specs())


def run_translation_trial(trial: Trial) -> dict[str, float]:
    """Median cold translation time (ms) of one spec, and its automaton's size."""
    from steer_envs.ltl.buchi import translate
    from steer_envs.ltl.simplify import clear_caches
    from steer_envs.ltl.specs import all_specs

    specs = all_specs()
    if trial.method not in specs:
        raise ValueError(f"unknown spec {trial.method!r}; expected one of {sorted(specs)}")
    repeats = LtlParams.from_json(trial.params).repeats
    formula = specs[str(trial.method)].translation_formula()
    runs = []
    automaton = None
    for _ in range(repeats):
        clear_caches()
        start = time.perf_counter()
        automaton = translate(formula)
        runs.append(time.perf_counter() - start)
    assert automaton is not None
    return {
        "translate_ms": 1e3 * statistics.median(runs),
        "states": float(automaton.num_states),
        "edges": float(len(automaton.edges)),
        "acceptance_sets": float(automaton.num_sets),
    }


LTL_TRANSLATION = register_suite(
    Suite(
        name="ltl-translation",
        description="LTL -> Buchi translation time of each thesis spec (target < 50 ms) and automaton size.",
        metrics=(
            Metric(
                "translate_ms",
                "median cold translation time (ms)",
                kind="timing",
                higher_is_better=False,
                fmt=".1f",
                goal=50.0,
            ),
            Metric("states", "automaton states", fmt=".0f"),
            Metric("edges", "automaton edges", fmt=".0f"),
            Metric("acceptance_sets", "generalized Buchi acceptance sets", fmt=".0f"),
        ),
        run_trial=run_translation_trial,
        methods=_spec_names,
        params=LtlParams(),
        trials_param="repeats",
        default_seeds=1,
        quick={"repeats": 3},
    )
)
