"""The TLI robustness protocol: LTL-DS soup scooping under random pushes (thesis §3.7.2, appendix "Multi-modal").

One *experiment* (``scoop_trial``) of the thesis's ten:

* **Demonstrations**: ``n_demos`` (1-3, drawn from ``seed`` when not given),
  segmented by their sensors into the modes a (reach), b (scoop), c
  (transport), d (done). ``demos="drawn"`` (default): hand-drawn-like curves
  (:func:`~steer_envs.data.tli_demos.drawn_scoop_demos`; the thesis's were drawn by hand);
  ``demos="expert"``: the scripted expert
  (:func:`~steer_envs.data.demos.collect_demonstrations`). The expert moves in
  straight lines through the middle of each region, and the per-mode DSs fitted
  to it hardly ever leave a mode: too few invariance failures to test the claim.
* **Policy**: :func:`~steer_envs.baselines.lpv_ds.task_policies.soup_scoop_policy`,
  an :class:`~steer_envs.baselines.lpv_ds.ltl_ds.LTLDSPolicy` - one LPV-DS
  per mode, the soup-scooping GR(1) automaton choosing the mode from the
  sensors, with or without modulation by cuts learned from invariance failures.
* **Perturbations** ("uniformly sampled in all directions of any magnitudes up
  to the dimension of the entire workspace"; Asm. 2: finitely many): up to
  ``n_perturbations`` pushes at distinct random steps in ``[1, push_window]``,
  each a displacement with a uniform direction and a magnitude uniform in
  ``[0, magnitude]`` (default 16, the workspace's side), applied through
  ``env.unwrapped.perturb`` (the state is clipped to the workspace; the soup
  falls off a spoon pushed out of the transport region). A push scheduled
  after the task is done is not applied.
* **Outcome**: *eventual success* = mode d reached within ``max_steps`` (the
  cap stands in for "forever": without modulation the automaton can loop
  between modes, the thesis's first row of Fig. 3.6). ``invariance_failures``
  counts the policy's own unplanned mode exits; each one sends the automaton
  back along its plan, so it is the number of discrete loop iterations.
  ``mode_reentries`` counts entries into a mode already visited in the
  episode (pushes included).

The same ``seed`` gives the same demonstrations, fits, start state and push
schedule with and without modulation, so the two runs are paired.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from steer_envs.baselines.lpv_ds.episodes import soup_scoop_episode
from steer_envs.baselines.lpv_ds.task_policies import soup_scoop_policy
from steer_envs.bench.trials import trial_env
from steer_envs.data.pushes import perturbation_schedule

__all__ = [
    "DS_EPS",
    "ENV_ID",
    "OVERSHOOT",
    "THESIS_SCOOP",
    "WORKSPACE_SIZE",
    "scoop_trial",
]

ENV_ID = "steer_envs/SoupScoop-v0"
#: thesis §3.7.2 / appendix: 10 experiments, all succeed with modulation (no number is given without it).
THESIS_SCOOP: Mapping[str, float] = {"experiments": 10, "success_with_modulation": 1.0}
#: side of SoupScoop's square workspace [-8, 8]^2: the largest push magnitude.
WORKSPACE_SIZE = 16.0
#: LPV-DS stability margin: with LPVDS's default 1e-3 some fitted components contract so slowly that
#: flows stall far from the attractor within an episode; 1.0 (per second) keeps reaching times short.
DS_EPS = 1.0
#: the guard attractors sit this far past the mean crossing point (dt * max_speed = 0.1 < 0.25 < margin 0.4).
OVERSHOOT = 0.25


def scoop_trial(
    seed: int,
    modulation: bool,
    n_perturbations: int = 3,
    *,
    n_demos: int | None = None,
    max_steps: int = 5000,
    push_window: int = 600,
    magnitude: float = WORKSPACE_SIZE,
    demos: str = "drawn",
    ds_eps: float = DS_EPS,
    overshoot: float = OVERSHOOT,
    record: bool = False,
) -> dict[str, Any]:
    """One soup-scooping experiment under random pushes (see the module docstring); a JSON-able dict.

    Args:
        seed: the experiment (demonstrations, fits, start state, pushes).
        modulation: LTL-DS with cuts (True) or the plain DS + automaton (False).
        n_perturbations: pushes scheduled in the episode.
        n_demos: 1-3 demonstrations; default drawn from ``seed``.
        max_steps: episode cap (a run still looping then counts as a failure).
        push_window: pushes happen at steps ``1..push_window``.
        magnitude: largest push length (default: the workspace side, 16).
        demos: ``"drawn"`` (hand-drawn-like curves, default) or ``"expert"`` (the scripted expert).
        ds_eps: stability margin of the LPV-DS fits (see :data:`DS_EPS`).
        overshoot: of the guard attractors (see :func:`~steer_envs.baselines.lpv_ds.ltl_ds.fit_mode_dynamics`).
        record: also return the trajectory, the pushes and the learned cuts (for plots).

    Keys: ``success`` (0/1), ``steps``, ``invariance_failures``, ``mode_reentries``,
    ``pushes`` (applied), ``num_cuts``, ``planned_transitions``, ``n_demos``,
    ``fit_seconds``, ``seconds`` and the inputs (+ ``trajectory``, ``push_log``,
    ``cuts``, ``attractors``, ``events`` with ``record``; the trajectory is a list of
    segments, split at pushes).

    >>> result = scoop_trial(0, True, 1, n_demos=1, max_steps=400)
    >>> result["pushes"] <= 1, result["steps"] <= 400, result["success"] in (0.0, 1.0)
    (True, True, True)
    """
    _check_args(seed, modulation, n_demos, max_steps)
    seed, t0 = int(seed), time.perf_counter()
    if n_demos is None:
        n_demos = int(np.random.default_rng([seed, 31]).integers(1, 4))
    schedule = perturbation_schedule(np.random.default_rng([seed, 17]), n_perturbations, push_window, magnitude)
    fit = {"modulation": modulation, "demos": demos, "ds_eps": ds_eps, "overshoot": overshoot}
    policy, out, fit_seconds = _fit_and_run(seed, n_demos, fit, schedule, max_steps, record)
    inputs = {"seed": seed, "modulation": modulation, "n_perturbations": n_perturbations, "n_demos": n_demos,
              "demos": demos, "max_steps": max_steps}  # fmt: skip
    result = {**inputs, **_outcome(policy, out), "fit_seconds": fit_seconds, "seconds": time.perf_counter() - t0}
    if record:
        result.update(_recorded(policy, out))
    return result


def _fit_and_run(
    seed: int, n_demos: int, fit: dict[str, Any], schedule: Any, max_steps: int, record: bool
) -> tuple[Any, dict[str, Any], float]:
    """The experiment's policy (fitted with the keyword arguments ``fit``), its pushed episode and the fit's time."""
    with threadpool_limits(limits=1):  # tiny numpy/cvxpy problems: extra BLAS threads only add contention
        with trial_env(ENV_ID, max_episode_steps=max_steps) as (env, _):
            t_fit = time.perf_counter()
            policy = soup_scoop_policy(seed, n_demos, env, **fit)
            fit_seconds = time.perf_counter() - t_fit
            out = soup_scoop_episode(env, policy, seed, schedule, max_steps, record)
    return policy, out, fit_seconds


def _check_args(seed: Any, modulation: Any, n_demos: Any, max_steps: Any) -> None:
    """Refuse arguments :func:`scoop_trial` cannot run with."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise TypeError(f"seed must be an int, got {type(seed).__name__}")
    if not isinstance(modulation, bool):
        raise TypeError(f"modulation must be a bool, got {type(modulation).__name__}")
    if n_demos is not None and (not isinstance(n_demos, int) or not 1 <= n_demos <= 10):
        raise ValueError(f"n_demos must be None or an int in [1, 10], got {n_demos!r}")
    if not isinstance(max_steps, int) or max_steps < 1:
        raise ValueError(f"max_steps must be a positive int, got {max_steps!r}")


