"""``tli-cooking``: reuse learned DS skills for new tasks by editing the automaton (thesis appendix "Generalization").

One trial = one experiment seed (two expert demonstrations, chicken first and
broccoli first, and the transition skills fitted on them: the same skills for
every method) x one edited automaton (the method: ``phi_cb``, ``phi_bc``,
``phi_c``, ``phi_cc``), run from ``n_starts`` starts without and with random
pushes through :func:`~steer_envs.bench.suites.tli_cooking.protocol.cooking_trial`.

>>> CookingParams(n_starts=4).to_json()["n_starts"]
4
"""

from __future__ import annotations

from typing import Any

from steer_envs.bench.findings import all_full
from steer_envs.bench.metrics import NUM_CUTS
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, Trial, TrialResult, register_suite
from steer_envs.bench.suites.tli_cooking.params import ENV_ID, VARIANTS, CookingParams
from steer_envs.bench.trials import run_protocol

THESIS_SOURCE = "thesis appendix 'Generalization Results', Fig. (c)-(f)"


def run_cooking_trial(trial: Trial) -> TrialResult:
    """One experiment under one edited automaton, with and without pushes."""
    from steer_envs.bench.suites.tli_cooking.protocol import cooking_trial

    _, res = run_protocol(trial, CookingParams, cooking_trial, VARIANTS)
    clean, push = res["clean"], res["push"]
    metrics = {
        "success": 100.0 * clean["success"],
        "invalid": clean["invalid"],
        "replans": clean["replans"],
        "success_push": 100.0 * push["success"],
        "invalid_push": push["invalid"],
        "replans_push": push["replans"],
        "loops_push": push["failures"],
        "num_cuts": float(res["num_cuts"]),
        "deliveries": clean["deliveries"],
    }
    extra: dict[str, Any] = {"skills": res["skills"], "fingerprint": res["fingerprint"]}
    if "figure" in clean:
        extra["figure"] = {
            "clean": clean["figure"],
            "push": push["figure"],
            "attractors": res["attractors"],
        }
    return TrialResult(metrics, extra)


def cooking_findings(table: Any) -> list[Finding]:
    """Every edited task succeeds from every start without retraining (and, reported beside, under pushes)."""
    claim = "every edited task (phi_cb, phi_bc, phi_c, phi_cc) succeeds from every start without retraining"
    push_claim = "every edited task recovers from random pushes by replanning (thesis Fig. (c)-(f))"
    return [all_full(table, claim, "success", VARIANTS), all_full(table, push_claim, "success_push", VARIANTS)]


TLI_COOKING = register_suite(
    Suite(
        name="tli-cooking",
        description=(
            "TLI re-tasking on Cooking-v0: DS skills learned once per mode transition from two demonstrations, run "
            "under the edited automata phi_cb, phi_bc, phi_c, phi_cc without / with random pushes; "
            "seeds are experiments."
        ),
        metrics=(
            Metric("success", "success (%) from the start box, no pushes", fmt=".0f"),
            Metric("invalid", "automaton-invalid transitions per episode, no pushes", higher_is_better=False),
            Metric("replans", "replans (unexpected transitions) per episode, no pushes", higher_is_better=False),
            Metric("success_push", "success (%) under random pushes", fmt=".0f"),
            Metric("invalid_push", "invalid transitions (not caused by a push) per episode", higher_is_better=False),
            Metric("replans_push", "replans per episode under pushes", higher_is_better=False),
            Metric("loops_push", "invariance failures (discrete loops) per episode", higher_is_better=False),
            NUM_CUTS,
            Metric("deliveries", "chicken deliveries per episode, no pushes", fmt=".1f"),
        ),
        run_trial=run_cooking_trial,
        envs=(ENV_ID,),
        methods=VARIANTS,
        params=CookingParams(),
        trials_param="n_starts",
        default_seeds=3,
        references=tuple(Reference("success", 100.0, env=ENV_ID, method=v, source=THESIS_SOURCE) for v in VARIANTS),
        quick={"n_starts": 3, "horizon": 2000},
        quick_seeds=1,
        plot="steer_envs.bench.suites.tli_cooking.plots:plot_cooking",
        findings=cooking_findings,
    )
)
