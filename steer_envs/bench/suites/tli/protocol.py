"""The TLI single-mode study (thesis §3.7.1, appendix "Single-mode Experiments") as a pure function.

One trial = one random convex mode (ConvexMode-v0 with ``layout_seed``), 1-3
demonstrations, one policy kind (``"bc"``, ``"bc+mod"``, ``"ds"``,
``"ds+mod"``) and ``n_starts`` start states. The pieces live in the library:

* **Demonstrations**: :func:`~steer_envs.data.tli_demos.convex_mode_demos`
  (``demos="drawn"``: simulated hand-drawn Bezier curves, the default;
  ``"expert"``: the scripted expert).
* **Policies**: :func:`~steer_envs.baselines.lpv_ds.single_mode.fitted_policy`
  (LPV-DS with the mode's attractor, or BC for ``bc_epochs``).
* **Starts**: :func:`~steer_envs.baselines.lpv_ds.single_mode.sample_starts`, a
  random demonstration point + ``N(0, noise_sigma^2 I)`` inside the mode;
  ``noise_sigma`` in {0, 1, 5} is the thesis's 0 / 5 / 30 % of the workspace.
* **Rollout**: :func:`~steer_envs.baselines.lpv_ds.single_mode.rollout`
  (ConvexMode-v0's dynamics, 1000 steps; success = never left the mode and
  ``|x_T - x*| < 0.4``).
* **Cuts** (``+mod``): :func:`~steer_envs.baselines.lpv_ds.single_mode.cut_loop`
  on the evaluation batch until no start leaves the mode or ``max_cuts`` (4)
  cuts exist; the last round is the result, each round's success is reported
  (the thesis's success-vs-cuts curve). With ``cut_sigma`` set, the cut rounds
  use fresh batches with that noise instead (the public code's variant, sigma
  5) and the evaluation batch is held out.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from steer_envs.baselines.lpv_ds.single_mode import DS_EPS, N_STEPS, cut_loop, fitted_policy, rollout, sample_starts
from steer_envs.core.validation import integer

__all__ = ["POLICY_KINDS", "THESIS_SUCCESS", "single_mode_trial"]

POLICY_KINDS: tuple[str, ...] = ("bc", "bc+mod", "ds", "ds+mod")
#: thesis Fig. 3.5 table: success (%) at noise 0 / 5 / 30 % of the workspace.
THESIS_SUCCESS: dict[str, tuple[float, float, float]] = {
    "bc": (88.9, 72.4, 58.6),
    "bc+mod": (91.9, 83.6, 76.0),
    "ds": (100.0, 97.0, 86.9),
    "ds+mod": (100.0, 100.0, 100.0),
}


def single_mode_trial(
    layout_seed: int,
    noise_sigma: float,
    policy_kind: str,
    n_starts: int = 100,
    seed: int = 0,
    *,
    n_demos: int | None = None,
    bc_epochs: int = 4000,
    max_cuts: int = 4,
    cut_sigma: float | None = None,
    n_steps: int = N_STEPS,
    demos: str = "drawn",
    ds_eps: float = DS_EPS,
) -> dict[str, Any]:
    """One trial of the single-mode study; returns a JSON-able dict of metrics.

    Args:
        layout_seed: the convex mode (ConvexMode-v0 geometry).
        noise_sigma: std of the start-state noise (thesis: 0, 1, 5).
        policy_kind: ``"bc"``, ``"bc+mod"``, ``"ds"`` or ``"ds+mod"``.
        n_starts: starts per batch (thesis: 100).
        seed: seed of start sampling and of the policy fit.
        n_demos: 1-3 demonstrations; default drawn from ``layout_seed``.
        bc_epochs: BC training epochs.
        max_cuts: most cuts the cut loop may add (``+mod`` only).
        cut_sigma: None: learn cuts on the evaluation batch (thesis); a float: on
            separate batches with this noise (held-out evaluation).
        n_steps: rollout length.
        demos: ``"drawn"`` (simulated hand-drawn curves, default) or ``"expert"``.
        ds_eps: LPV-DS stability margin (``A_k^T P + P A_k <= -eps I``); see
            :data:`~steer_envs.baselines.lpv_ds.single_mode.DS_EPS`.

    Keys: ``success_rate``, ``invariance_failure_rate`` (left the mode),
    ``reachability_failure_rate`` (stayed but missed the attractor), ``num_cuts``,
    ``cuts_until_invariant`` (cuts after which a cut round had no failure; None
    if never), ``cut_round_success`` (success of each cut round), ``n_demos``,
    ``fit_seconds``, ``seconds`` and the inputs.

    >>> result = single_mode_trial(0, 1.0, "ds+mod", n_starts=4, n_demos=1, n_steps=200)
    >>> result["policy_kind"], 0.0 <= result["success_rate"] <= 1.0, result["num_cuts"] <= 4
    ('ds+mod', True, True)
    """
    n_steps = _check_args(policy_kind, noise_sigma, n_starts, max_cuts, n_steps, ds_eps)
    t0 = time.perf_counter()
    if n_demos is None:
        n_demos = int(np.random.default_rng([layout_seed, 31]).integers(1, 4))
    base_kind = policy_kind.split("+")[0]
    t_fit = time.perf_counter()
    policy, model, xs = fitted_policy(
        int(layout_seed), int(n_demos), base_kind, int(bc_epochs), int(seed), demos, float(ds_eps)
    )
    fit_seconds = time.perf_counter() - t_fit
    rng = np.random.default_rng([int(seed), int(layout_seed), 1])
    max_cuts_used = max_cuts if policy_kind.endswith("+mod") else None
    loop, res = _cut_and_roll_out(policy, model, np.concatenate(xs), rng, float(noise_sigma), cut_sigma, n_starts,
                                  max_cuts=max_cuts_used, n_steps=n_steps)  # fmt: skip
    inputs = {"layout_seed": int(layout_seed), "noise_sigma": float(noise_sigma), "policy_kind": policy_kind,
              "n_starts": n_starts, "seed": int(seed), "n_demos": int(n_demos), "demos": demos}  # fmt: skip
    return {**inputs, **_outcome(res, loop), "fit_seconds": fit_seconds, "seconds": time.perf_counter() - t0}


def _outcome(res: dict[str, Any], loop: Any) -> dict[str, Any]:
    """The final rollout's success and failure rates, and what the cut loop learned."""
    left, success = res["left"], res["success"]
    return {
        "success_rate": float(success.mean()),
        "invariance_failure_rate": float(left.mean()),
        "reachability_failure_rate": float((~left & ~success).mean()),
        "num_cuts": len(loop.cuts),
        "cuts_until_invariant": loop.cuts_until_invariant,
        "cut_round_success": loop.round_success,
    }


