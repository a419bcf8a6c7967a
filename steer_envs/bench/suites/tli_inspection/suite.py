"""``tli-inspection``: vanilla DS vs LTL-DS on InspectionLine-v0 under large pushes (thesis robot experiment 2).

One trial = one experiment seed (two expert demonstrations and the fits) x one
method (``vanilla-ds``, ``ltl-ds``, ``ltl-ds+mod``), run for ``n_episodes``
without pushes and ``n_episodes`` with large pushes through
:func:`~steer_envs.bench.suites.tli_inspection.protocol.inspection_trial`.

>>> InspectionParams(n_episodes=3).to_json()["n_episodes"]
3
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, Trial, TrialResult, register_suite
from steer_envs.utils.threads import single_threaded

ENV_ID = "steer_envs/InspectionLine-v0"
METHODS: tuple[str, ...] = ("vanilla-ds", "ltl-ds", "ltl-ds+mod")
SOURCE = "thesis appendix 'Robot Experiment 2: Inspection Line'"


@dataclass(frozen=True)
class InspectionParams(SuiteParams):
    """Parameters of ``tli-inspection``: episodes per condition, pushes per episode, push lengths, step cap."""

    suite_name: ClassVar[str] = "tli-inspection"
    n_episodes: int = 10
    n_pushes: int = 1
    min_push: float = 4.0
    max_push: float = 10.0
    max_steps: int = 3000
    plot_seeds: int = 1

    def __post_init__(self) -> None:
        self.require_at_least(1, "n_episodes", "max_steps")
        self.require_at_least(0, "n_pushes", "min_push", "plot_seeds")
        self.require("max_push", self.max_push >= self.min_push, ">= min_push")


def run_inspection_trial(trial: Trial) -> TrialResult:
    """One experiment of one method, without and with large pushes."""
    from steer_envs.bench.suites.tli_inspection.protocol import inspection_trial

    if trial.method not in METHODS:
        raise ValueError(f"tli-inspection: unknown method {trial.method!r}; expected one of {METHODS}")
    p = InspectionParams.from_json(trial.params)
    record = trial.seed < p.plot_seeds
    method = str(trial.method)
    with single_threaded():
        clean = inspection_trial(
            trial.seed, method, n_episodes=p.n_episodes, n_pushes=p.n_pushes, min_push=0.0, max_push=0.0,
            max_steps=p.max_steps,
        )  # fmt: skip
        push = inspection_trial(
            trial.seed, method, n_episodes=p.n_episodes, n_pushes=p.n_pushes, min_push=p.min_push,
            max_push=p.max_push, max_steps=p.max_steps, record=record,
        )  # fmt: skip
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
    out = []
    v = {k: table.mean(k, "vanilla-ds") for k in ("reached", "uninspected", "success")}
    claim = "vanilla DS reaches the release station after large pushes, but without the inspection in some episodes"
    if None in v.values():
        out.append(Finding(claim, None))
    else:
        detail = (
            f"vanilla-ds: reached {v['reached']:.0f} %, uninspected {v['uninspected']:.0f} %, "
            f"success {v['success']:.0f} %"
        )
        out.append(Finding(claim, v["reached"] >= 100.0 - 1e-9 and v["uninspected"] > 0, detail))
    m = {k: table.mean(k, "ltl-ds+mod") for k in ("success", "inspections")}
    claim = "LTL-DS with cuts re-does the inspection after large pushes and succeeds in every episode"
    if None in m.values():
        out.append(Finding(claim, None))
    else:
        detail = f"ltl-ds+mod: success {m['success']:.0f} %, {m['inspections']:.2f} inspections per episode"
        out.append(Finding(claim, m["success"] >= 100.0 - 1e-9 and m["inspections"] > 1.0, detail))
    return out


def _plot(suite: Suite, records: Any, out_dir: str) -> list[str]:
    from steer_envs.bench.suites.tli_inspection.plots import plot_inspection

    return plot_inspection(suite, records, out_dir)


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
            Metric("num_cuts", "cuts learned over the trial", higher_is_better=False, fmt=".1f"),
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
        plot=_plot,
        findings=inspection_findings,
    )
)
