"""Cutting planes: the half-spaces that bound a mode's flow after its invariance failures (thesis ch. 3, TLI).

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

A :class:`CutSet` holds one mode's cuts and its reference point (the
attractor); :mod:`~steer_envs.baselines.lpv_ds.modulation` bends a velocity
field so that it never crosses them.

>>> import numpy as np
>>> cut = solve_cut([1.0, 0.0], [1.1, 0.0], [-1.0, 0.0], [0.0, 0.0])  # passes 0.4 from the attractor
>>> round(float(-cut.signed_distance([[0.0, 0.0]])[0]), 3), float(cut.signed_distance([[1.1, 0.0]])[0]) > 0
(0.4, True)
>>> CutSet(np.zeros(2), [cut]).inside(np.array([[0.5, 0.0], [1.5, 0.0]])).tolist()
[True, False]
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import minimize

from steer_envs.core.validation import describe, integer, real_array, real_scalar

__all__ = [
    "ATTRACTOR_MARGIN",
    "Cut",
    "CutSet",
    "FailureRecord",
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

    >>> Cut(point=[1.0, 0.0], normal=[2.0, 0.0]).normal.tolist()
    [1.0, 0.0]
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
    """What one invariance failure contributes to the cut program.

    Attributes:
        last_in_mode: ``(d,)`` the last state inside the mode (the cut passes through it).
        failure: ``(d,)`` the first state outside (kept on the outer side of the cut).
        entry: ``(d,)`` where the mode was entered (kept inside).
    """

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
    f, fail, x0, att, vis, extra = _cut_points(last_in_mode, failure, entry, attractor, visited, also_keep)
    d = len(f)
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
    for v, use_x0, r, dropped in _relaxation_ladder(vis, extra, keep_x0, rho):
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


def _cut_points(
    last_in_mode: ArrayLike,
    failure: ArrayLike,
    entry: ArrayLike,
    attractor: ArrayLike,
    visited: ArrayLike | None,
    also_keep: ArrayLike | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The points of :func:`solve_cut` checked: finite, of one dimension; ``visited``/``also_keep`` as ``(m, d)``."""
    f = _vec(last_in_mode, "last_in_mode")
    d = len(f)
    fail = _vec(failure, "failure", d)
    x0 = _vec(entry, "entry", d)
    att = _vec(attractor, "attractor", d)
    vis = np.zeros((0, d)) if visited is None else _states(visited, "visited", d)
    extra = np.zeros((0, d)) if also_keep is None else _states(also_keep, "also_keep", d)
    if not (np.all(np.isfinite(vis)) and np.all(np.isfinite(extra))):
        raise ValueError("visited and also_keep must be finite")
    return f, fail, x0, att, vis, extra


def _relaxation_ladder(
    vis: np.ndarray, extra: np.ndarray, keep_x0: bool, rho: float
) -> list[tuple[np.ndarray, bool, float, tuple[str, ...]]]:
    """The programs :func:`solve_cut` tries in order: ``(kept states, keep the entry, margin, dropped names)``.

    As posed; without ``also_keep``; without earlier last-in-mode states; without the entry; smaller margins.
    """
    attempts: list[tuple[np.ndarray, bool, float, tuple[str, ...]]] = []
    if len(extra):
        attempts.append((np.concatenate([vis, extra]), keep_x0, rho, ()))
    attempts.append((vis, keep_x0, rho, ()))
    if len(vis):
        attempts.append((vis[:0], keep_x0, rho, ("visited",)))
    if keep_x0:
        attempts.append((vis[:0], False, rho, ("visited", "entry")))
    attempts += [(vis[:0], False, rho * 0.25**i, ("visited", "entry", "margin")) for i in range(1, 8)]
    return attempts


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


def resolve_cuts(
    failures: Sequence[FailureRecord], attractor: ArrayLike, margin: float = ATTRACTOR_MARGIN
) -> list[Cut]:
    """(Re-)solve the cut of every failure, each keeping the others' last-in-mode and entry states inside.

    Keeping the other failures' entry states inside matters: a later cut that
    excluded an earlier failure's start would make that start begin outside the
    cuts, where the modulation (by design) leaves the flow unchanged.

    >>> import numpy as np
    >>> rec = FailureRecord(np.array([1.0, 0.0]), np.array([1.1, 0.0]), np.array([-1.0, 0.0]))
    >>> [c.point.tolist() for c in resolve_cuts([rec], [0.0, 0.0])]
    [[1.0, 0.0]]
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


# ------------------------------------------------------------------ the cuts of one mode
@dataclass
class CutSet:
    """The cuts of one mode and the reference point (the mode's attractor).

    ``Gamma_k(x) = max(0, 1 - ((f_k - x)^T n_k) / ((f_k - r)^T n_k))`` is 0 on the
    plane through ``r`` parallel to cut ``k``, 1 on the cut, > 1 beyond it
    (:meth:`gammas`).

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


# ------------------------------------------------------------------------ input checks
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
