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

from dataclasses import dataclass
from typing import Any, ClassVar

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, Trial, TrialResult, register_suite
from steer_envs.utils.threads import single_threaded

ENV_ID = "steer_envs/ArmScoop-v0"
METHODS: tuple[str, ...] = ("ltl-ds", "ltl-ds+mod")
SOURCE = "thesis appendix 'Robot Experiment 1: Soup-Scooping' (30/30 trials, six subjects)"


@dataclass(frozen=True)
class ArmScoopParams(SuiteParams):
    """Parameters of ``tli-arm-scoop``.

    ``n_episodes`` pushed episodes per trial (cuts persist across them);
    ``n_pushes`` pushes per episode (the first while scooping, the second while
    carrying, more in random modes), each after ``1..max_dwell`` steps in its
    mode; ``max_steps`` per episode; the first ``plot_seeds`` experiments keep
    data for the figure.
    """

    suite_name: ClassVar[str] = "tli-arm-scoop"
    n_episodes: int = 30
    n_pushes: int = 3
    max_dwell: int = 20
    max_steps: int = 600
    plot_seeds: int = 1

    def __post_init__(self) -> None:
        self.require_at_least(1, "n_episodes", "max_dwell", "max_steps")
        self.require_at_least(0, "n_pushes", "plot_seeds")


def run_scoop_trial(trial: Trial) -> TrialResult:
    """One experiment of one method: ``n_episodes`` pushed episodes on the arm."""
    from steer_envs.bench.suites.tli_arm_scoop.protocol import scoop_trial

    if trial.method not in METHODS:
        raise ValueError(f"tli-arm-scoop: unknown method {trial.method!r}; expected one of {METHODS}")
    p = ArmScoopParams.from_json(trial.params)
    record = trial.seed < p.plot_seeds
    with single_threaded():
        res = scoop_trial(
            trial.seed, str(trial.method), n_episodes=p.n_episodes, n_pushes=p.n_pushes, max_dwell=p.max_dwell,
            max_steps=p.max_steps, record=record,
        )  # fmt: skip
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
    if record:
        extra["figure"] = res["figure"]
    return TrialResult(metrics, extra)


def scoop_findings(table: Any) -> list[Finding]:
    """The thesis's claims: every trial succeeds with modulation; LTL replans after task-level pushes; cuts bound."""
    out = []
    success = table.means("success", METHODS)
    claim = "LTL-DS with modulation succeeds in every pushed trial (thesis: 30/30 with six human subjects)"
    if success is None:
        out.append(Finding(claim, None))
    else:
        detail = f"ltl-ds+mod {success['ltl-ds+mod']:.0f} %, ltl-ds (no modulation) {success['ltl-ds']:.0f} %"
        out.append(Finding(claim, success["ltl-ds+mod"] >= 100.0 - 1e-9, detail))
    rec, pushes = table.mean("recovered", "ltl-ds+mod"), table.mean("task_pushes", "ltl-ds+mod")
    claim = "LTL replans after task-level pushes (beads spilled, spoon lifted out empty): those episodes still succeed"
    if rec is None or pushes is None:
        out.append(Finding(claim, None))
    else:
        detail = f"ltl-ds+mod: {pushes:.2f} task-level pushes per episode, {rec:.0f} % of their episodes succeeded"
        out.append(Finding(claim, pushes > 0 and rec >= 100.0 - 1e-9, detail))
    fails, repeats = table.means("failures", METHODS), table.means("repeats", METHODS)
    cuts = table.mean("num_cuts", "ltl-ds+mod")
    claim = "with modulation no invariance failure is experienced again: none crosses a cut learned before it"
    if fails is None or repeats is None or cuts is None:
        out.append(Finding(claim, None))
    else:
        detail = (
            f"invariance failures per episode: ltl-ds {fails['ltl-ds']:.2f}, ltl-ds+mod {fails['ltl-ds+mod']:.2f}; "
            f"{cuts:.0f} cuts learned; failures through an earlier cut: ltl-ds {repeats['ltl-ds']:.0f}, "
            f"ltl-ds+mod {repeats['ltl-ds+mod']:.0f}"
        )
        out.append(Finding(claim, cuts > 0 and repeats["ltl-ds+mod"] == 0, detail))
    nominal, modulated = (table.mean(k, "ltl-ds+mod") for k in ("sampled_exits_nominal", "sampled_exits_modulated"))
    claim = "the cuts learned on the arm bound the scoop DS: fewer sampled flows leave the mode after modulation"
    if nominal is None or modulated is None:
        out.append(Finding(claim, None))
    else:
        detail = f"sampled scoop flows exiting the mode: nominal {nominal:.1f} %, modulated {modulated:.1f} %"
        out.append(Finding(claim, modulated < nominal, detail))
    return out


def _plot(suite: Suite, records: Any, out_dir: str) -> list[str]:
    from steer_envs.bench.suites.tli_arm_scoop.plots import plot_arm_scoop

    return plot_arm_scoop(suite, records, out_dir)


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
            Metric("num_cuts", "cuts learned over the trial", higher_is_better=False, fmt=".1f"),
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
        plot=_plot,
        findings=scoop_findings,
    )
)