def _cut_and_roll_out(
    policy: Any,
    model: Any,
    demo_points: np.ndarray,
    rng: np.random.Generator,
    noise_sigma: float,
    cut_sigma: float | None,
    n_starts: int,
    *,
    max_cuts: int | None,
    n_steps: int,
) -> tuple[Any, dict[str, Any]]:
    """The evaluation batch, the cut loop on it (or on fresh ``cut_sigma`` batches) and the batch's final rollout."""
    starts = sample_starts(model, demo_points, noise_sigma, n_starts, rng)
    batch_fn = None if cut_sigma is None else (lambda: sample_starts(model, demo_points, cut_sigma, n_starts, rng))
    loop = cut_loop(policy, model, starts, max_cuts=max_cuts, batch_fn=batch_fn, n_steps=n_steps)
    res = loop.last_rollout
    if cut_sigma is not None or res is None:  # else the last cut round already rolled out `starts`
        res = rollout(loop.policy, model, starts, n_steps)
    return loop, res


def _check_args(policy_kind: str, noise_sigma: float, n_starts: int, max_cuts: int, n_steps: int, ds_eps: float) -> int:
    """Refuse arguments :func:`single_mode_trial` cannot run with; returns ``n_steps`` as an int."""
    if policy_kind not in POLICY_KINDS:
        raise ValueError(f"policy_kind must be one of {POLICY_KINDS}, got {policy_kind!r}")
    if not (np.isfinite(noise_sigma) and noise_sigma >= 0):
        raise ValueError(f"noise_sigma must be a finite float >= 0, got {noise_sigma!r}")
    if not isinstance(n_starts, int) or n_starts < 1:
        raise ValueError(f"n_starts must be a positive int, got {n_starts!r}")
    if not isinstance(max_cuts, int) or max_cuts < 0:
        raise ValueError(f"max_cuts must be an int >= 0, got {max_cuts!r}")
    n_steps = integer(n_steps, "n_steps", low=1, owner="single_mode_trial")
    if not (np.isfinite(ds_eps) and ds_eps > 0):
        raise ValueError(f"ds_eps must be a finite float > 0, got {ds_eps!r}")
    return n_steps
