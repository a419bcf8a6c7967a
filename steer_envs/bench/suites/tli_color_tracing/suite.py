"""``tli-color-tracing``: LTL-DS from one demonstration under three replanning automata (thesis robot experiment 3).

One trial = one experiment seed (the single demonstration and the tile DSs
fitted on it: the same for every automaton) x one replanning automaton (the
method: ``a``, ``b``, ``c`` of :func:`steer_envs.ltl.specs.color_tracing`), run
for ``n_episodes`` without and ``n_episodes`` with random pushes into the dark
region through
:func:`~steer_envs.bench.suites.tli_color_tracing.protocol.color_trial`.

>>> ColorTracingParams(n_episodes=3).to_json()["n_episodes"]
3
"""

from __future__ import annotations

from typing import Any

from steer_envs.bench.findings import all_full, cell_means, full, judge
from steer_envs.bench.metrics import NUM_CUTS
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, Trial, TrialResult, register_suite
from steer_envs.bench.suites.tli_color_tracing.params import AUTOMATA, ENV_ID, ColorTracingParams
from steer_envs.bench.trials import run_protocol

SOURCE = "thesis appendix 'Robot Experiment 3: Color Tracing' (videos; no numbers given)"
#: each automaton's re-entry rule in words (the claim its finding checks)
RULES = {
    "a": "(a) a push into D from any tile re-enters at yellow",
    "b": "(b) a push into D after yellow re-enters at blue (from yellow: at yellow)",
    "c": "(c) a push into D from yellow re-enters at blue, from blue at pink (other tiles: the tile left)",
}


def _percent(part: float, whole: float) -> float | None:
    return None if whole <= 0 else 100.0 * part / whole


def run_color_trial(trial: Trial) -> TrialResult:
    """One experiment under one replanning automaton, without and with pushes."""
    from steer_envs.bench.suites.tli_color_tracing.protocol import color_trial

    p, res = run_protocol(trial, ColorTracingParams, color_trial, AUTOMATA)
    clean, push = res["clean"], res["push"]
    metrics = {
        "success_clean": 100.0 * clean["success"],
        "success": 100.0 * push["success"],
        "pushes": push["n_pushes"] / p.n_episodes,
        "replans": push["replans"],
        "reentry_ok": _percent(push["reentry_ok"], push["n_pushes"]),
        "tracked_ok": _percent(push["tracked_ok"], push["n_pushes"]),
        "failures": push["failures"],
        "violations": push["violations"],
        "num_cuts": float(res["num_cuts"]),
        "steps": push["steps"],
    }
    extra: dict[str, Any] = {"pushes": push["push_log"]}
    if "figure" in push:
        extra["figure"] = {"push": push["figure"]}
    return TrialResult(metrics, extra)


def _reentry_finding(table: Any, a: str) -> Finding:
    """Automaton ``a``'s re-entry rule held after every push."""
    return judge(
        f"{RULES[a]}: the next mode entered after every push is the one the automaton prescribes",
        cell_means(table, a, ("reentry_ok", "pushes")),
        lambda c: c["pushes"] > 0 and full(c["reentry_ok"]),
        a + ": {reentry_ok:.0f} % of pushes re-entered as prescribed ({pushes:.1f} pushes per episode)",
    )


def color_findings(table: Any) -> list[Finding]:
    """Per automaton: its re-entry rule held after every push; the automaton told D1..D4 apart; red reached."""
    out = [_reentry_finding(table, a) for a in AUTOMATA]
    claim = "the automaton tells D1..D4 apart from the sensor history: its D mode equals the env's after every push"
    out.append(all_full(table, claim, "tracked_ok", AUTOMATA))
    claim = "LTL-DS from a single demonstration reaches red in every pushed episode under every automaton"
    out.append(all_full(table, claim, "success", AUTOMATA))
    return out


TLI_COLOR_TRACING = register_suite(
    Suite(
        name="tli-color-tracing",
        description=(
            "TLI color tracing on ColorTracing-v0: one LPV-DS per tile from a single demonstration, recombined by "
            "the replanning automata (a), (b), (c) under random pushes into the dark region; seeds are experiments."
        ),
        metrics=(
            Metric("success_clean", "success (%) without pushes (red reached)", fmt=".0f"),
            Metric("success", "success (%) under random pushes into D", fmt=".0f"),
            Metric("pushes", "pushes into D per episode", fmt=".1f"),
            Metric(
                "replans",
                "replans per episode (mode changes off the plan: pushes, invariance failures)",
                higher_is_better=False,
                fmt=".1f",
            ),
            Metric("reentry_ok", "pushes whose next tile is the automaton's re-entry tile (%)", fmt=".0f"),
            Metric("tracked_ok", "pushes whose D mode the automaton tracked as the env's (%)", fmt=".0f"),
            Metric("failures", "invariance failures (own exits into D) per episode", higher_is_better=False),
            Metric("violations", "env constraint violations per episode", higher_is_better=False),
            NUM_CUTS,
            Metric("steps", "steps per pushed episode", higher_is_better=False, fmt=".0f"),
        ),
        run_trial=run_color_trial,
        envs=(ENV_ID,),
        methods=AUTOMATA,
        params=ColorTracingParams(),
        trials_param="n_episodes",
        default_seeds=3,
        references=tuple(
            Reference(metric, 100.0, env=ENV_ID, method=a, source=SOURCE)
            for a in AUTOMATA
            for metric in ("success", "reentry_ok")
        ),
        quick={"n_episodes": 2, "n_pushes": 2},
        quick_seeds=1,
        plot="steer_envs.bench.suites.tli_color_tracing.plots:plot_color_tracing",
        findings=color_findings,
    )
)
