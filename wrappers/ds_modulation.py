"""Cutting planes and DS modulation: mode invariance for any velocity policy (thesis ch. 3, TLI).

Each *invariance failure* (the policy left its mode although the plan did not
ask for it) yields a **cut**: a hyperplane through the last in-mode state ``f``
with outward unit normal ``n`` that keeps the mode's entry state, the other
last-in-mode states and a ball around the attractor ``x*`` inside, puts the
failure state outside, and passes as close to ``x*`` as it can (the QCQP of
the appendix "QCQP Optimization Details")::

    min_n  (n^T (x* - f))^2
    s.t.   |n| = 1,   n^T (x* - f) <= -rho,   n^T (x^0 - f) <= 0,
           n^T (f' - f) <= 0  (earlier last-in-mode states f'),   n^T (x_fail - f) >= 0.

``rho`` (0.4, the success radius) is the public code's "points 0.4 around the
attractor" written exactly as a ball; the failure constraint is the thesis's
"separates the failure state" (the appendix program leaves it implicit, it
fixes which of the two tangent normals is meant). In 2D, ``n = (cos t, sin t)``
turns every constraint into an arc of the circle, the feasible set into one
arc, and the objective into ``|x* - f|^2 cos^2(t - phi)``: the minimiser is an
arc end point or a stationary point, so :func:`solve_cut` enumerates those and
is exact (tested against 100k sampled normals). For ``d > 2`` it runs SLSQP from
many starts (the public code's ``fmincon`` approach) and keeps the best
feasible normal. An infeasible program is relaxed in a fixed order (drop the
earlier last-in-mode states, then the entry state, then shrink ``rho``) and
the cut records what was dropped.

**Gamma and modulation** (thesis Eq. "modulate") with the reference
point ``r = x*``: ``Gamma_k(x) = max(0, 1 - ((f_k - x)^T n_k) / ((f_k - r)^T n_k))``
is 0 on the plane through ``r`` parallel to cut ``k``, 1 on the cut, > 1
beyond. Among the cuts the state is inside of (``Gamma_k <= 1``) and the flow
approaches (``n_k^T v > 0``) the one with the largest ``Gamma_k`` is used: ``M = E D E^-1`` with
``E = [(x - r)/|x - r|, tangent basis of the cut]`` and
``D = diag(1 - Gamma_k, 1, ..., 1)``. In closed form ``M v = v - (n_k^T v)
(x - r) / h_k`` with ``h_k = (f_k - r)^T n_k``. Outside every cut the nominal
velocity is used (thesis: "outside the cuts but inside the mode, it follows the
nominal DS"); we read "outside" per cut, so a state beyond one cut (a start
drawn there, or a push) is still held by the cuts it is inside of; read for the
whole intersection, a start beyond an older cut would follow the nominal flow out
through a newer cut's failure.

Two safeguards make the no-crossing guarantee actually hold: (1) the
nearest-cut rule alone keeps the velocity *tangent* to the nearest cut, which
at a *corner* of two cuts can carry the state through the second one (the
thesis's proof looks at one cut; tests/wrappers/test_ds_modulation.py fails
without this): where the modulated velocity still approaches another cut
``j``, the whole velocity is scaled by ``min(1, (1 - Gamma_j) |v| / (n_j^T M v))``
(its direction, hence ``dV/dt < 0``, is kept; with one cut nothing changes)
and the speed removed goes along ``r - x`` instead, which approaches no cut and
also decreases ``V``, so corners do not become spurious equilibria;
(2) with ``max_speed`` the nominal velocity is clipped before and the result
after modulation (the thesis's ``|x'| <= 20``). Then every cut's
distance shrinks by at most the factor ``1 - dt * max_speed / h_k`` per Euler
step, so no cut is crossed whenever ``dt * max_speed < min_k h_k``
(ConvexMode: ``0.01 * 20 = 0.2 < rho = 0.4``).
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import minimize

from steer_envs.core.env import HasTask, perturbable_env
from steer_envs.core.policy import VelocityPolicy
from steer_envs.core.validation import boolean, describe, integer, real_array, real_scalar

__all__ = [
    "Cut",
    "CutSet",
    "DSModulationWrapper",
    "FailureRecord",
    "ModulatedPolicy",
    "gamma",
    "modulate",
    "modulation_matrix",
    "resolve_cuts",
    "solve_cut",
]

#: default radius of the ball around the attractor that every cut keeps inside (the success radius).
ATTRACTOR_MARGIN = 0.4
#: slack of the feasibility tests of candidate normals.
FEAS_TOL = 1e-9
#: most SLSQP starts of the ``d > 2`` cut solver (each start is one bounded local solve).
MAX_RESTARTS = 10_000


@dataclass(frozen=True)
class Cut:
    """A half-space boundary ``{x : n^T (x - point) <= 0}`` (``n`` unit, pointing out of the mode).

    Attributes:
        point: ``(d,)`` a point on the plane (the last in-mode state of the failure).
        normal: ``(d,)`` outward unit normal.
        relaxed: constraints of the QCQP that had to be dropped to make it feasible
            (``"visited"``, ``"entry"``, ``"margin"``); empty when solved as posed.
    """

    point: np.ndarray
    normal: np.ndarray
    relaxed: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        p = real_array(self.point, "point", finite=False, owner="Cut")
        n = real_array(self.normal, "normal", finite=False, owner="Cut")
        if not isinstance(self.relaxed, tuple) or not all(isinstance(r, str) for r in self.relaxed):
            raise TypeError(f"Cut: relaxed must be a tuple of str, got {describe(self.relaxed)}")
        if p.ndim != 1 or n.shape != p.shape or not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
            raise ValueError(f"Cut: point and normal must be finite vectors of equal length, got {p.shape}, {n.shape}")
        norm = np.linalg.norm(n)
        if not norm > 0:
            raise ValueError("Cut: normal must be non-zero")
        object.__setattr__(self, "point", p)
        object.__setattr__(self, "normal", n / norm)

    def signed_distance(self, x: ArrayLike) -> np.ndarray:
        """``n^T (x - point)`` of ``(N, d)`` states: > 0 outside the cut."""
        return (np.asarray(x, dtype=np.float64) - self.point) @ self.normal


@dataclass(frozen=True)
class FailureRecord:
    """What one invariance failure contributes to the cut program."""

    last_in_mode: np.ndarray
    failure: np.ndarray
    entry: np.ndarray


# --------------------------------------------------------------------------- QCQP
def solve_cut(
    last_in_mode: ArrayLike,
    failure: ArrayLike,
    entry: ArrayLike,
    attractor: ArrayLike,
    visited: ArrayLike | None = None,
    *,
    also_keep: ArrayLike | None = None,
    margin: float = ATTRACTOR_MARGIN,
    restarts: int = 64,
    seed: int = 0,
) -> Cut:
    """The cut through ``last_in_mode`` for one invariance failure (the QCQP; see the module docstring).

    Args:
        last_in_mode: ``f`` ``(d,)``, the last state inside the mode.
        failure: ``(d,)`` the first state outside (kept on the outer side).
        entry: ``x^0`` ``(d,)``, where the mode was entered (kept inside).
        attractor: ``x*`` ``(d,)``; the ball of radius ``margin`` around it is kept inside.
        visited: ``(m, d)`` last-in-mode states of earlier failures (kept inside), or None.
        also_keep: ``(m', d)`` further states kept inside as long as that is feasible: the first
            constraints the relaxation drops (without recording it), before ``visited``.
        margin: radius of that ball (the distance of the plane to ``x*`` is at least this).
        restarts, seed: multistart of the ``d > 2`` solver (unused in 2D).
    """
    f = _vec(last_in_mode, "last_in_mode")
    d = len(f)
    fail = _vec(failure, "failure", d)
    x0 = _vec(entry, "entry", d)
    att = _vec(attractor, "attractor", d)
    vis = np.zeros((0, d)) if visited is None else _states(visited, "visited", d)
    extra = np.zeros((0, d)) if also_keep is None else _states(also_keep, "also_keep", d)
    if not (np.all(np.isfinite(vis)) and np.all(np.isfinite(extra))):
        raise ValueError("visited and also_keep must be finite")
    margin = real_scalar(margin, "margin", low=0.0)
    restarts = integer(restarts, "restarts", low=1, high=MAX_RESTARTS)
    seed = integer(seed, "seed")
    if np.linalg.norm(fail - f) == 0:
        raise ValueError("failure must differ from last_in_mode (the cut separates them)")
    a_star = att - f
    dist = float(np.linalg.norm(a_star))
    if dist == 0:
        raise ValueError("last_in_mode coincides with the attractor; no cut can keep the attractor inside")
    rho = min(float(margin), 0.9 * dist)
    relaxed: list[str] = [] if rho == margin else ["margin"]
    vis = vis[np.linalg.norm(vis - f, axis=1) > 1e-12]
    extra = extra[np.linalg.norm(extra - f, axis=1) > 1e-12]
    keep_x0 = bool(np.linalg.norm(x0 - f) > 1e-12)
    # relaxation ladder: as posed; without also_keep; without earlier last-in-mode states; without the entry;
    # smaller margins
    attempts: list[tuple[np.ndarray, bool, float, tuple[str, ...]]] = []
    if len(extra):
        attempts.append((np.concatenate([vis, extra]), keep_x0, rho, ()))
    attempts.append((vis, keep_x0, rho, ()))
    if len(vis):
        attempts.append((vis[:0], keep_x0, rho, ("visited",)))
    if keep_x0:
        attempts.append((vis[:0], False, rho, ("visited", "entry")))
    attempts += [(vis[:0], False, rho * 0.25**i, ("visited", "entry", "margin")) for i in range(1, 8)]
    for v, use_x0, r, dropped in attempts:
        # rows a of the constraints a^T n <= c
        rows = [a_star, *(v - f)] + ([x0 - f] if use_x0 else []) + [-(fail - f)]
        a_mat = np.asarray(rows)
        c = np.zeros(len(rows))
        c[0] = -r
        n = _solve_2d(a_star, a_mat, c, fail - f) if d == 2 else _solve_nd(a_star, a_mat, c, restarts, seed)
        if n is not None:
            kept = [name for name, present in (("visited", len(vis) > 0), ("entry", keep_x0)) if present]
            all_relaxed = [*relaxed, *(name for name in dropped if name in kept or name == "margin")]
            return Cut(point=f, normal=n, relaxed=tuple(dict.fromkeys(all_relaxed)))
    raise ValueError(
        "no cut can separate the failure state from the attractor: they lie in the same direction from last_in_mode"
    )


def _solve_2d(a_star: np.ndarray, a_mat: np.ndarray, c: np.ndarray, sep: np.ndarray) -> np.ndarray | None:
    """Exact minimiser of ``(a_star . n)^2`` over unit ``n`` with ``a_mat n <= c`` in 2D, or None if infeasible."""
    norms = np.linalg.norm(a_mat, axis=1)
    if np.any((norms == 0) & (c < 0)):
        return None
    live = norms > 0
    a_mat, c, norms = a_mat[live], c[live], norms[live]
    ratio = c / norms
    if np.any(ratio < -1 - 1e-12):
        return None  # a constraint no unit vector meets
    phis = np.arctan2(a_mat[:, 1], a_mat[:, 0])
    # a . n = |a| cos(t - phi) <= c  <=>  t - phi outside (-acos(c/|a|), acos(c/|a|)): arc end points
    half = np.arccos(np.clip(ratio, -1.0, 1.0))
    phi_star = np.arctan2(a_star[1], a_star[0])
    cands = np.concatenate([phis + half, phis - half, phi_star + np.array([0.5, -0.5, 0.0, 1.0]) * np.pi])
    normals = np.stack([np.cos(cands), np.sin(cands)], axis=1)
    scale = np.maximum(1.0, norms)
    ok = np.all((normals @ a_mat.T - c) <= FEAS_TOL * scale, axis=1)
    if not ok.any():
        return None
    normals = normals[ok]
    obj = (normals @ a_star) ** 2
    best = obj <= obj.min() + 1e-12 * max(1.0, float(a_star @ a_star))
    # ties (both tangents feasible): prefer the normal that puts the failure state farthest outside
    pick = np.argmax(np.where(best, normals @ sep, -np.inf))
    return normals[pick]


def _solve_nd(a_star: np.ndarray, a_mat: np.ndarray, c: np.ndarray, restarts: int, seed: int) -> np.ndarray | None:
    """Multistart SLSQP on the sphere for ``d > 2``; the best feasible local minimiser, or None."""
    d = len(a_star)
    rng = np.random.default_rng(seed)
    starts = rng.normal(size=(max(1, restarts), d))
    starts /= np.linalg.norm(starts, axis=1, keepdims=True)
    cons = (
        {"type": "ineq", "fun": lambda n: c - a_mat @ n, "jac": lambda n: -a_mat},
        {"type": "eq", "fun": lambda n: np.array([n @ n - 1.0]), "jac": lambda n: 2.0 * n[None, :]},
    )
    scale = np.maximum(1.0, np.linalg.norm(a_mat, axis=1))
    best, best_obj = None, np.inf
    for n0 in starts:
        res = minimize(
            lambda n: float(n @ a_star) ** 2,
            n0,
            jac=lambda n: 2.0 * float(n @ a_star) * a_star,
            constraints=cons,
            method="SLSQP",
            options={"maxiter": 200, "ftol": 1e-14},
        )
        n = res.x / max(np.linalg.norm(res.x), 1e-300)
        if np.all(a_mat @ n - c <= 1e-7 * scale) and (n @ a_star) ** 2 < best_obj:
            best, best_obj = n, float(n @ a_star) ** 2
    return best


# ------------------------------------------------------------------ Gamma, modulation
@dataclass
class CutSet:
    """The cuts of one mode and the reference point (the mode's attractor).

    Attributes:
        reference: ``(d,)`` reference point ``r`` (the attractor ``x*``).
        cuts: the cuts; every cut must keep ``reference`` strictly inside.
    """

    reference: np.ndarray
    cuts: list[Cut] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.reference = _vec(self.reference, "reference")
        for cut in list(self.cuts):
            self._check(cut)

    def _check(self, cut: Cut) -> None:
        if not isinstance(cut, Cut):
            raise TypeError(f"cuts must be Cut objects, got {type(cut).__name__}")
        if cut.point.shape != self.reference.shape:
            raise ValueError(f"cut dimension {cut.point.shape} does not match reference {self.reference.shape}")
        if not (cut.point - self.reference) @ cut.normal > 0:
            raise ValueError("a cut must keep the reference point (attractor) strictly inside")

    def add(self, cut: Cut) -> None:
        """Append a cut (validated)."""
        self._check(cut)
        self.cuts.append(cut)

    def set_cuts(self, cuts: Iterable[Cut]) -> None:
        """Replace all cuts in place (validated), e.g. after re-solving them; holders of this set see the change."""
        new = list(cuts)
        for cut in new:
            self._check(cut)
        self.cuts[:] = new

    def __len__(self) -> int:
        return len(self.cuts)

    @property
    def dim(self) -> int:
        return len(self.reference)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(K, d)`` points, ``(K, d)`` normals and ``(K,)`` heights ``h_k = n_k^T (f_k - r)``."""
        if not self.cuts:
            return np.zeros((0, self.dim)), np.zeros((0, self.dim)), np.zeros(0)
        pts = np.stack([c.point for c in self.cuts])
        nrm = np.stack([c.normal for c in self.cuts])
        return pts, nrm, np.einsum("kd,kd->k", pts - self.reference, nrm)

    def gammas(self, x: ArrayLike) -> np.ndarray:
        """Per-cut ``Gamma_k(x)``: ``(N, d) -> (N, K)``."""
        xb = _batch(x, self.dim)
        _, nrm, h = self.arrays()
        return np.maximum(0.0, ((xb - self.reference) @ nrm.T) / h)

    def inside(self, x: ArrayLike) -> np.ndarray:
        """Strictly inside every cut (``Gamma_k < 1`` for all ``k``): ``(N,)`` bool."""
        return np.all(self.gammas(x) < 1.0, axis=1)


def gamma(x: ArrayLike, cuts: CutSet) -> np.ndarray:
    """``Gamma(x) = max_k Gamma_k(x)`` (0 with no cuts): < 1 inside, 1 on, > 1 outside the cuts. ``(N,)``."""
    g = cuts.gammas(x)
    return g.max(axis=1) if g.shape[1] else np.zeros(len(g))


def modulation_matrix(x: ArrayLike, cut: Cut, reference: ArrayLike) -> np.ndarray:
    """``M = E D E^-1`` of one cut at states ``(N, d)``: ``(N, d, d)`` (identity where ``Gamma_k <= 0``).

    ``E = [r_hat, e_1 .. e_{d-1}]`` with ``r_hat = (x - r)/|x - r|`` and ``e_i`` an
    orthonormal basis of the cut's tangent space; ``D = diag(1 - Gamma_k, 1, ...)``.
    The explicit form of what :func:`modulate` applies in closed form.
    """
    ref = _vec(reference, "reference", len(cut.normal))
    xb = _batch(x, len(ref))
    n = cut.normal
    h = float((cut.point - ref) @ n)
    # tangent basis: null space of n^T
    _, _, vt = np.linalg.svd(n[None, :])
    tangent = vt[1:].T  # (d, d-1)
    out = np.repeat(np.eye(len(ref))[None], len(xb), axis=0)
    for i, xi in enumerate(xb):
        g = max(0.0, float((xi - ref) @ n) / h)
        if g <= 0:
            continue
        r_hat = (xi - ref) / np.linalg.norm(xi - ref)
        E = np.column_stack([r_hat, tangent])
        D = np.diag([1.0 - g] + [1.0] * (len(ref) - 1))
        out[i] = E @ D @ np.linalg.inv(E)
    return out


def modulate(x: ArrayLike, velocity: ArrayLike, cuts: CutSet, max_speed: float | None = None) -> np.ndarray:
    """Modulated velocities ``M(x) v`` for states ``(N, d)`` and nominal velocities ``(N, d)``.

    Applies the thesis modulation against the nearest approached cut, the corner
    safeguard and (with ``max_speed``) speed clipping before and after; see the
    module docstring. Rows that approach no cut they are inside of (a state on
    a cut counts as inside) keep ``v``.
    """
    if not isinstance(cuts, CutSet):
        raise TypeError(f"cuts must be a CutSet, got {describe(cuts)}")
    xb = _batch(x, cuts.dim)
    v = _reals(velocity, "velocity")
    if v.shape != xb.shape:
        raise ValueError(f"velocity must have the shape of x {xb.shape}, got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("velocity must be finite (got NaN or inf)")
    if max_speed is not None:
        max_speed = _speed(max_speed)
        v = _clip(v, max_speed)
    if len(cuts) == 0:
        return v.copy()
    _, nrm, h = cuts.arrays()
    rel = xb - cuts.reference
    gam = np.maximum(0.0, (rel @ nrm.T) / h)  # (N, K)
    # inside (or on, up to rounding: a start drawn on its own cut's plane) each cut; a cut the state is
    # already beyond neither modulates nor constrains it
    inside = gam <= 1.0 + 1e-9
    approach = v @ nrm.T  # (N, K)  n_k . v
    active = inside & (approach > 0) & (gam > 0)
    score = np.where(active, gam, -np.inf)
    k = np.argmax(score, axis=1)
    rows = np.isfinite(score[np.arange(len(xb)), k])
    out = v.copy()
    if rows.any():
        idx = np.nonzero(rows)[0]
        kk = k[idx]
        # M v = v - Gamma_k [E^-1 v]_1 r_hat = v - (n_k . v) (x - r) / h_k
        out[idx] = v[idx] - (approach[idx, kk] / h[kk])[:, None] * rel[idx]
        # corner safeguard: the modulated flow must not approach another cut faster than the nominal one
        speed = np.linalg.norm(v[idx], axis=1)
        app2 = out[idx] @ nrm.T  # (n, K)
        g2 = gam[idx]
        risky = (app2 > 0) & (g2 > 0) & inside[idx]
        risky[np.arange(len(idx)), kk] = False
        bound = np.where(risky, np.maximum(0.0, 1.0 - g2) * speed[:, None] / np.where(risky, app2, 1.0), np.inf)
        scale = np.clip(bound.min(axis=1), 0.0, 1.0)
        # what the scaling takes away goes straight toward the reference point instead: that direction
        # approaches no cut (n_j . (r - x) = -Gamma_j h_j <= 0) and decreases V, so a flow pinned in a
        # corner of two cuts keeps moving instead of stalling there
        home = -rel[idx]
        dist = np.linalg.norm(home, axis=1)
        home = home * (np.minimum(speed, dist) / np.maximum(dist, 1e-300))[:, None]
        out[idx] = scale[:, None] * out[idx] + (1.0 - scale)[:, None] * home
    if max_speed is not None:
        out = _clip(out, max_speed)
    return out


class ModulatedPolicy:
    """``x -> M(x) policy(x)``: a velocity policy bounded by cuts (no env needed).

    Args:
        policy: any batched ``VelocityPolicy`` (``(N, d) -> (N, d)``), e.g. an
            :class:`~steer_envs.baselines.lpv_ds.lpvds.LPVDS` or a BC policy.
        cuts: a :class:`CutSet` (shared, so cuts added to it later take effect).
        max_speed: optional speed limit applied before and after modulation
            (the discrete-time guarantee needs it, see the module docstring).
    """

    def __init__(self, policy: VelocityPolicy, cuts: CutSet, max_speed: float | None = None) -> None:
        if not callable(policy):
            raise TypeError(f"policy must be a callable VelocityPolicy, got {type(policy).__name__}")
        if not isinstance(cuts, CutSet):
            raise TypeError(f"cuts must be a CutSet, got {type(cuts).__name__}")
        self.policy = policy
        self.cuts = cuts
        self.max_speed = None if max_speed is None else _speed(max_speed)

    def __call__(self, x: ArrayLike) -> np.ndarray:
        arr = _reals(x, "x", owner="ModulatedPolicy")
        single = arr.ndim == 1
        xb = _batch(arr[None] if single else arr, self.cuts.dim)
        v = _reals(self.policy(xb), "policy(x)", owner="ModulatedPolicy")
        if v.shape != xb.shape:
            raise ValueError(f"policy returned shape {v.shape} for states of shape {xb.shape}")
        out = modulate(xb, v, self.cuts, self.max_speed)
        return out[0] if single else out


def resolve_cuts(
    failures: Sequence[FailureRecord], attractor: ArrayLike, margin: float = ATTRACTOR_MARGIN
) -> list[Cut]:
    """(Re-)solve the cut of every failure, each keeping the others' last-in-mode and entry states inside.

    Keeping the other failures' entry states inside matters: a later cut that
    excluded an earlier failure's start would make that start begin outside the
    cuts, where the modulation (by design) leaves the flow unchanged.
    """
    if not failures:
        return []
    lims = np.stack([fr.last_in_mode for fr in failures])
    entries = np.stack([fr.entry for fr in failures])
    cuts = []
    for i, fr in enumerate(failures):
        others = np.delete(lims, i, axis=0)
        also = np.delete(entries, i, axis=0)
        cuts.append(solve_cut(fr.last_in_mode, fr.failure, fr.entry, attractor, others, also_keep=also, margin=margin))
    return cuts


# ------------------------------------------------------------------------ wrapper
PlanFn = Callable[[int, Mapping[str, Any]], Iterable[int] | None]


class DSModulationWrapper(gym.ActionWrapper[Any, Any, Any], gym.utils.RecordConstructorArgs):
    """Modulate any velocity action by learned cuts; learn a cut on every invariance failure.

    The unwrapped env must be a :class:`~steer_envs.core.env.PerturbableEnv`
    (``state`` and ``perturb``) and report ``info["mode"]`` (the 2D kinematic envs do). The agent's action is a
    nominal velocity (from a DS, BC, or anything); the env receives
    ``M(x) action`` for the current mode (nominal where that mode has no
    attractor or no cuts yet).

    **Attractors** come from the constructor: ``attractor`` is either one point
    (used for the mode the env starts in, e.g. ConvexMode's single mode) or a
    mapping ``mode index -> point`` (e.g. the per-mode attractors of
    :mod:`steer_envs.data.segmentation`).

    **The plan.** A mode change ``m -> m'`` during a step is an invariance
    failure unless the plan asked for it: ``plan(m, info)`` (constructor arg)
    returns the modes the plan allows next; by default the wrapper reads
    ``info["plan"]`` of the step before the transition (a mode sequence from
    the current mode, as :class:`~steer_envs.wrappers.LTLReplanWrapper`
    provides; so wrap *around* it: ``DSModulationWrapper(LTLReplanWrapper(env),
    ...)``), and with no plan every exit of a mode is a failure (single-mode
    envs). Exits caused by a push (:meth:`perturb`, or
    ``env.unwrapped.perturb`` noticed as a jump of the state between steps) are
    not failures.

    On a failure the cut through the last in-mode state is added and all cuts
    of that mode are re-solved with the new visited set (the TLI protocol). Cuts
    persist across episodes (that is the learning); :meth:`clear_cuts` forgets.
    ``info`` gains ``invariance_failure``, ``cut_added``, ``num_cuts`` and ``modulated``.

    Args:
        env: a steer-envs kinematic env (possibly wrapped) whose action is a
            velocity of the state's dimension ``d``.
        attractor: one point ``(d,)``, or a mapping mode index -> point.
        plan: optional ``(mode, info) -> allowed next modes`` (mode indices).
        home_mode: the mode a single ``attractor`` belongs to (default: the
            task's initial mode).
        margin: radius around each attractor every cut keeps inside (a real number >= 0).
        learn: add cuts on failures (``False``: only apply the given ``cuts``); a bool.
        cuts: optional initial ``{mode: CutSet}`` (extended in place as cuts are learned).

    Arguments that could never work are refused here: an attractor or cut set of
    another dimension than the state, a mode index (int) the task does not have.

    The constructor arguments are recorded (``env.spec``) as given, ``cuts`` as
    a copy taken before any learning.

    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import steer_envs
    >>> env = DSModulationWrapper(gym.make("steer_envs/ConvexMode-v0", layout_seed=0), attractor=[0.0, 0.0])
    >>> obs, info = env.reset(seed=0)
    >>> obs, reward, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
    >>> info["num_cuts"], info["invariance_failure"]
    (0, False)
    >>> env.spec.additional_wrappers[0].kwargs["margin"]
    0.4
    """

    def __init__(
        self,
        env: gym.Env,
        attractor: ArrayLike | Mapping[int, ArrayLike],
        *,
        plan: PlanFn | None = None,
        home_mode: int | None = None,
        margin: float = ATTRACTOR_MARGIN,
        learn: bool = True,
        cuts: Mapping[int, CutSet] | None = None,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self,
            attractor=attractor,
            plan=plan,
            home_mode=home_mode,
            margin=margin,
            learn=learn,
            cuts=copy.deepcopy(cuts),
            _disable_deepcopy=True,  # `plan` may be a bound method: record it, do not copy its owner
        )
        gym.ActionWrapper.__init__(self, env)
        who = "DSModulationWrapper"
        base = perturbable_env(env, who=who)
        self._base = base
        if plan is not None and not callable(plan):
            raise TypeError(f"plan must be None or a callable (mode, info) -> modes, got {type(plan).__name__}")
        margin = real_scalar(margin, "margin", low=0.0, owner=who)
        learn = boolean(learn, "learn", owner=who)
        self.max_speed: float | None = getattr(base, "max_speed", None)
        self.dt: float | None = getattr(base, "dt", None)
        task = base.task if isinstance(base, HasTask) else None
        self._task = task
        # the velocity is a state derivative: attractors, cuts and actions live in the state's space
        self.dim = int(np.asarray(base.state).reshape(-1).size)
        space = env.action_space
        if isinstance(space, gym.spaces.Box) and space.shape != (self.dim,):
            raise ValueError(
                f"{who}: the env's action must be a velocity of the state's dimension ({self.dim},), "
                f"got an action space of shape {space.shape}"
            )
        num_modes = len(task.modes) if task is not None else None

        def mode_index(value: Any, name: str) -> int:
            return integer(value, name, low=0, high=None if num_modes is None else num_modes - 1, owner=who)

        if isinstance(attractor, Mapping):
            if not attractor:
                raise ValueError(f"{who}: attractor must map at least one mode index to a point")
            self.attractors = {
                mode_index(m, "attractor key (mode index)"): self._point(a, f"attractor[{m!r}]")
                for m, a in attractor.items()
            }
        else:
            if home_mode is None:
                home_mode = task.mode_index(task.initial or task.modes[0]) if task is not None else 0
            self.attractors = {mode_index(home_mode, "home_mode"): self._point(attractor, "attractor")}
        self.plan_fn = plan
        self.margin = margin
        self.learn = learn
        self.cut_sets: dict[int, CutSet] = {}
        if cuts is not None and not isinstance(cuts, Mapping):
            raise TypeError(f"{who}: cuts must be None or a mapping mode index -> CutSet, got {describe(cuts)}")
        for m, cs in (cuts or {}).items():
            if not isinstance(cs, CutSet):
                raise TypeError(f"cuts[{m}] must be a CutSet, got {type(cs).__name__}")
            if cs.dim != self.dim:
                raise ValueError(f"{who}: cuts[{m!r}] has dimension {cs.dim}, the state has {self.dim}")
            self.cut_sets[mode_index(m, "cuts key (mode index)")] = cs
        self.failures: dict[int, list[FailureRecord]] = {}
        self._mode: int | None = None
        self._entry: np.ndarray | None = None
        self._state: np.ndarray | None = None
        self._info: dict[str, Any] = {}
        self._modulated = False
        self._warned_plan = False

    # ------------------------------------------------------------ helpers
    def _point(self, value: Any, name: str) -> np.ndarray:
        """An attractor: a finite point of the state's dimension."""
        arr = _vec(value, f"DSModulationWrapper: {name}")
        if arr.shape != (self.dim,):
            raise ValueError(f"DSModulationWrapper: {name} must have the state's shape ({self.dim},), got {arr.shape}")
        return arr

    def attractor_of(self, mode: int) -> np.ndarray | None:
        """The attractor of ``mode`` (None: that mode is not modulated and learns no cuts)."""
        return self.attractors.get(int(mode))

    def clear_cuts(self) -> None:
        """Forget every learned cut and failure."""
        self.cut_sets.clear()
        self.failures.clear()

    @property
    def num_cuts(self) -> int:
        """Cuts over all modes."""
        return sum(len(c) for c in self.cut_sets.values())

    def _planned(self, mode: int, info: Mapping[str, Any]) -> set[int] | None:
        """Modes the plan allows after ``mode`` (None: no plan, every exit is a failure)."""
        if self.plan_fn is not None:
            nxt = self.plan_fn(mode, info)
            if nxt is None:
                return None
            if isinstance(nxt, (str, bytes)) or not isinstance(nxt, Iterable):
                raise TypeError(
                    f"DSModulationWrapper: plan(mode, info) must return mode indices or None, got {describe(nxt)}"
                )
            return {integer(m, "plan(mode, info) entry", owner="DSModulationWrapper") for m in nxt}
        plan = info.get("plan")
        if plan is None:
            return None
        names = tuple(self._task.modes) if self._task is not None else ()
        if any(isinstance(m, str) and m not in names for m in plan):
            if not self._warned_plan:
                warnings.warn(
                    f"info['plan'] {list(plan)} names modes the env's task does not have {names}; pass `plan=`",
                    RuntimeWarning,
                    stacklevel=3,
                )
                self._warned_plan = True
            return None
        seq = [names.index(m) if isinstance(m, str) else int(m) for m in plan]
        if mode in seq:
            i = seq.index(mode)
            return set(seq[i + 1 : i + 2])
        return set(seq[:1])

    def _track(self, info: Mapping[str, Any], *, entered: bool) -> None:
        mode = int(info["mode"])
        state = np.asarray(self._base.state, dtype=np.float64)
        if entered or mode != self._mode:
            self._entry = state.copy()
        self._mode, self._state, self._info = mode, state, dict(info)

    def _extra(self, info: Mapping[str, Any], failure: bool, added: bool) -> dict[str, Any]:
        return dict(
            info, invariance_failure=failure, cut_added=added, num_cuts=self.num_cuts, modulated=self._modulated
        )

    # --------------------------------------------------------------- API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self._modulated = False
        self._track(info, entered=True)
        return obs, self._extra(info, False, False)

    def perturb(self, delta: ArrayLike | None = None, *, to: ArrayLike | None = None) -> dict[str, Any]:
        """Push the agent (``env.unwrapped.perturb``); a mode exit caused by a push is not a failure."""
        info = self._base.perturb(delta, to=to)
        self._track(info, entered=False)
        return info

    def action(self, action: Any) -> np.ndarray:
        """The modulated velocity for the current state and mode (float32).

        ``action`` is a finite real velocity of the state's shape ``(d,)`` (a list, a
        numpy array or a torch tensor, detached); strings, complex numbers, booleans,
        NaN/inf and other shapes are refused (``TypeError``/``ValueError``).
        """
        v = real_array(action, "action", shape=(self.dim,), owner="DSModulationWrapper")
        self._modulated = False
        cuts = self.cut_sets.get(self._mode) if self._mode is not None else None
        if cuts is None or len(cuts) == 0:
            return v.astype(np.float32)  # nothing to modulate
        x = np.asarray(self._base.state, dtype=np.float64)
        out = modulate(x[None], v[None], cuts, self.max_speed)[0]
        nominal = _clip(v[None], self.max_speed)[0] if self.max_speed is not None else v
        self._modulated = not np.allclose(out, nominal)
        return out.astype(np.float32)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        before = np.asarray(self._base.state, dtype=np.float64)
        pushed = self._state is not None and not np.array_equal(before, self._state)
        prev_mode, prev_info, entry = self._mode, self._info, self._entry
        obs, reward, terminated, truncated, info = self.env.step(self.action(action))
        after = np.asarray(self._base.state, dtype=np.float64)
        mode = int(info["mode"])
        failure = added = False
        # a push through env.unwrapped.perturb (not our perturb) makes the pre-step mode unknown: no verdict
        if not pushed and prev_mode is not None and mode != prev_mode:
            planned = self._planned(prev_mode, prev_info)
            failure = planned is None or mode not in planned
            if failure and self.learn and self.attractor_of(prev_mode) is not None and entry is not None:
                added = self._add_failure(prev_mode, before, after, entry)
        # after an unseen push the entry state is unknown: the first state we see again stands in for it
        self._track(info, entered=pushed)
        return obs, reward, terminated, truncated, self._extra(info, failure, added)

    def _add_failure(self, mode: int, last_in: np.ndarray, fail: np.ndarray, entry: np.ndarray) -> bool:
        att = self.attractor_of(mode)
        assert att is not None
        records = [*self.failures.get(mode, []), FailureRecord(last_in.copy(), fail.copy(), entry.copy())]
        try:
            cuts = resolve_cuts(records, att, self.margin)
        except ValueError as err:
            warnings.warn(f"DSModulationWrapper: no cut for this failure ({err})", RuntimeWarning, stacklevel=3)
            return False
        self.failures[mode] = records
        self.cut_sets.setdefault(mode, CutSet(att)).set_cuts(cuts)
        if self.dt is not None and self.max_speed is not None:
            h = self.cut_sets[mode].arrays()[2]
            if h.min() <= self.dt * self.max_speed:
                warnings.warn(
                    f"a cut is {h.min():.3g} from the attractor, not more than dt * max_speed = "
                    f"{self.dt * self.max_speed:.3g}: the discrete-time no-crossing guarantee does not hold",
                    RuntimeWarning,
                    stacklevel=3,
                )
        return True


# ------------------------------------------------------------------------ helpers
def _reals(value: Any, name: str, owner: str | None = None) -> np.ndarray:
    """``value`` as a float64 array of real numbers (NaN/inf allowed; the callers check finiteness).

    A float numpy array is read as is (the hot path of the modulation inside rollouts);
    anything else goes through :func:`~steer_envs.core.validation.real_array`, which refuses
    strings, complex numbers, booleans and objects instead of converting them.
    """
    if type(value) is np.ndarray and value.dtype.kind == "f":
        return value.astype(np.float64, copy=False)
    return real_array(value, name, finite=False, owner=owner)


def _vec(value: ArrayLike, name: str, d: int | None = None) -> np.ndarray:
    arr = _reals(value, name)
    if arr.ndim != 1 or len(arr) < 1 or (d is not None and len(arr) != d):
        raise ValueError(f"{name} must have shape ({d if d is not None else 'd'},), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return arr


def _batch(x: ArrayLike, d: int) -> np.ndarray:
    arr = _reals(x, "x")
    if arr.ndim != 2 or arr.shape[1] != d:
        raise ValueError(f"x must have shape (N, {d}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("x must be finite (got NaN or inf)")
    return arr


def _states(value: ArrayLike, name: str, d: int) -> np.ndarray:
    """``(m, d)`` states (a flat vector of ``m * d`` numbers is read row by row)."""
    arr = real_array(value, name, finite=False)
    if arr.size % d:
        raise ValueError(f"{name} must hold states of dimension {d} (shape (m, {d})), got shape {arr.shape}")
    return arr.reshape(-1, d)


def _speed(max_speed: Any) -> float:
    return real_scalar(max_speed, "max_speed", low=0.0, low_inclusive=False)


def _clip(v: np.ndarray, max_speed: float) -> np.ndarray:
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    return v * np.minimum(1.0, max_speed / np.maximum(norm, 1e-300))
