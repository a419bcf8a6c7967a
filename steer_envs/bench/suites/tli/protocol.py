"""The TLI single-mode study (thesis §3.7.1, appendix "Single-mode Experiments") as a pure function.

One trial = one random convex mode (ConvexMode-v0 with ``layout_seed``), 1-3
demonstrations, one policy kind (``"bc"``,
``"bc+mod"``, ``"ds"``, ``"ds+mod"``) and ``n_starts`` start states:

* **Demonstrations** (``demos="drawn"``, default): the thesis's demos were drawn
  by hand, curving through the mode from its left-most vertex to the attractor.
  They are simulated as cubic Bezier curves from ``demo_start`` to the
  attractor whose two inner control points are drawn uniformly inside the
  mode (a Bezier curve lies in the convex hull of its control points, so in
  the convex mode), 200 samples of ``dt = 0.01`` with a speed decreasing
  linearly to 0 at the attractor; velocities are the exact derivatives.
  ``demos="expert"`` uses the ConvexMode scripted expert instead (a saturated
  straight-line flow to the attractor, run for 200 steps; the first demo
  starts at ``demo_start``, further ones at ``demo_start + N(0, 0.5^2 I)``).
* **Policies**: :class:`~steer_envs.baselines.lpv_ds.lpvds.LPVDS` with the mode's
  attractor, or :class:`~steer_envs.baselines.bc.modeling.BCPolicy` with its
  defaults (2x100 ReLU, tanh x 50, Adam 1e-3, batch 512) for ``bc_epochs`` (4000).
* **Starts**: a random demonstration point + ``N(0, noise_sigma^2 I)``,
  redrawn until inside the mode; ``noise_sigma`` in {0, 1, 5} is the thesis's
  0 / 5 / 30 % of the workspace.
* **Rollout**: forward Euler, ``dt = 0.01``, 1000 steps, ``|x'| <= 20``, state
  clipped to the workspace (exactly ConvexMode-v0's dynamics, vectorised).
  Success = never left the mode and ``|x_T - x*| < 0.4``.
* **Cuts** (``+mod``), "iteratively sample a failure state and add a cut until
  all invariance failures are corrected": the evaluation batch is rolled out,
  its first failing start (draw order; one whose last in-mode state is not
  already a cut point) adds a cut and all cuts are re-solved (QCQP),
  and the batch is rolled out again, until no start leaves the mode or
  ``max_cuts`` (4) cuts exist; the last round is the result, each round's
  success is reported (the thesis's success-vs-cuts curve). With
  ``cut_sigma`` set, the cut rounds use fresh batches with that noise instead
  (the public code's variant, sigma 5) and the evaluation batch is held out.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from steer_envs.baselines.bc.modeling import BCConfig, BCPolicy
from steer_envs.baselines.lpv_ds.lpvds import LPVDS
from steer_envs.core.policy import VelocityPolicy
from steer_envs.core.validation import BoundExceeded, integer, real_scalar
from steer_envs.wrappers.ds_modulation import CutSet, FailureRecord, ModulatedPolicy, resolve_cuts

__all__ = ["POLICY_KINDS", "THESIS_SUCCESS", "convex_mode_demos", "rollout", "sample_starts", "single_mode_trial"]

POLICY_KINDS: tuple[str, ...] = ("bc", "bc+mod", "ds", "ds+mod")
#: thesis Fig. 3.5 table: success (%) at noise 0 / 5 / 30 % of the workspace.
THESIS_SUCCESS: dict[str, tuple[float, float, float]] = {
    "bc": (88.9, 72.4, 58.6),
    "bc+mod": (91.9, 83.6, 76.0),
    "ds": (100.0, 97.0, 86.9),
    "ds+mod": (100.0, 100.0, 100.0),
}
DT = 0.01
MAX_SPEED = 20.0
N_STEPS = 1000
DEMO_STEPS = 200
SUCCESS_RADIUS = 0.4
#: LPV-DS stability margin of the single-mode study. The library default (1e-3) lets the LMI fit return
#: nearly marginal A_k on some layouts, whose flows stall short of the attractor within N_STEPS;
#: eps = 1.0 makes every flow contract at a rate the rollout length can resolve.
DS_EPS = 1.0
#: draws of a rejection-sampling loop (a start, a control point inside the mode) before it gives up.
MAX_DRAWS = 100_000


def _make_env(layout_seed: int) -> gym.Env:
    import steer_envs  # noqa: F401 - registers the ids

    return gym.make("steer_envs/ConvexMode-v0", layout_seed=layout_seed)


def convex_mode_demos(
    layout_seed: int, n_demos: int, steps: int = DEMO_STEPS, demos: str = "drawn"
) -> tuple[list[np.ndarray], list[np.ndarray], Any]:
    """``n_demos`` demonstrations of a ConvexMode layout: (states list, velocities list, model); see module doc.

    >>> xs, vs, model = convex_mode_demos(0, 2)
    >>> len(xs), xs[0].shape, bool(model.inside(xs[0]).all())
    (2, (200, 2), True)
    """
    if not isinstance(n_demos, int) or n_demos < 1:
        raise ValueError(f"n_demos must be a positive int, got {n_demos!r}")
    steps = integer(steps, "steps", low=2, owner="convex_mode_demos")
    if demos == "drawn":
        return _drawn_demos(layout_seed, n_demos, steps)
    if demos != "expert":
        raise ValueError(f"demos must be 'drawn' or 'expert', got {demos!r}")
    from steer_envs.data.experts import make_expert

    env = _make_env(layout_seed)
    base: Any = env.unwrapped
    model = base.model
    expert = make_expert(env)
    rng = np.random.default_rng([layout_seed, 7919])
    xs, vs = [], []
    for i in range(n_demos):
        start = model.demo_start.copy()
        for _ in range(MAX_DRAWS if i > 0 else 0):
            cand = model.demo_start + rng.normal(0.0, 0.5, size=2)
            if model.inside(cand[None])[0]:
                start = cand
                break
        else:
            if i > 0:
                raise BoundExceeded(
                    f"convex_mode_demos: no start of demo {i} inside the mode within MAX_DRAWS={MAX_DRAWS} draws"
                )
        obs, info = base.reset(options={"state": start})
        expert.reset(obs, info)
        states, actions = [], []
        for _ in range(steps):  # the unwrapped env keeps stepping after success: full convergence
            action = np.asarray(expert.act(obs, info), dtype=np.float64)
            states.append(base.state)
            actions.append(action)
            obs, _, _, _, info = base.step(action.astype(np.float32))
        xs.append(np.asarray(states))
        vs.append(np.asarray(actions))
    env.close()
    return xs, vs, model


def _drawn_demos(layout_seed: int, n_demos: int, steps: int) -> tuple[list[np.ndarray], list[np.ndarray], Any]:
    """Simulated hand-drawn demos: cubic Bezier curves inside the mode (see the module docstring)."""
    env = _make_env(layout_seed)
    model: Any = env.unwrapped.model  # type: ignore[attr-defined]
    env.close()
    rng = np.random.default_rng([layout_seed, 104729])
    lo, hi = model.vertices.min(axis=0), model.vertices.max(axis=0)
    tau = np.arange(steps) / (steps - 1)
    duration = DT * (steps - 1)
    s = 1.0 - (1.0 - tau) ** 2  # progress along the curve: speed falls linearly to 0
    ds_dt = 2.0 * (1.0 - tau) / duration
    xs, vs = [], []
    for _ in range(n_demos):
        ctrl: list[np.ndarray] = []
        for _ in range(MAX_DRAWS):
            if len(ctrl) == 2:
                break
            cand = rng.uniform(lo, hi)
            if model.inside(cand[None])[0]:
                ctrl.append(cand)
        if len(ctrl) < 2:
            raise BoundExceeded(
                f"convex_mode_demos: no control points inside the mode within MAX_DRAWS={MAX_DRAWS} draws"
            )
        p0, p1, p2, p3 = model.demo_start, ctrl[0], ctrl[1], model.attractor
        b = s[:, None]
        x = (1 - b) ** 3 * p0 + 3 * (1 - b) ** 2 * b * p1 + 3 * (1 - b) * b**2 * p2 + b**3 * p3
        dx_ds = 3 * (1 - b) ** 2 * (p1 - p0) + 6 * (1 - b) * b * (p2 - p1) + 3 * b**2 * (p3 - p2)
        xs.append(x)
        vs.append(dx_ds * ds_dt[:, None])
    return xs, vs, model


@functools.lru_cache(maxsize=8)
def fitted_policy(
    layout_seed: int, n_demos: int, kind: str, bc_epochs: int, seed: int, demos: str, ds_eps: float = DS_EPS
) -> tuple[Any, Any, tuple[np.ndarray, ...]]:
    """(policy, model, demos) of a layout's single-mode study; cached so noise levels share one fit.

    ``demos`` is a tuple of ``(T, 2)`` arrays, one per demonstration (shared by the cache: do not modify).
    """
    xs, vs, model = convex_mode_demos(layout_seed, n_demos, demos=demos)
    if kind == "ds":
        policy: Any = LPVDS(eps=ds_eps, random_state=seed).fit(xs, vs, attractor=model.attractor)
    else:
        policy = BCPolicy(BCConfig(epochs=bc_epochs), seed=seed)
        policy.fit(np.concatenate(xs), np.concatenate(vs))
    return policy, model, tuple(xs)


def sample_starts(model: Any, demo_points: np.ndarray, sigma: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` starts: a random demo point + ``N(0, sigma^2 I)``, redrawn until inside the mode.

    Gives up with :class:`~steer_envs.core.validation.BoundExceeded` after :data:`MAX_DRAWS` rounds.
    """
    sigma = real_scalar(sigma, "sigma", low=0.0, owner="sample_starts")
    n = integer(n, "n", low=0, owner="sample_starts")
    out = np.empty((n, 2))
    todo = np.arange(n)
    for _ in range(MAX_DRAWS):
        if len(todo) == 0:
            return out
        cand = demo_points[rng.integers(0, len(demo_points), size=len(todo))]
        cand = cand + rng.normal(0.0, sigma, size=cand.shape)
        ok = model.inside(cand)
        out[todo[ok]] = cand[ok]
        todo = todo[~ok]
    if len(todo) == 0:
        return out
    raise BoundExceeded(
        f"sample_starts: {len(todo)} of {n} start states not inside the mode within MAX_DRAWS={MAX_DRAWS} rounds "
        f"(sigma={sigma})"
    )


