"""``tli-arm-scoop``: LTL-DS soup scooping on the Panda arm under random pushes (thesis robot experiment 1).

One trial = one experiment seed (two expert demonstrations, one LPV-DS per
mode) x one method (``ltl-ds``: automaton + mode DSs; ``ltl-ds+mod``: also
cuts from invariance failures and modulation), run for ``n_episodes`` pushed
episodes on ``ArmScoop-v0`` through
:func:`~steer_envs.bench.suites.tli_arm_scoop.protocol.scoop_trial` (the
thesis: 30 trials by six subjects).

>>> ArmScoopParams(n_episodes=3).to_json()["n_episodes"]
3
"""

from __future__ import annotations

from typing import Any

from steer_envs.bench.findings import cell_means, full, judge
from steer_envs.bench.metrics import NUM_CUTS
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, Trial, TrialResult, register_suite
from steer_envs.bench.suites.tli_arm_scoop.params import ENV_ID, METHODS, ArmScoopParams
from steer_envs.bench.trials import run_protocol

MOD = "ltl-ds+mod"
SOURCE = "thesis appendix 'Robot Experiment 1: Soup-Scooping' (30/30 trials, six subjects)"


def run_scoop_trial(trial: Trial) -> TrialResult:
    """One experiment of one method: ``n_episodes`` pushed episodes on the arm."""
    from steer_envs.bench.suites.tli_arm_scoop.protocol import scoop_trial

    _, res = run_protocol(trial, ArmScoopParams, scoop_trial, METHODS)
    undone = res["undone_episodes"]
    metrics = {
        "success": 100.0 * res["success"],
        "failures": res["failures"],
        "task_pushes": res["task_pushes"],
        "recovered": None if undone == 0 else 100.0 * res["recovered"] / undone,
        "spills": res["spills"],
        "num_cuts": float(res["num_cuts"]),
        "repeats": float(res["repeats"]),
        "sampled_exits_nominal": 100.0 * res["sampled_exits_nominal"],
        "sampled_exits_modulated": 100.0 * res["sampled_exits_modulated"],
        "steps": res["steps"],
    }
    extra: dict[str, Any] = {"failure_modes": res["failure_modes"], "undone_episodes": undone}
    if "figure" in res:
        extra["figure"] = res["figure"]
    return TrialResult(metrics, extra)


def scoop_findings(table: Any) -> list[Finding]:
    """The thesis's claims: every trial succeeds with modulation; LTL replans after task-level pushes; cuts bound."""
    failures = {k: table.means(k, METHODS) for k in ("failures", "repeats")} | {"cuts": table.mean("num_cuts", MOD)}
    return [
        judge(
            "LTL-DS with modulation succeeds in every pushed trial (thesis: 30/30 with six human subjects)",
            table.means("success", METHODS),
            lambda s: full(s[MOD]),
            lambda s: f"ltl-ds+mod {s[MOD]:.0f} %, ltl-ds (no modulation) {s['ltl-ds']:.0f} %",
        ),
        judge(
            "LTL replans after task-level pushes (beads spilled, spoon lifted out empty): those episodes still succeed",
            cell_means(table, MOD, ("recovered", "task_pushes")),
            lambda m: m["task_pushes"] > 0 and full(m["recovered"]),
            "ltl-ds+mod: {task_pushes:.2f} task-level pushes per episode, "
            "{recovered:.0f} % of their episodes succeeded",
        ),
        judge(
            "with modulation no invariance failure is experienced again: none crosses a cut learned before it",
            failures,
            lambda f: f["cuts"] > 0 and f["repeats"][MOD] == 0,
            lambda f: (
                f"invariance failures per episode: ltl-ds {f['failures']['ltl-ds']:.2f}, "
                f"ltl-ds+mod {f['failures'][MOD]:.2f}; {f['cuts']:.0f} cuts learned; failures through an earlier "
                f"cut: ltl-ds {f['repeats']['ltl-ds']:.0f}, ltl-ds+mod {f['repeats'][MOD]:.0f}"
            ),
        ),
        judge(
            "the cuts learned on the arm bound the scoop DS: fewer sampled flows leave the mode after modulation",
            cell_means(table, MOD, ("sampled_exits_nominal", "sampled_exits_modulated")),
            lambda e: e["sampled_exits_modulated"] < e["sampled_exits_nominal"],
            "sampled scoop flows exiting the mode: nominal {sampled_exits_nominal:.1f} %, "
            "modulated {sampled_exits_modulated:.1f} %",
        ),
    ]


TLI_ARM_SCOOP = register_suite(
    Suite(
        name="tli-arm-scoop",
        description=(
            "TLI soup scooping on the Panda arm (ArmScoop-v0, robosuite): one LPV-DS per mode in (y, z, pitch) from "
            "two demonstrations, the scooping automaton, with / without cuts and modulation, under random pushes; "
            "seeds are experiments."
        ),
        metrics=(
            Metric("success", "success (%) under random pushes (beads delivered)", fmt=".0f"),
            Metric("failures", "invariance failures per episode", higher_is_better=False),
            Metric("task_pushes", "pushes per episode that undid task progress (spill, empty spoon)"),
            Metric("recovered", "episodes with a task-level push that still succeeded (%)", fmt=".0f"),
            Metric("spills", "beads spilled by the policy itself per episode", higher_is_better=False),
            NUM_CUTS,
            Metric(
                "repeats",
                "invariance failures that crossed a cut learned from earlier ones (per trial)",
                higher_is_better=False,
                fmt=".0f",
            ),
            Metric(
                "sampled_exits_nominal",
                "sampled scoop-DS flows from pushed states leaving the mode, nominal (%)",
                higher_is_better=False,
                fmt=".1f",
            ),
            Metric(
                "sampled_exits_modulated",
                "the same flows modulated by the trial's cuts (%)",
                higher_is_better=False,
                fmt=".1f",
            ),
            Metric("steps", "steps per episode (20 Hz)", higher_is_better=False, fmt=".0f"),
        ),
        run_trial=run_scoop_trial,
        envs=(ENV_ID,),
        methods=METHODS,
        params=ArmScoopParams(),
        trials_param="n_episodes",
        default_seeds=1,
        references=(Reference("success", 100.0, env=ENV_ID, method="ltl-ds+mod", source=SOURCE),),
        quick={"n_episodes": 2},
        quick_seeds=1,
        plot="steer_envs.bench.suites.tli_arm_scoop.plots:plot_arm_scoop",
        findings=scoop_findings,
    )
)
