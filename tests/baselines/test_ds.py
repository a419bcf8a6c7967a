"""LPV-DS: stability certificate, fit quality, 2D/3D, batching and input validation."""

from __future__ import annotations

import numpy as np
import pytest

from steer_envs.baselines.lpv_ds.lpvds import LPVDS, _benchmark_demos, benchmark_fit_time, velocities_from_positions
from steer_envs.core.policy import VelocityPolicy


@pytest.fixture(scope="module")
def demos_2d() -> tuple[list[np.ndarray], list[np.ndarray]]:
    return _benchmark_demos(3, 200, seed=0)


@pytest.fixture(scope="module")
def fitted_2d(demos_2d) -> LPVDS:
    xs, vs = demos_2d
    return LPVDS(random_state=0).fit(xs, vs, attractor=np.zeros(2))


def _integrate(ds: LPVDS, x0: np.ndarray, steps: int, dt: float = 0.01, max_speed: float = 20.0) -> np.ndarray:
    x = np.array(x0, dtype=float)
    path = [x]
    for _ in range(steps):
        v = ds(x)
        v *= np.minimum(1.0, max_speed / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12))
        x = x + dt * v
        path.append(x)
    return np.stack(path, axis=1)  # (N, T, d)


def test_certificate_holds_numerically(fitted_2d: LPVDS) -> None:
    report = fitted_2d.check_stability()
    assert report.stable
    assert report.p_min_eig > 0
    assert np.all(report.margins <= -0.99 * fitted_2d.eps)  # the LMI margin the fit asked for
    assert report.attractor_residual < 1e-9
    np.testing.assert_allclose(fitted_2d.b, -np.einsum("kij,j->ki", fitted_2d.A, fitted_2d.attractor))
    # independent of the eigenvalue test: V decreases along the flow everywhere we look
    x = np.random.default_rng(1).uniform(-20, 20, size=(5000, 2))
    assert np.all(fitted_2d.lyapunov_derivative(x) < 0)
    np.testing.assert_allclose(fitted_2d(np.zeros((1, 2))), 0.0, atol=1e-12)


def test_rollouts_reproduce_demos_and_reach_attractor(fitted_2d: LPVDS, demos_2d) -> None:
    xs, _ = demos_2d
    paths = _integrate(fitted_2d, np.stack([d[0] for d in xs]), steps=2000)
    assert np.all(np.linalg.norm(paths[:, -1], axis=1) < 0.05)
    for demo, path in zip(xs, paths, strict=True):
        gap = np.min(np.linalg.norm(demo[:, None] - path[None], axis=2), axis=1)  # demo point -> nearest rollout
        assert gap.mean() < 0.15


def test_fits_a_single_demonstration_and_picks_k_by_bic(demos_2d) -> None:
    xs, vs = demos_2d
    ds = LPVDS().fit(xs[0], vs[0])  # attractor defaults to the demo's last point
    np.testing.assert_allclose(ds.attractor, xs[0][-1])
    assert ds.check_stability().stable
    assert 1 <= ds.n_components_ <= ds.max_components
    fixed = LPVDS(n_components=2).fit(xs[0], vs[0])
    assert fixed.n_components_ == 2
    # a straight line at constant direction needs one component
    t = np.linspace(0, 1, 150)[:, None]
    line = (1 - t) * np.array([-4.0, 1.0])
    assert LPVDS().fit(line, np.gradient(line, 0.01, axis=0)).n_components_ <= 2


def test_learned_p_fits_a_non_contracting_system_better_than_identity() -> None:
    # x' = A x with A stable but not contracting in the Euclidean norm (A + A^T is indefinite):
    # P = I cannot certify it, a learned P can.
    a = np.array([[-1.0, 6.0], [0.0, -1.5]])
    assert np.linalg.eigvalsh(a + a.T).max() > 0
    xs, vs = [], []
    for x0 in ([0.0, 4.0], [3.0, -3.0], [-4.0, 2.0]):
        x = [np.array(x0)]
        for _ in range(400):
            x.append(x[-1] + 0.01 * a @ x[-1])
        x = np.asarray(x)
        xs.append(x)
        vs.append(x @ a.T)

    def rel_err(ds: LPVDS) -> float:
        X, V = np.concatenate(xs), np.concatenate(vs)
        return float(np.linalg.norm(ds(X) - V) / np.linalg.norm(V))

    learned = LPVDS(a_max=20.0).fit(xs, vs, attractor=np.zeros(2))
    identity = LPVDS(a_max=20.0, learn_p=False).fit(xs, vs, attractor=np.zeros(2))
    assert learned.check_stability().stable and identity.check_stability().stable
    assert rel_err(learned) < 0.5 * rel_err(identity)
    assert rel_err(learned) < 0.2