def rollout(policy: VelocityPolicy, model: Any, starts: np.ndarray, n_steps: int = N_STEPS) -> dict[str, np.ndarray]:
    """Integrate ``policy`` from ``starts`` with ConvexMode's dynamics; per-start outcome arrays.

    Returns ``final`` ``(N, 2)``, ``left`` (left the mode), ``success``,
    ``exit_step`` (-1 if never), ``last_in`` and ``first_out`` ``(N, 2)`` (NaN if never).
    """
    n_steps = integer(n_steps, "n_steps", low=0, owner="rollout")
    x = np.asarray(starts, dtype=np.float64).copy()
    n = len(x)
    left = np.zeros(n, dtype=bool)
    exit_step = np.full(n, -1)
    last_in = np.full((n, 2), np.nan)
    first_out = np.full((n, 2), np.nan)
    for t in range(n_steps):
        v = np.asarray(policy(x), dtype=np.float64)
        speed = np.linalg.norm(v, axis=1, keepdims=True)
        v = v * np.minimum(1.0, MAX_SPEED / np.maximum(speed, 1e-300))
        nxt = np.clip(x + DT * v, model.low, model.high)
        out = ~model.inside(nxt) & ~left
        if out.any():
            left |= out
            exit_step[out] = t
            last_in[out] = x[out]
            first_out[out] = nxt[out]
        x = nxt
    reached = np.linalg.norm(x - model.attractor, axis=1) < SUCCESS_RADIUS
    return {
        "final": x,
        "left": left,
        "success": reached & ~left,
        "exit_step": exit_step,
        "last_in": last_in,
        "first_out": first_out,
    }


