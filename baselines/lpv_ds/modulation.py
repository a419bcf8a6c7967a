"""DS modulation: bend any velocity field so that it never crosses a mode's cuts (thesis ch. 3, TLI).

**Gamma and modulation** (thesis Eq. "modulate") with the reference
point ``r = x*``: ``Gamma_k(x) = max(0, 1 - ((f_k - x)^T n_k) / ((f_k - r)^T n_k))``
is 0 on the plane through ``r`` parallel to cut ``k``, 1 on the cut, > 1
beyond (the cuts come from :mod:`~steer_envs.baselines.lpv_ds.cuts`). Among
the cuts the state is inside of (``Gamma_k <= 1``) and the flow approaches
(``n_k^T v > 0``) the one with the largest ``Gamma_k`` is used: ``M = E D E^-1`` with
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

>>> import numpy as np
>>> from steer_envs.baselines.lpv_ds.cuts import Cut, CutSet
>>> cuts = CutSet(np.zeros(2), [Cut(point=[1.0, 0.0], normal=[1.0, 0.0])])
>>> modulate(np.array([[0.5, 0.0]]), np.array([[1.0, 0.0]]), cuts).tolist()  # halved toward the cut
[[0.5, 0.0]]
>>> ModulatedPolicy(lambda x: np.ones_like(x), cuts)(np.array([0.5, 0.0])).tolist()
[0.5, 1.0]
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from steer_envs.baselines.lpv_ds.cuts import Cut, CutSet, _batch, _reals, _vec
from steer_envs.core.policy import VelocityPolicy
from steer_envs.core.validation import describe, real_scalar

__all__ = ["ModulatedPolicy", "clip_speed", "gamma", "hold_beyond_cuts", "modulate", "modulation_matrix"]


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
        v = clip_speed(v, max_speed)
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
        out[idx] = _corner_safeguard(out[idx], v[idx], rel[idx], gam[idx], inside[idx], kk, nrm)
    if max_speed is not None:
        out = clip_speed(out, max_speed)
    return out


def _corner_safeguard(
    out: np.ndarray,
    v: np.ndarray,
    rel: np.ndarray,
    gam: np.ndarray,
    inside: np.ndarray,
    kk: np.ndarray,
    nrm: np.ndarray,
) -> np.ndarray:
    """The modulated rows ``out`` scaled so they approach no other cut faster than allowed (module docstring).

    The modulated flow must not approach another cut faster than the nominal one; what the scaling takes
    away goes straight toward the reference point instead.
    """
    speed = np.linalg.norm(v, axis=1)
    app2 = out @ nrm.T  # (n, K)
    risky = (app2 > 0) & (gam > 0) & inside
    risky[np.arange(len(out)), kk] = False
    bound = np.where(risky, np.maximum(0.0, 1.0 - gam) * speed[:, None] / np.where(risky, app2, 1.0), np.inf)
    scale = np.clip(bound.min(axis=1), 0.0, 1.0)
    # the direction toward the reference point approaches no cut (n_j . (r - x) = -Gamma_j h_j <= 0) and
    # decreases V, so a flow pinned in a corner of two cuts keeps moving instead of stalling there
    home = -rel
    dist = np.linalg.norm(home, axis=1)
    home = home * (np.minimum(speed, dist) / np.maximum(dist, 1e-300))[:, None]
    return scale[:, None] * out + (1.0 - scale)[:, None] * home


def hold_beyond_cuts(x: ArrayLike, velocity: ArrayLike, cuts: CutSet) -> np.ndarray:
    """For states beyond a cut (``Gamma_k > 1``), stop the motion further out; other rows unchanged.

    The thesis leaves the nominal flow outside the cuts, which is harmless when
    a mode is entered inside them. LTL-DS re-enters a mode through its guards,
    and a guard can lie on a cut: the b -> c guard of soup scooping (soup -> pink
    column) is the same line as the c -> b spill boundary, so re-entries land a
    hair beyond the cut through the previous spill and exit again (a discrete
    loop that more cuts do not end). This applies the modulation's
    ``lambda_r = max(0, 1 - Gamma_k) = 0`` there: for each cut ``k`` the row is
    beyond and moves away from (``n_k^T v > 0``), ``v <- v - (n_k^T v)
    (x - r) / (n_k^T (x - r))``, which zeroes ``n_k^T v`` and, like the
    modulation, only lowers ``dV/dt`` (``n_k^T (x - r) > 0``). Cuts are taken
    in decreasing ``Gamma_k``; each step only lowers the approach to the other
    cuts beyond which the row lies, so none is left approached (a residual from
    rounding is zeroed).

    >>> import numpy as np
    >>> from steer_envs.baselines.lpv_ds.cuts import Cut, CutSet
    >>> cuts = CutSet(np.zeros(2), [Cut(point=np.array([1.0, 0.0]), normal=np.array([1.0, 0.0]))])
    >>> hold_beyond_cuts(np.array([[2.0, 0.0], [0.5, 0.0]]), np.array([[1.0, 0.0], [1.0, 0.0]]), cuts).tolist()
    [[0.0, 0.0], [1.0, 0.0]]
    """
    xb = np.asarray(x, dtype=np.float64)
    v = np.array(velocity, dtype=np.float64)
    if len(cuts) == 0:
        return v
    _, nrm, h = cuts.arrays()
    rel = xb - cuts.reference
    gam = (rel @ nrm.T) / h  # (N, K)
    rows = np.nonzero(np.any(gam > 1.0, axis=1))[0]
    for i in rows:
        for k in np.argsort(-gam[i]):
            if gam[i, k] <= 1.0:
                break
            approach = float(nrm[k] @ v[i])
            if approach > 0:
                v[i] = v[i] - approach * rel[i] / (gam[i, k] * h[k])
        if np.any((nrm @ v[i] > 1e-12) & (gam[i] > 1.0)):
            v[i] = 0.0  # rounding only (see the docstring)
    return v


class ModulatedPolicy:
    """``x -> M(x) policy(x)``: a velocity policy bounded by cuts (no env needed).

    Args:
        policy: any batched ``VelocityPolicy`` (``(N, d) -> (N, d)``), e.g. an
            :class:`~steer_envs.baselines.lpv_ds.lpvds.LPVDS` or a BC policy.
        cuts: a :class:`~steer_envs.baselines.lpv_ds.cuts.CutSet` (shared, so cuts added to it later take effect).
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


def _speed(max_speed: Any) -> float:
    return real_scalar(max_speed, "max_speed", low=0.0, low_inclusive=False)


def clip_speed(v: np.ndarray, max_speed: float) -> np.ndarray:
    """Rows of ``v`` ``(N, d)`` scaled down to norm at most ``max_speed`` (the direction kept).

    >>> clip_speed(np.array([[3.0, 4.0], [0.3, 0.4]]), 1.0).round(2).tolist()
    [[0.6, 0.8], [0.3, 0.4]]
    """
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    return v * np.minimum(1.0, max_speed / np.maximum(norm, 1e-300))