def _outcome(policy: Any, out: dict[str, Any]) -> dict[str, Any]:
    """The episode's metrics: success, steps, failures, planned transitions, re-entries, pushes, cuts."""
    events = policy.events
    visited: set[str] = {out["first_mode"]}
    reentries = 0
    for ev in events:
        reentries += ev.target in visited
        visited.add(ev.target)
    return {
        "success": float(out["success"]),
        "steps": out["steps"],
        "invariance_failures": sum(ev.kind == "failure" for ev in events),
        "planned_transitions": sum(ev.kind == "planned" for ev in events),
        "mode_reentries": reentries,
        "pushes": len(out["push_log"]),
        "num_cuts": policy.num_cuts,
    }


def _recorded(policy: Any, out: dict[str, Any]) -> dict[str, Any]:
    """The trajectory, the pushes, the learned cuts, the attractors and the mode events (for plots)."""
    return {
        "trajectory": out["trajectory"],
        "push_log": out["push_log"],
        "cuts": {
            m: [{"point": c.point.tolist(), "normal": c.normal.tolist()} for c in cs.cuts]
            for m, cs in policy.cut_sets.items()
            if len(cs)
        },
        "attractors": {m: policy.dynamics[m].attractor.tolist() for m in policy.modes},
        "events": [
            {"step": ev.step, "from": ev.source, "to": ev.target, "kind": ev.kind, "before": ev.before.tolist()}
            for ev in policy.events
        ],
    }
