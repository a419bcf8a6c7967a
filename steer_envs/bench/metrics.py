"""Metrics (and their references) that several suites declare alike.

* data suites (one trial builds one shard): :data:`BUILT`; skill-data suites also
  :data:`SKILL_OUTCOME_METRICS` (:func:`skill_outcomes` computes them);
* skill-steering suites (thesis Tables 2.2, 2.3): the alignment / success quadrants :data:`QUADRANT_METRICS`;
* robot-experiment suites (thesis ch. 3): :data:`NUM_CUTS`;
* Maze2D steering suites (thesis Table 2.1 and beyond): :data:`MAZE_STEERING_METRICS`;
* a thesis table ``{method: {metric: value}}`` as references: :func:`table_references`;
* policy suites that evaluate without and with perturbations (thesis Tables 4.1, 4.3):
  :func:`evaluation_metrics` (the columns of the two evaluations), :data:`EVAL_SECONDS`,
  :func:`train_seconds` and :func:`success_references` (the thesis's success rates beside them).

>>> evaluation_metrics({"success_rate": 0.9, "violation_rate": 0.0}, {"success_rate": 0.5, "violation_rate": 0.1})
{'success': 0.9, 'success_perturbed': 0.5, 'violation': 0.0, 'violation_perturbed': 0.1}
>>> success_references({"bc": {"can": (0.93, 0.20)}}, lambda task: task, "thesis Table 4.3")[1].metric
'success_perturbed'
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from steer_envs.bench.suite import Metric, Reference

__all__ = [
    "BUILT",
    "EVAL_SECONDS",
    "MAZE_STEERING_METRICS",
    "NUM_CUTS",
    "QUADRANT_METRICS",
    "SHARE",
    "SKILL_OUTCOME_METRICS",
    "evaluation_metrics",
    "skill_outcomes",
    "success_references",
    "table_references",
    "train_seconds",
]

#: a data suite's trial built its shard (0: found on disk)
BUILT = Metric("built", "the shard was built by this trial (0: found on disk)", kind="timing", fmt=".0f")
#: a skill-data suite's shard: how its recorded skills ended (:func:`skill_outcomes`)
SKILL_OUTCOME_METRICS: tuple[Metric, ...] = (
    Metric("skill_success", "skills whose outcome the world shows at their end", fmt=".2f"),
    Metric("violations", "skills that reported a constraint violation", higher_is_better=False, fmt=".2f"),
)
#: cuts a robot experiment learned from invariance failures
NUM_CUTS = Metric("num_cuts", "cuts learned over the trial", higher_is_better=False, fmt=".1f")
#: what a skill-steering suite's TA and CS are a share of
SHARE = "share of the trial's interactions"
#: the thesis's quadrants of a skill-steering suite: aligned / misaligned x success / failure
QUADRANT_METRICS: tuple[Metric, ...] = (
    Metric("AS", "aligned success", fmt=".2f"),
    Metric("AF", "aligned failure", higher_is_better=False, fmt=".2f"),
    Metric("MS", "misaligned success", higher_is_better=False, fmt=".2f"),
    Metric("MF", "misaligned failure", higher_is_better=False, fmt=".2f"),
)
#: one Maze2D steering call scored as Table 2.1 (:func:`steer_envs.steering.maze.steering_trial`)
MAZE_STEERING_METRICS: tuple[Metric, ...] = (
    Metric("min_l2", "L2 of the picked plan to the sketch / maze extent", higher_is_better=False, fmt=".3f"),
    Metric("avg_l2", "batch-mean L2 to the sketch / maze extent", higher_is_better=False, fmt=".3f"),
    Metric("collision", "fraction of the batch with a waypoint in a wall", higher_is_better=False, fmt=".3f"),
    Metric(
        "latency_ms", "ms per steering call (batch 32)", kind="timing", higher_is_better=False, fmt=".1f", goal=250.0
    ),
    Metric(
        "ss_gd_latency",
        "SS / GD time per call, back to back",
        kind="timing",
        higher_is_better=False,
        fmt=".2f",
        goal=4.5,
    ),
    Metric("network_evals", "denoiser calls per steering call", higher_is_better=False, fmt=".0f"),
)
#: the wall time of a policy's two evaluations
EVAL_SECONDS = Metric(
    "eval_seconds", "both evaluations' wall time (s)", kind="timing", higher_is_better=False, fmt=".1f"
)


def train_seconds(description: str, goal: float | None = None) -> Metric:
    """The ``train_seconds`` metric (a timing, lower is better) described as ``description``."""
    return Metric("train_seconds", description, kind="timing", higher_is_better=False, fmt=".1f", goal=goal)


def skill_outcomes(records: Sequence[Any]) -> dict[str, float]:
    """The :data:`SKILL_OUTCOME_METRICS` of skill records (each with ``success`` and ``violation``; none: 0).

    >>> from types import SimpleNamespace as R
    >>> skill_outcomes([R(success=True, violation=False), R(success=False, violation=False)])
    {'skill_success': 0.5, 'violations': 0.0}
    """
    n = max(len(records), 1)
    return {
        "skill_success": sum(r.success for r in records) / n,
        "violations": sum(r.violation for r in records) / n,
    }


def evaluation_metrics(clean: Mapping[str, Any], perturbed: Mapping[str, Any]) -> dict[str, float]:
    """Success and invalid-transition rates of an evaluation without (``clean``) and with the perturbations."""
    return {
        "success": clean["success_rate"],
        "success_perturbed": perturbed["success_rate"],
        "violation": clean["violation_rate"],
        "violation_perturbed": perturbed["violation_rate"],
    }


def success_references(
    table: Mapping[str, Mapping[Any, tuple[float, float]]],
    env_of: Callable[[Any], str],
    source: str,
    *,
    drop: bool = False,
) -> tuple[Reference, ...]:
    """A thesis table ``{method: {cell: (success, success +perturb)}}`` as references, ``env_of(cell)`` the env.

    ``drop`` adds the success lost to the perturbations (``success_drop``).
    """
    refs = []
    for method, cells in table.items():
        for cell, (plain, perturbed) in cells.items():
            values = {"success": plain, "success_perturbed": perturbed}
            if drop:
                values["success_drop"] = plain - perturbed
            refs += [Reference(m, v, env=env_of(cell), method=method, source=source) for m, v in values.items()]
    return tuple(refs)


def table_references(
    table: Mapping[str, Mapping[str, float]], *, source: str, env: str | None = None
) -> tuple[Reference, ...]:
    """A thesis table as references: ``{method: {metric: value}}``, each for ``env`` (``None``: any env).

    >>> table_references({"DP-SS": {"TA": 0.71, "CS": 0.73}}, source="thesis Table 2.3")[1]
    Reference(metric='CS', value=0.73, env=None, method='DP-SS', source='thesis Table 2.3')
    """
    return tuple(
        Reference(metric, value, env=env, method=method, source=source)
        for method, values in table.items()
        for metric, value in values.items()
    )
