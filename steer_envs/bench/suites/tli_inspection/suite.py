"""``tli-inspection``: vanilla DS vs LTL-DS on InspectionLine-v0 under large pushes (thesis robot experiment 2).

One trial = one experiment seed (two expert demonstrations and the fits) x one
method (``vanilla-ds``, ``ltl-ds``, ``ltl-ds+mod``), run for ``n_episodes``
without pushes and ``n_episodes`` with large pushes through
:func:`~steer_envs.bench.suites.tli_inspection.protocol.inspection_trial`.

>>> InspectionParams(n_episodes=3).to_json()["n_episodes"]
3
"""

from __future__ import annotations

from typing import Any

from steer_envs.bench.findings import cell_means, full, judge
from steer_envs.bench.metrics import NUM_CUTS
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, Trial, TrialResult, register_suite
from steer_envs.bench.suites.tli_inspection.params import ENV_ID, METHODS, InspectionParams
from steer_envs.bench.trials import check_trial
from steer_envs.utils.threads import single_threaded

SOURCE = "thesis appendix 'Robot Experiment 2: Inspection Line'"


def run_inspection_trial(trial: Trial) -> TrialResult:
    """One experiment of one method, without and with large pushes."""
    from steer_envs.bench.suites.tli_inspection.protocol import inspection_trial

    check_trial(trial, methods=METHODS)
    p = InspectionParams.from_json(trial.params)
    record = trial.seed < p.plot_seeds
    method = str(trial.method)
    with single_threaded():
        clean = inspection_trial(trial.seed, method, p.replace(min_push=0.0, max_push=0.0))
        push = inspection_trial(trial.seed, method, p, record=record)
    metrics = {
        "success_clean": 100.0 * clean["success"],
        "success": 100.0 * push["success"],
        "uninspected": 100.0 * push["uninspected"],
        "reached": 100.0 * (push["success"] + push["uninspected"]),
        "inspections": push["inspections"],
        "num_cuts": float(push["num_cuts"]),
        "steps": push["steps"],
    }
    extra: dict[str, Any] = {"figure": push["figure"]} if record else {}
    return TrialResult(metrics, extra)


def inspection_findings(table: Any) -> list[Finding]:
    """The thesis's point: vanilla DS reaches its attractor but skips the inspection; LTL-DS re-does it."""
    return [
        judge(
            "vanilla DS reaches the release station after large pushes, but without the inspection in some episodes",
            cell_means(table, "vanilla-ds", ("reached", "uninspected", "success")),
            lambda v: full(v["reached"]) and v["uninspected"] > 0,
            "vanilla-ds: reached {reached:.0f} %, uninspected {uninspected:.0f} %, success {success:.0f} %",
        ),
        judge(
            "LTL-DS with cuts re-does the inspection after large pushes and succeeds in every episode",
            cell_means(table, "ltl-ds+mod", ("success", "inspections")),
            lambda m: full(m["success"]) and m["inspections"] > 1.0,
            "ltl-ds+mod: success {success:.0f} %, {inspections:.2f} inspections per episode",
        ),
    ]


TLI_INSPECTION = register_suite(
    Suite(
        name="tli-inspection",
        description=(
            "TLI inspection line: one vanilla LPV-DS for the whole task vs LTL-DS (without / with cuts) on "
            "InspectionLine-v0 under large pushes during the inspection; seeds are experiments."
        ),
        metrics=(
            Metric("success_clean", "success (%) without pushes", fmt=".0f"),
            Metric("success", "success (%) under large pushes (released after the inspection)", fmt=".0f"),
            Metric(
                "uninspected",
                "episodes ending at the station with an uninspected object (%)",
                higher_is_better=False,
                fmt=".0f",
            ),
            Metric("reached", "episodes ending at the release station (%), inspected or not", fmt=".0f"),
            Metric("inspections", "times the object was put on the line per episode", fmt=".2f"),
            NUM_CUTS,
            Metric("steps", "steps per episode", higher_is_better=False, fmt=".0f"),
        ),
        run_trial=run_inspection_trial,
        envs=(ENV_ID,),
        methods=METHODS,
        params=InspectionParams(),
        trials_param="n_episodes",
        default_seeds=3,
        references=(
            Reference("success", 100.0, env=ENV_ID, method="ltl-ds+mod", source=SOURCE + " (task completion)"),
            Reference("reached", 100.0, env=ENV_ID, method="vanilla-ds", source=SOURCE + " (always reaches it)"),
        ),
        quick={"n_episodes": 4},
        quick_seeds=1,
        plot="steer_envs.bench.suites.tli_inspection.plots:plot_inspection",
        findings=inspection_findings,
    )
)