def test_3d_fit_is_stable_and_converges() -> None:
    t = np.linspace(0, 1, 200)[:, None]
    xs, vs = [], []
    for phase in (0.0, 1.0, 2.0):
        x = np.hstack([(1 - t) * 4 * np.cos(3 * t + phase), (1 - t) * 4 * np.sin(3 * t + phase), (1 - t) ** 2 * 3])
        xs.append(x)
        vs.append(velocities_from_positions(x, dt=0.01))
    ds = LPVDS().fit(xs, vs, attractor=np.zeros(3))
    assert ds.check_stability().stable
    assert ds(np.ones((7, 3))).shape == (7, 3)
    end = _integrate(ds, np.stack([x[0] for x in xs]), steps=3000)[:, -1]
    assert np.all(np.linalg.norm(end, axis=1) < 0.05)


def test_batched_call_gamma_and_protocol(fitted_2d: LPVDS) -> None:
    x = np.random.default_rng(0).uniform(-6, 6, size=(11, 2))
    out = fitted_2d(x)
    assert out.shape == (11, 2)
    np.testing.assert_allclose(fitted_2d(x[3]), out[3])  # a single state gives a single velocity
    g = fitted_2d.gamma(x)
    assert g.shape == (11, fitted_2d.n_components_)
    np.testing.assert_allclose(g.sum(axis=1), 1.0)
    assert np.all(fitted_2d.gamma(np.array([[1e4, -1e4]])) >= 0)  # far away: still a valid mixture
    assert isinstance(fitted_2d, VelocityPolicy)
    with pytest.raises(ValueError, match="shape"):
        fitted_2d(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="finite"):
        fitted_2d(np.array([[np.nan, 0.0]]))


def test_from_parameters_round_trip(fitted_2d: LPVDS) -> None:
    ds = LPVDS.from_parameters(
        fitted_2d.attractor, fitted_2d.P, fitted_2d.A, fitted_2d.weights, fitted_2d.means, fitted_2d.covariances
    )
    x = np.random.default_rng(3).uniform(-5, 5, size=(20, 2))
    np.testing.assert_allclose(ds(x), fitted_2d(x))
    assert ds.check_stability().stable
    unstable = LPVDS.from_parameters(np.zeros(2), np.eye(2), np.eye(2)[None], [1.0], np.zeros((1, 2)), np.eye(2)[None])
    assert not unstable.check_stability().stable
    with pytest.raises(ValueError, match="means"):
        LPVDS.from_parameters(np.zeros(2), np.eye(2), np.eye(2)[None], [1.0], np.zeros((2, 2)), np.eye(2)[None])


def test_degenerate_input_is_rejected(demos_2d) -> None:
    xs, vs = demos_2d
    with pytest.raises(ValueError, match="at least"):
        LPVDS().fit(xs[0][:4], vs[0][:4])
    bad = xs[0].copy()
    bad[5, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        LPVDS().fit(bad, vs[0])
    with pytest.raises(ValueError, match="attractor"):
        LPVDS().fit(xs[0], vs[0], attractor=xs[0][0])  # the demo's start, not its end
    with pytest.raises(ValueError, match=r"same number|shapes"):
        LPVDS().fit(xs, vs[:2])
    with pytest.raises(ValueError, match="zero"):
        LPVDS().fit(xs[0], np.zeros_like(vs[0]))
    with pytest.raises(ValueError, match="identical"):
        LPVDS().fit(np.ones((50, 2)), vs[0][:50])
    with pytest.raises(ValueError, match="attractor must be"):
        LPVDS().fit(xs[0], vs[0], attractor=np.zeros(3))
    with pytest.raises(ValueError, match="n_components"):
        LPVDS(n_components=0)
    with pytest.raises(ValueError, match="eps"):
        LPVDS(eps=-1.0)
    with pytest.raises(RuntimeError, match="not fitted"):
        LPVDS()(np.zeros((1, 2)))


def test_velocities_from_positions_is_exact_on_a_cubic() -> None:
    t = np.arange(100) * 0.01
    x = np.stack([t**3, 2 * t], axis=1)
    v = velocities_from_positions(x, dt=0.01)
    np.testing.assert_allclose(v, np.stack([3 * t**2, np.full_like(t, 2.0)], axis=1), atol=1e-9)
    with pytest.raises(ValueError, match="dt"):
        velocities_from_positions(x, dt=0.0)


def test_benchmark_reports_a_fit_time() -> None:
    out = benchmark_fit_time(n_demos=3, n_points=200, seed=0)
    assert set(out) == {"fit_seconds", "n_components", "worst_margin", "n_points"}
    assert out["n_points"] == 600 and out["fit_seconds"] > 0 and out["worst_margin"] < 0
