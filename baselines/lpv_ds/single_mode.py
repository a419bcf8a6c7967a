"""The single-mode invariance study (thesis §3.7.1): fit, start states, rollout and the cut loop on ConvexMode.

* **Policies** (:func:`fitted_policy`): :class:`~steer_envs.baselines.lpv_ds.lpvds.LPVDS`
  with the mode's attractor, or :class:`~steer_envs.baselines.bc.modeling.BCPolicy`
  with its defaults (2x100 ReLU, tanh x 50, Adam 1e-3, batch 512), fitted on
  :func:`~steer_envs.data.tli_demos.convex_mode_demos`.
* **Starts** (:func:`sample_starts`): a random demonstration point +
  ``N(0, sigma^2 I)``, redrawn until inside the mode.
* **Rollout** (:func:`rollout`): forward Euler, ``dt = 0.01``, 1000 steps,
  ``|x'| <= 20``, state clipped to the workspace (exactly ConvexMode-v0's
  dynamics, vectorised). Success = never left the mode and ``|x_T - x*| < 0.4``.
* **Cuts** (:func:`cut_loop`), "iteratively sample a failure state and add a
  cut until all invariance failures are corrected": the batch is rolled out,
  its first failing start (draw order; one whose last in-mode state is not
  already a cut point) adds a cut and all cuts are re-solved (QCQP), and the
  batch is rolled out again, until no start leaves the mode or ``max_cuts``
  cuts exist; each round's success is reported (the thesis's success-vs-cuts
  curve).

>>> import numpy as np
>>> policy, model, xs = fitted_policy(0, 1, "ds", 10, 0, "drawn")
>>> res = rollout(policy, model, xs[0][:3], n_steps=50)
>>> sorted(res), res["final"].shape
(['exit_step', 'final', 'first_out', 'last_in', 'left', 'success'], (3, 2))
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.baselines.bc.modeling import BCConfig, BCPolicy
from steer_envs.baselines.lpv_ds.cuts import CutSet, FailureRecord, resolve_cuts
from steer_envs.baselines.lpv_ds.lpvds import LPVDS
from steer_envs.baselines.lpv_ds.modulation import ModulatedPolicy
from steer_envs.core.policy import VelocityPolicy
from steer_envs.core.rejection import rejection_sample
from steer_envs.core.validation import BoundExceeded, integer, real_scalar
from steer_envs.data.tli_demos import convex_mode_demos

__all__ = [
    "DS_EPS",
    "DT",
    "MAX_SPEED",
    "N_STEPS",
    "SUCCESS_RADIUS",
    "CutLoopResult",
    "cut_loop",
    "fitted_policy",
    "rollout",
    "sample_starts",
]

#: ConvexMode-v0's time step, speed limit; the rollout length and the success radius of the study.
DT = 0.01
MAX_SPEED = 20.0
N_STEPS = 1000
SUCCESS_RADIUS = 0.4
#: LPV-DS stability margin of the single-mode study. The library default (1e-3) lets the LMI fit return
#: nearly marginal A_k on some layouts, whose flows stall short of the attractor within N_STEPS;
#: eps = 1.0 makes every flow contract at a rate the rollout length can resolve.
DS_EPS = 1.0
#: rounds of the start-state rejection sampling before it gives up.
MAX_DRAWS = 100_000


@functools.lru_cache(maxsize=8)
def fitted_policy(
    layout_seed: int, n_demos: int, kind: str, bc_epochs: int, seed: int, demos: str, ds_eps: float = DS_EPS
) -> tuple[Any, Any, tuple[np.ndarray, ...]]:
    """(policy, model, demos) of a layout's single-mode study; cached so noise levels share one fit.

    ``kind`` is ``"ds"`` (LPV-DS) or anything else (BC for ``bc_epochs``). ``demos`` is the demonstration
    source of :func:`~steer_envs.data.tli_demos.convex_mode_demos`; the returned demos are a tuple of
    ``(T, 2)`` arrays, one per demonstration (shared by the cache: do not modify).
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

    def draw(m: int) -> np.ndarray:
        cand = demo_points[rng.integers(0, len(demo_points), size=m)]
        return cand + rng.normal(0.0, sigma, size=cand.shape)

    def failure(missing: int) -> str:
        return (
            f"sample_starts: {missing} of {n} start states not inside the mode within MAX_DRAWS={MAX_DRAWS} rounds "
            f"(sigma={sigma})"
        )

    return rejection_sample(draw, model.inside, n, 2, MAX_DRAWS, failure)


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
    """What :func:`cut_loop` learned: the acting policy, its cuts and the rounds it took.

    Attributes:
        policy: the acting policy (modulated by ``cuts`` unless the loop ran without modulation).
        cuts: the learned cuts.
        failures: the failures the cuts were solved from, in the order they were cut.
        round_success: the success rate of each round's rollout.
        cuts_until_invariant: cuts after which a round had no invariance failure (None if never).
        last_rollout: the last round's rollout of the fixed ``starts`` (None with ``batch_fn`` or no rounds).
    """

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
        fresh = _fresh_failures(res, failures)
        if len(cuts) >= max_cuts or not fresh:
            return CutLoopResult(acting, cuts, failures, round_success, None, res if batch_fn is None else None)
        first = int(fresh[0])  # the batch's first failing start (in draw order)
        failures.append(FailureRecord(res["last_in"][first], res["first_out"][first], batch[first]))
        cuts.set_cuts(resolve_cuts(failures, model.attractor))
    raise BoundExceeded(f"cut_loop: no verdict after max_cuts + 1 = {max_cuts + 1} rounds")  # pragma: no cover


def _fresh_failures(res: dict[str, np.ndarray], failures: list[FailureRecord]) -> list[int]:
    """Indices of the rollout's failures that repeat no known one, in draw order.

    A failure is new unless an earlier one had the same last in-mode *and* failure state (a start on its
    own cut can slide along it out of the mode: that exit gets a second cut through the same point).
    """
    known = np.array([np.concatenate([fr.last_in_mode, fr.failure]) for fr in failures]).reshape(-1, 4)
    pairs = np.concatenate([res["last_in"], res["first_out"]], axis=1)
    return [i for i in np.nonzero(res["left"])[0] if not np.any(np.linalg.norm(known - pairs[i], axis=1) < 1e-9)]
