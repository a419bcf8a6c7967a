"""LPV-DS: a globally asymptotically stable dynamical system learned from demonstrations.

Thesis ch. 3 (§"Motion-Level Reactivity in DS", after Figueroa & Billard 2018)::

    x' = f(x) = sum_k gamma_k(x) (A_k x + b_k),   b_k = -A_k x*,
    A_k^T P + P A_k <= -eps I  (all k),            P = P^T >= eps I,

so ``V(x) = (x - x*)^T P (x - x*)`` is a Lyapunov function and every state is
driven to the attractor ``x*`` (reachability). The fit has three steps:

1. **Mixing** ``gamma_k``: a Gaussian mixture (scikit-learn) on position plus
   scaled unit-velocity features (the "position + velocity similarity" of the
   physically-consistent GMM), the number of components ``K`` picked by BIC;
   ``gamma_k(x)`` are the posteriors of the *position* marginal. Thin Gaussians
   (eigenvalue ratio below 0.35) are widened so the mixing is smooth.
2. **Lyapunov matrix** ``P`` (convex, cvxpy): minimise the total violation
   ``sum_i pos((x_i - x*)^T P v_i)`` of "V decreases along the data" over unit
   vectors, with ``P >= eps I`` and ``trace P = d`` (a normalisation) plus a
   small pull toward ``I`` that makes the solution unique.
3. **Linear systems** ``A_k`` (convex, cvxpy, ``P`` fixed): least-squares
   velocity error under the LMIs above and ``|A_k|_F <= a_max``.

:meth:`LPVDS.check_stability` re-verifies the certificate numerically
(eigenvalues), independent of the solver's word.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import cvxpy as cp
import numpy as np
from numpy.typing import ArrayLike
from scipy.signal import savgol_filter
from sklearn.mixture import GaussianMixture
from threadpoolctl import threadpool_limits

__all__ = ["LPVDS", "StabilityReport", "benchmark_fit_time", "velocities_from_positions"]

#: fewest points a demonstration set must have (per state dimension: 5 * d).
MIN_POINTS_PER_DIM = 5
#: a position covariance whose eigenvalue ratio is below this is widened (public LPV-DS code).
THIN_RATIO = 0.35


@dataclass(frozen=True)
class StabilityReport:
    """Numerical check of the Lyapunov certificate of an :class:`LPVDS`.

    Attributes:
        stable: ``P`` positive definite and every ``A_k^T P + P A_k`` negative definite.
        p_min_eig: smallest eigenvalue of ``P`` (must be > 0).
        margins: ``(K,)`` largest eigenvalue of ``sym(A_k^T P + P A_k)`` per component
            (must be < 0; the fit asks for ``<= -eps``).
        attractor_residual: ``max_k |A_k x* + b_k|`` (0 up to rounding: ``x*`` is the equilibrium).
    """

    stable: bool
    p_min_eig: float
    margins: np.ndarray
    attractor_residual: float

    @property
    def worst_margin(self) -> float:
        """The largest (least negative) of :attr:`margins`."""
        return float(np.max(self.margins))


def velocities_from_positions(positions: ArrayLike, dt: float, window: int = 11, order: int = 3) -> np.ndarray:
    """Velocities of one sampled trajectory ``(T, d)`` by a Savitzky-Golay derivative (as the public TLI code).

    >>> import numpy as np
    >>> x = np.stack([np.linspace(0, 1, 21), np.zeros(21)], axis=1)
    >>> np.round(velocities_from_positions(x, dt=0.05)[10], 6).tolist()
    [1.0, 0.0]
    """
    x = _as_points(positions, "positions")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive finite float, got {dt!r}")
    window = min(int(window), len(x) if len(x) % 2 == 1 else len(x) - 1)
    if window <= order:
        raise ValueError(f"positions needs more than {order + 1} samples for a degree-{order} filter, got {len(x)}")
    return savgol_filter(x, window_length=window, polyorder=order, deriv=1, delta=float(dt), axis=0)


class LPVDS:
    """Linear-parameter-varying DS ``x' = sum_k gamma_k(x) A_k (x - x*)``; a batched ``VelocityPolicy``.

    Args:
        n_components: number of mixture components ``K``; ``None`` picks it by BIC
            over ``1..max_components``.
        max_components: upper bound of the BIC search.
        eps: stability margin of the LMIs (``A_k^T P + P A_k <= -eps I``, ``P >= eps I``).
        a_max: bound on ``|A_k|_F`` (keeps the fit well posed where data are sparse).
        direction_weight: weight of the unit-velocity features relative to the
            positions' spread in the GMM (0 clusters on position only).
        learn_p: fit ``P`` from the data (step 2); ``False`` uses ``P = I``.
        attractor_tol: how far (in units of the data's bounding-box diagonal) every
            demonstration's last point may be from the attractor.
        random_state: seed of the GMM fit (the fit is deterministic given it).

    >>> import numpy as np
    >>> t = np.linspace(0.0, 1.0, 60)[:, None]
    >>> demo = np.hstack([4 * (1 - t), 2 * (1 - t) ** 2])  # a curve ending at the origin
    >>> ds = LPVDS(n_components=1).fit(demo, velocities_from_positions(demo, dt=0.01), attractor=np.zeros(2))
    >>> ds.check_stability().stable, ds(np.array([[1.0, 1.0]])).shape
    (True, (1, 2))
    """

    def __init__(
        self,
        *,
        n_components: int | None = None,
        max_components: int = 6,
        eps: float = 1e-3,
        a_max: float = 5.0,
        direction_weight: float = 1.0,
        learn_p: bool = True,
        attractor_tol: float = 0.25,
        random_state: int = 0,
    ) -> None:
        if n_components is not None and (not isinstance(n_components, (int, np.integer)) or n_components < 1):
            raise ValueError(f"n_components must be None or a positive int, got {n_components!r}")
        if not isinstance(max_components, (int, np.integer)) or max_components < 1:
            raise ValueError(f"max_components must be a positive int, got {max_components!r}")
        for name, value in (("eps", eps), ("a_max", a_max), ("attractor_tol", attractor_tol)):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite float, got {value!r}")
        if not (np.isfinite(direction_weight) and direction_weight >= 0):
            raise ValueError(f"direction_weight must be a finite float >= 0, got {direction_weight!r}")
        self.n_components = n_components
        self.max_components = int(max_components)
        self.eps = float(eps)
        self.a_max = float(a_max)
        self.direction_weight = float(direction_weight)
        self.learn_p = bool(learn_p)
        self.attractor_tol = float(attractor_tol)
        self.random_state = int(random_state)
        # fitted parameters
        self.attractor: np.ndarray | None = None
        self.P: np.ndarray | None = None
        self.A: np.ndarray | None = None  # (K, d, d)
        self.b: np.ndarray | None = None  # (K, d)
        self.weights: np.ndarray | None = None  # (K,)
        self.means: np.ndarray | None = None  # (K, d)
        self.covariances: np.ndarray | None = None  # (K, d, d)
        self.n_components_: int = 0
        self._mixing: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # cached by gamma()
        self.fit_seconds: float | None = None

    # ----------------------------------------------------------- construction
    @classmethod
    def from_parameters(
        cls,
        attractor: ArrayLike,
        P: ArrayLike,
        A: ArrayLike,
        weights: ArrayLike,
        means: ArrayLike,
        covariances: ArrayLike,
    ) -> LPVDS:
        """An LPV-DS from given parameters (``b_k = -A_k x*``); no certificate is assumed, see ``check_stability``.

        >>> import numpy as np
        >>> ds = LPVDS.from_parameters(np.zeros(2), np.eye(2), [-np.eye(2)], [1.0], [np.zeros(2)], [np.eye(2)])
        >>> ds(np.array([[1.0, 2.0]])).tolist(), ds.check_stability().stable
        ([[-1.0, -2.0]], True)
        """
        ds = cls()
        att = np.asarray(attractor, dtype=np.float64)
        if att.ndim != 1:
            raise ValueError(f"attractor must be a vector, got shape {att.shape}")
        d = len(att)
        A = np.asarray(A, dtype=np.float64)
        k = A.shape[0] if A.ndim == 3 else -1
        shapes = {
            "P": (np.asarray(P, dtype=np.float64), (d, d)),
            "A": (A, (k, d, d)),
            "weights": (np.asarray(weights, dtype=np.float64), (k,)),
            "means": (np.asarray(means, dtype=np.float64), (k, d)),
            "covariances": (np.asarray(covariances, dtype=np.float64), (k, d, d)),
        }
        for name, (arr, shape) in shapes.items():
            if arr.shape != shape or not np.all(np.isfinite(arr)):
                raise ValueError(f"{name} must be a finite array of shape {shape} (K from A), got {arr.shape}")
        w = shapes["weights"][0]
        if np.any(w <= 0):
            raise ValueError("weights must be positive")
        ds.attractor = att
        ds.P = shapes["P"][0]
        ds.A = A
        ds.b = -np.einsum("kij,j->ki", A, att)
        ds._mixing = None
        ds.weights = w / w.sum()
        ds.means = shapes["means"][0]
        ds.covariances = shapes["covariances"][0]
        ds.n_components = k
        ds.n_components_ = k
        return ds

    # -------------------------------------------------------------------- fit
    def fit(
        self,
        positions: ArrayLike | Sequence[ArrayLike],
        velocities: ArrayLike | Sequence[ArrayLike],
        attractor: ArrayLike | None = None,
    ) -> LPVDS:
        """Fit the DS to demonstrations.

        Args:
            positions: one demonstration ``(T, d)`` or a list of them.
            velocities: the matching velocities (same shapes); see
                :func:`velocities_from_positions`.
            attractor: ``x*`` ``(d,)``; default: the mean of the demonstrations'
                last points (the thesis's segmentation rule). Every demonstration
                must end within ``attractor_tol`` (relative) of it.

        Returns:
            ``self``. Raises ``ValueError`` for NaN/inf, mismatched shapes, too few
            points, an attractor away from the demonstrations' ends, or an
            infeasible stability program.
        """
        start = time.perf_counter()
        # small dense problems: BLAS threads only add contention
        with threadpool_limits(limits=1):
            self._fit(positions, velocities, attractor)
        self.fit_seconds = time.perf_counter() - start
        return self

    def _fit(
        self,
        positions: ArrayLike | Sequence[ArrayLike],
        velocities: ArrayLike | Sequence[ArrayLike],
        attractor: ArrayLike | None,
    ) -> None:
        xs, vs = _as_demos(positions, "positions"), _as_demos(velocities, "velocities")
        if len(xs) != len(vs) or any(x.shape != v.shape for x, v in zip(xs, vs, strict=True)):
            raise ValueError(
                "positions and velocities must hold the same number of demonstrations with equal shapes, got "
                f"{[x.shape for x in xs]} and {[v.shape for v in vs]}"
            )
        d = xs[0].shape[1]
        if any(x.shape[1] != d for x in xs):
            raise ValueError(f"all demonstrations must have the same dimension, got {[x.shape[1] for x in xs]}")
        X, V = np.concatenate(xs), np.concatenate(vs)
        if len(X) < MIN_POINTS_PER_DIM * d:
            raise ValueError(f"need at least {MIN_POINTS_PER_DIM * d} points in {d}D to fit an LPV-DS, got {len(X)}")
        ends = np.stack([x[-1] for x in xs])
        att = ends.mean(axis=0) if attractor is None else np.asarray(attractor, dtype=np.float64)
        if att.shape != (d,) or not np.all(np.isfinite(att)):
            raise ValueError(f"attractor must be a finite vector of shape ({d},), got {np.shape(att)}")
        extent = float(np.linalg.norm(X.max(axis=0) - X.min(axis=0)))
        if extent <= 0:
            raise ValueError("positions are all identical; the demonstrations do not move")
        worst = float(np.max(np.linalg.norm(ends - att, axis=1)))
        if worst > self.attractor_tol * extent:
            raise ValueError(
                f"attractor {att.tolist()} is {worst:.3g} from a demonstration's last point, more than "
                f"attractor_tol * extent = {self.attractor_tol * extent:.3g}; the attractor must be where the "
                "demonstrations end"
            )
        speeds = np.linalg.norm(V, axis=1)
        if not np.any(speeds > 1e-9 * max(1.0, extent)):
            raise ValueError("velocities are all zero; nothing to imitate")

        self.attractor = att
        self._fit_mixture(X, V, extent)
        self.P = self._fit_p(X - att, V, d) if self.learn_p else np.eye(d)
        self.A = self._fit_a(X - att, V)
        self.b = -np.einsum("kij,j->ki", self.A, att)

    def _fit_mixture(self, X: np.ndarray, V: np.ndarray, extent: float) -> None:
        d = X.shape[1]
        spread = float(np.mean(X.std(axis=0))) or extent
        unit = V / np.maximum(np.linalg.norm(V, axis=1, keepdims=True), 1e-12)
        feats = np.hstack([X, self.direction_weight * spread * unit]) if self.direction_weight > 0 else X
        candidates = [self.n_components] if self.n_components is not None else range(1, self.max_components + 1)
        best: GaussianMixture | None = None
        best_bic = np.inf
        for k in candidates:
            if k > len(X) // (2 * feats.shape[1]) and best is not None:
                break  # not enough points per component for a meaningful full covariance
            gmm = GaussianMixture(
                n_components=int(k), covariance_type="full", reg_covar=1e-6 * spread**2 + 1e-9,
                random_state=self.random_state, n_init=1, max_iter=200,
            )  # fmt: skip
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # ConvergenceWarning on tiny sets is harmless here
                gmm.fit(feats)
            bic = gmm.bic(feats)
            if bic < best_bic:
                best, best_bic = gmm, bic
        assert best is not None
        covs = best.covariances_[:, :d, :d].copy()
        floor = (1e-3 * extent) ** 2
        for i, c in enumerate(covs):
            evals, evecs = np.linalg.eigh(0.5 * (c + c.T))
            evals = np.maximum(evals, max(THIN_RATIO * evals.max(), floor))  # widen thin Gaussians
            covs[i] = (evecs * evals) @ evecs.T
        self._mixing = None
        self.weights = best.weights_.copy()
        self.means = best.means_[:, :d].copy()
        self.covariances = covs
        self.n_components_ = len(self.weights)

    def _fit_p(self, Xc: np.ndarray, V: np.ndarray, d: int) -> np.ndarray:
        keep = np.linalg.norm(Xc, axis=1) > 1e-9
        xu = Xc[keep] / np.linalg.norm(Xc[keep], axis=1, keepdims=True)
        vu = V[keep] / np.maximum(np.linalg.norm(V[keep], axis=1, keepdims=True), 1e-12)
        if len(xu) > 1000:  # enough to pin down a d x d matrix; keeps the program small
            xu, vu = xu[:: len(xu) // 1000 + 1], vu[:: len(vu) // 1000 + 1]
        G = 0.5 * (np.einsum("ni,nj->nij", xu, vu) + np.einsum("ni,nj->nij", vu, xu)).reshape(len(xu), d * d)
        P = cp.Variable((d, d), symmetric=True)
        objective = cp.sum(cp.pos(G @ cp.vec(P, order="C"))) / len(xu) + 1e-3 * cp.sum_squares(P - np.eye(d))
        constraints = [P >> self.eps * np.eye(d), cp.trace(P) == d]
        _solve(cp.Problem(cp.Minimize(objective), constraints), "Lyapunov matrix P")
        p_value = cast(np.ndarray, P.value)
        Pv = 0.5 * (p_value + p_value.T)
        evals, evecs = np.linalg.eigh(Pv)
        return (evecs * np.maximum(evals, self.eps)) @ evecs.T  # clean tiny solver negatives

    def _fit_a(self, Xc: np.ndarray, V: np.ndarray) -> np.ndarray:
        assert self.P is not None
        d = Xc.shape[1]
        gam = self.gamma(Xc + self.attractor)
        k = gam.shape[1]
        A = [cp.Variable((d, d)) for _ in range(k)]
        pred = sum(cp.multiply(gam[:, i : i + 1], Xc @ A[i].T) for i in range(k))
        scale = float(np.mean(np.sum(V**2, axis=1))) or 1.0
        objective = cp.sum_squares(pred - V) / (len(V) * scale)
        constraints = []
        for Ak in A:
            Q = Ak.T @ self.P + self.P @ Ak
            constraints += [0.5 * (Q + Q.T) << -self.eps * np.eye(d), cp.norm(Ak, "fro") <= self.a_max]
        _solve(cp.Problem(cp.Minimize(objective), constraints), "linear systems A_k")
        return np.stack([cast(np.ndarray, Ak.value) for Ak in A])

    # ---------------------------------------------------------------- evaluate
    def _require_fit(self) -> None:
        if self.A is None:
            raise RuntimeError("LPVDS is not fitted; call fit() or from_parameters() first")

    def gamma(self, x: ArrayLike) -> np.ndarray:
        """Mixing weights ``gamma_k(x)``: ``(N, d) -> (N, K)``, rows sum to 1."""
        if self.means is None or self.covariances is None or self.weights is None:
            raise RuntimeError("LPVDS is not fitted; call fit() or from_parameters() first")
        x = self._check_x(x)
        if self._mixing is None:
            self._mixing = _mixing_constants(self.weights, self.means, self.covariances)
        inv_chol_flat, offsets, log_norm = self._mixing
        k = len(log_norm)
        # whitened offsets of all components at once: z_k = L_k^-1 x - L_k^-1 mu_k
        z = _thin_matmul(x, inv_chol_flat).reshape(len(x), k, -1) - offsets
        log_p = log_norm - 0.5 * np.sum(z * z, axis=2)
        log_p -= log_p.max(axis=1, keepdims=True)
        p = np.exp(log_p)
        return p / p.sum(axis=1, keepdims=True)

    def __call__(self, x: ArrayLike) -> np.ndarray:
        """Velocities ``f(x)``: ``(N, d) -> (N, d)`` (a single ``(d,)`` state gives ``(d,)``)."""
        self._require_fit()
        assert self.A is not None and self.attractor is not None
        arr = np.asarray(x, dtype=np.float64)
        single = arr.ndim == 1
        xb = self._check_x(arr[None] if single else arr)
        gam = self.gamma(xb)
        k, d = self.A.shape[:2]
        per_k = _thin_matmul(xb - self.attractor, self.A.reshape(k * d, d)).reshape(len(xb), k, d)  # A_k (x - x*)
        out = np.sum(gam[:, :, None] * per_k, axis=1)
        return out[0] if single else out

    def lyapunov(self, x: ArrayLike) -> np.ndarray:
        """``V(x) = (x - x*)^T P (x - x*)``: ``(N, d) -> (N,)``."""
        self._require_fit()
        assert self.P is not None and self.attractor is not None
        xc = self._check_x(x) - self.attractor
        return np.einsum("ni,ij,nj->n", xc, self.P, xc)

    def lyapunov_derivative(self, x: ArrayLike, velocity: ArrayLike | None = None) -> np.ndarray:
        """``dV/dt = 2 (x - x*)^T P x'`` along ``velocity`` (default: the DS itself): ``(N,)``."""
        self._require_fit()
        assert self.P is not None and self.attractor is not None
        xb = self._check_x(x)
        v = self(xb) if velocity is None else np.asarray(velocity, dtype=np.float64)
        if v.shape != xb.shape:
            raise ValueError(f"velocity must have shape {xb.shape}, got {v.shape}")
        return 2.0 * np.einsum("ni,ij,nj->n", xb - self.attractor, self.P, v)

    def check_stability(self, tol: float = 0.0) -> StabilityReport:
        """Verify ``P > 0`` and ``A_k^T P + P A_k < -tol`` numerically (eigenvalues)."""
        self._require_fit()
        assert self.P is not None and self.A is not None and self.b is not None and self.attractor is not None
        p_min = float(np.linalg.eigvalsh(0.5 * (self.P + self.P.T)).min())
        margins = np.array([np.linalg.eigvalsh(Ak.T @ self.P + self.P @ Ak).max() for Ak in self.A])
        residual = float(np.max(np.abs(np.einsum("kij,j->ki", self.A, self.attractor) + self.b)))
        stable = bool(p_min > 0 and np.all(margins < -tol) and residual < 1e-8 * (1 + np.abs(self.attractor).max()))
        return StabilityReport(stable=stable, p_min_eig=p_min, margins=margins, attractor_residual=residual)

    def _check_x(self, x: ArrayLike) -> np.ndarray:
        assert self.attractor is not None
        arr = np.asarray(x, dtype=np.float64)
        d = len(self.attractor)
        if arr.ndim != 2 or arr.shape[1] != d:
            raise ValueError(f"x must have shape (N, {d}), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError("x must be finite (got NaN or inf)")
        return arr


def _mixing_constants(
    weights: np.ndarray, means: np.ndarray, covariances: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(L^-1 stacked (K d, d), L_k^-1 mu_k (K, d), log w_k - log det L_k (K,))`` of the position GMM."""
    k, d = means.shape
    chol = np.linalg.cholesky(covariances)
    inv_chol = np.linalg.inv(chol)
    log_det = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=1, axis2=2)), axis=1)
    return inv_chol.reshape(k * d, d), np.einsum("kij,kj->ki", inv_chol, means), np.log(weights) - 0.5 * log_det


def _thin_matmul(x: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``x @ m.T`` for a small inner dimension ``d`` by broadcasting: no BLAS call.

    BLAS threads cost more than they give on ``(N, d) x (d, K d)`` products with
    ``d`` = 2 or 3; ``d`` fused multiply-adds over ``(N, K d)`` arrays are cheap.
    """
    out = x[:, 0, None] * m[None, :, 0]
    for j in range(1, x.shape[1]):
        out += x[:, j, None] * m[None, :, j]
    return out


def _solve(problem: cp.Problem, what: str) -> float:
    """Solve with Clarabel (SCS as a fallback); raise ValueError when no solution is found."""
    for solver in ("CLARABEL", "SCS"):
        if solver not in cp.installed_solvers():
            continue
        try:
            value = problem.solve(solver=solver)
        except cp.error.SolverError:
            continue
        if problem.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) and value is not None:
            return float(value)
    raise ValueError(f"LPV-DS: the convex program for the {what} has no solution (status {problem.status})")


def _as_points(value: ArrayLike, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a float array of shape (T, d), got {type(value).__name__}") from None
    if arr.ndim != 2 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ValueError(f"{name} must have shape (T, d), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (got NaN or inf)")
    return arr


def _as_demos(value: ArrayLike | Sequence[ArrayLike], name: str) -> list[np.ndarray]:
    """One ``(T, d)`` array or a list of them -> list of validated arrays."""
    if isinstance(value, np.ndarray) or (
        isinstance(value, Sequence) and len(value) > 0 and np.ndim(value[0]) == 1  # type: ignore[arg-type]
    ):
        return [_as_points(cast(ArrayLike, value), name)]
    if not isinstance(value, Sequence) or len(value) == 0:
        raise TypeError(f"{name} must be a (T, d) array or a non-empty list of them, got {type(value).__name__}")
    return [_as_points(v, f"{name}[{i}]") for i, v in enumerate(value)]


def _benchmark_demos(n_demos: int, n_points: int, seed: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Curved 2D demonstrations ending at the origin (a spiral-in family with per-demo variation)."""
    rng = np.random.default_rng(seed)
    xs, vs = [], []
    t = np.linspace(0.0, 1.0, n_points)
    for _ in range(n_demos):
        radius = rng.uniform(5.0, 7.0) * (1.0 - t)
        angle = rng.uniform(0.6, 1.0) * np.pi * (1.0 - t) + rng.uniform(-0.3, 0.3)
        x = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
        xs.append(x)
        vs.append(velocities_from_positions(x, dt=0.01))
    return xs, vs


def benchmark_fit_time(n_demos: int = 3, n_points: int = 200, seed: int = 0) -> dict[str, float]:
    """Time an LPV-DS fit of ``n_demos`` x ``n_points`` curved 2D demonstrations (the fit-time benchmark).

    Returns ``{"fit_seconds", "n_components", "worst_margin", "n_points"}``.

    >>> result = benchmark_fit_time(n_demos=1, n_points=60)
    >>> sorted(result), result["worst_margin"] < 0
    (['fit_seconds', 'n_components', 'n_points', 'worst_margin'], True)
    """
    xs, vs = _benchmark_demos(n_demos, n_points, seed)
    ds = LPVDS(random_state=seed).fit(xs, vs, attractor=np.zeros(2))
    report = ds.check_stability()
    assert ds.fit_seconds is not None
    return {
        "fit_seconds": ds.fit_seconds,
        "n_components": float(ds.n_components_),
        "worst_margin": report.worst_margin,
        "n_points": float(n_demos * n_points),
    }