@dataclass
class CutLoopResult:
    """What :func:`cut_loop` learned: the acting policy, its cuts and the rounds it took."""

    policy: VelocityPolicy
    cuts: CutSet
    failures: list[FailureRecord]
    round_success: list[float]
    cuts_until_invariant: int | None
    last_rollout: dict[str, np.ndarray] | None


def cut_loop(
    policy: VelocityPolicy,
    model: Any,
    starts: np.ndarray,
    *,
    max_cuts: int | None,
    batch_fn: Callable[[], np.ndarray] | None = None,
    n_steps: int = N_STEPS,
) -> CutLoopResult:
    """The thesis cut loop: roll out, cut the batch's first new invariance failure, repeat.

    ``max_cuts=None`` means no modulation (the policy acts as is, nothing is
    rolled out). Each round rolls out ``starts`` (or a fresh ``batch_fn()``) and
    stops when no start leaves the mode, after ``max_cuts`` cuts, or when every
    failure repeats a known one (a further cut would add nothing).
    """
    cuts = CutSet(model.attractor)
    if max_cuts is None:
        return CutLoopResult(policy, cuts, [], [], None, None)
    # every round that does not stop adds one cut, so the loop runs at most max_cuts + 1 rounds
    max_cuts = integer(max_cuts, "max_cuts", low=0, owner="cut_loop")
    acting = ModulatedPolicy(policy, cuts, max_speed=MAX_SPEED)
    failures: list[FailureRecord] = []
    round_success: list[float] = []
    for _ in range(max_cuts + 1):
        batch = starts if batch_fn is None else batch_fn()
        res = rollout(acting, model, batch, n_steps)
        round_success.append(float(res["success"].mean()))
        if not res["left"].any():
            return CutLoopResult(acting, cuts, failures, round_success, len(cuts), res if batch_fn is None else None)
        # a failure is new unless an earlier one had the same last in-mode *and* failure state (a start on
        # its own cut can slide along it out of the mode: that exit gets a second cut through the same point)
        known = np.array([np.concatenate([fr.last_in_mode, fr.failure]) for fr in failures]).reshape(-1, 4)
        pairs = np.concatenate([res["last_in"], res["first_out"]], axis=1)
        fresh = [i for i in np.nonzero(res["left"])[0] if not np.any(np.linalg.norm(known - pairs[i], axis=1) < 1e-9)]
        if len(cuts) >= max_cuts or not fresh:
            return CutLoopResult(acting, cuts, failures, round_success, None, res if batch_fn is None else None)
        first = int(fresh[0])  # the batch's first failing start (in draw order)
        failures.append(FailureRecord(res["last_in"][first], res["first_out"][first], batch[first]))
        cuts.set_cuts(resolve_cuts(failures, model.attractor))
    raise BoundExceeded(f"cut_loop: no verdict after max_cuts + 1 = {max_cuts + 1} rounds")  # pragma: no cover


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
        ds_eps: LPV-DS stability margin (``A_k^T P + P A_k <= -eps I``); see :data:`DS_EPS`.

    Keys: ``success_rate``, ``invariance_failure_rate`` (left the mode),
    ``reachability_failure_rate`` (stayed but missed the attractor), ``num_cuts``,
    ``cuts_until_invariant`` (cuts after which a cut round had no failure; None
    if never), ``cut_round_success`` (success of each cut round), ``n_demos``,
    ``fit_seconds``, ``seconds`` and the inputs.

    >>> result = single_mode_trial(0, 1.0, "ds+mod", n_starts=4, n_demos=1, n_steps=200)
    >>> result["policy_kind"], 0.0 <= result["success_rate"] <= 1.0, result["num_cuts"] <= 4
    ('ds+mod', True, True)
    """
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
    t0 = time.perf_counter()
    if n_demos is None:
        n_demos = int(np.random.default_rng([layout_seed, 31]).integers(1, 4))
    base_kind = policy_kind.split("+")[0]
    t_fit = time.perf_counter()
    policy, model, xs = fitted_policy(
        int(layout_seed), int(n_demos), base_kind, int(bc_epochs), int(seed), demos, float(ds_eps)
    )
    fit_seconds = time.perf_counter() - t_fit
    demo_points = np.concatenate(xs)
    rng = np.random.default_rng([int(seed), int(layout_seed), 1])

    starts = sample_starts(model, demo_points, float(noise_sigma), n_starts, rng)
    batch_fn = None if cut_sigma is None else (lambda: sample_starts(model, demo_points, cut_sigma, n_starts, rng))
    loop = cut_loop(
        policy,
        model,
        starts,
        max_cuts=max_cuts if policy_kind.endswith("+mod") else None,
        batch_fn=batch_fn,
        n_steps=n_steps,
    )
    acting, cuts, res = loop.policy, loop.cuts, loop.last_rollout
    round_success, cuts_until_invariant = loop.round_success, loop.cuts_until_invariant
    if cut_sigma is not None or res is None:  # else the last cut round already rolled out `starts`
        res = rollout(acting, model, starts, n_steps)
    left, success = res["left"], res["success"]
    return {
        "layout_seed": int(layout_seed),
        "noise_sigma": float(noise_sigma),
        "policy_kind": policy_kind,
        "n_starts": n_starts,
        "seed": int(seed),
        "n_demos": int(n_demos),
        "demos": demos,
        "success_rate": float(success.mean()),
        "invariance_failure_rate": float(left.mean()),
        "reachability_failure_rate": float((~left & ~success).mean()),
        "num_cuts": len(cuts),
        "cuts_until_invariant": cuts_until_invariant,
        "cut_round_success": round_success,
        "fit_seconds": fit_seconds,
        "seconds": time.perf_counter() - t0,
    }
