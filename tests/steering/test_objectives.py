"""Alignment objectives xi(tau, z): values, gradients, numpy agreement, errors."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from steer_envs.core import Nudge, Point, Sketch, resample_path  # noqa: E402
from steer_envs.steering import objectives as xi  # noqa: E402


def _tau(*trajs: list) -> torch.Tensor:
    return torch.tensor(trajs, dtype=torch.float64)


# ---------------------------------------------------------------- hand values
def test_point_cost_hand_computed() -> None:
    tau = _tau([[0, 0], [3, 4], [6, 8]], [[0, 0], [0, 0], [0, 0]])
    z = Point([0, 0])
    # distances (0, 5, 10) -> mean 5; second trajectory sits on z
    np.testing.assert_allclose(xi.point_cost(tau, z).numpy(), [5.0, 0.0])
    assert xi.alignment_cost(tau, z).shape == (2,)


def test_sketch_cost_hand_computed_mean_and_sum() -> None:
    # sketch of 2 points resampled to T=3 -> (0,0), (1,0), (2,0)
    sketch = Sketch([[0, 0], [2, 0]])
    tau = _tau([[0, 1], [1, 1], [2, 1]], [[0, 0], [1, 0], [2, 3]])
    mean = xi.sketch_cost(tau, sketch).numpy()
    total = xi.sketch_cost(tau, sketch, reduction="sum").numpy()
    np.testing.assert_allclose(mean, [1.0, 1.0])
    np.testing.assert_allclose(total, [3.0, 3.0])
    np.testing.assert_allclose(xi.alignment_cost(tau, sketch, reduction="sum").numpy(), total)
    with pytest.raises(ValueError, match="`reduction` must be 'mean' or 'sum'"):
        xi.sketch_cost(tau, sketch, reduction="max")  # type: ignore[arg-type]


def test_sketch_cost_uses_index_uniform_resampling() -> None:
    rng = np.random.default_rng(0)
    sketch = rng.normal(size=(7, 2))
    tau = rng.normal(size=(4, 11, 2))
    goal = resample_path(sketch, 11)
    expected = np.linalg.norm(tau - goal, axis=-1).mean(axis=-1)
    np.testing.assert_allclose(xi.alignment_cost_np(tau, Sketch(sketch)), expected, rtol=1e-12)
    np.testing.assert_allclose(xi.resample_path_torch(torch.as_tensor(sketch), 11).numpy(), goal, rtol=1e-12)


def test_nudge_projection_and_cost() -> None:
    tau = _tau([[0, 0], [1, 1], [2, 2]], [[5, 5], [6, 6], [7, 7]])
    nudge = Nudge([[9, 9], [8, 8]])
    projected = xi.apply_nudge(tau, nudge)
    np.testing.assert_array_equal(projected[:, :2].numpy(), [[[9, 9], [8, 8]]] * 2)
    np.testing.assert_array_equal(projected[:, 2:].numpy(), tau[:, 2:].numpy())
    assert tau[0, 0, 0] == 0.0  # input untouched
    assert torch.all(xi.nudge_cost(projected, nudge) == 0.0)
    assert torch.all(torch.isinf(xi.nudge_cost(tau, nudge)))
    # tolerance
    near = projected.clone()
    near[0, 1, 0] += 1e-3
    np.testing.assert_array_equal(xi.nudge_cost(near, nudge, atol=1e-2).numpy(), [0.0, 0.0])
    np.testing.assert_array_equal(xi.alignment_cost(near, nudge).numpy(), [np.inf, 0.0])
    # numpy in, numpy out
    out = xi.apply_nudge(tau.numpy(), nudge)
    assert isinstance(out, np.ndarray)
    np.testing.assert_array_equal(out, projected.numpy())


def test_nudge_gradient_flows_to_kept_states() -> None:
    tau = torch.zeros(2, 4, 2, dtype=torch.float64, requires_grad=True)
    out = xi.apply_nudge(tau, Nudge([[1.0, 1.0]]))
    out.sum().backward()
    assert tau.grad is not None
    np.testing.assert_array_equal(tau.grad[:, 0].numpy(), 0.0)  # overwritten: no gradient
    np.testing.assert_array_equal(tau.grad[:, 1:].numpy(), 1.0)


# ------------------------------------------------------------------ gradients
def test_gradcheck_point_and_sketch() -> None:
    gen = torch.Generator().manual_seed(0)
    tau = torch.randn(3, 5, 2, dtype=torch.float64, generator=gen, requires_grad=True)
    point = Point([0.3, -0.2])
    sketch = Sketch([[0.0, 0.0], [1.0, 0.5], [2.0, -1.0]])
    assert torch.autograd.gradcheck(lambda t: xi.point_cost(t, point), (tau,))
    assert torch.autograd.gradcheck(lambda t: xi.sketch_cost(t, sketch), (tau,))
    assert torch.autograd.gradcheck(lambda t: xi.sketch_cost(t, sketch, reduction="sum"), (tau,))
    # gradient with respect to the sketch itself (e.g. a learned or normalized sketch)
    path = torch.tensor(sketch.points, requires_grad=True)
    assert torch.autograd.gradcheck(lambda p: xi.sketch_cost(tau.detach(), p), (path,))


def test_gradient_matches_closed_form_and_is_finite_on_target() -> None:
    tau = torch.tensor([[[3.0, 4.0], [0.0, 0.0]]], dtype=torch.float64, requires_grad=True)
    xi.point_cost(tau, Point([0.0, 0.0])).sum().backward()
    # d/ds ||s|| / T = s / (T ||s||); zero (not NaN) at the target
    np.testing.assert_allclose(tau.grad.numpy(), [[[0.3, 0.4], [0.0, 0.0]]])


def test_gradient_descent_on_sketch_cost_reaches_the_sketch() -> None:
    sketch = Sketch([[0.0, 0.0], [4.0, 2.0]])
    tau = torch.zeros(1, 9, 2, dtype=torch.float64, requires_grad=True)
    # the gradient of a norm has unit length per step, so a small fixed step converges to within ~lr
    opt = torch.optim.SGD([tau], lr=0.05)
    for _ in range(300):
        opt.zero_grad()
        xi.sketch_cost(tau, sketch, reduction="sum").sum().backward()
        opt.step()
    assert xi.sketch_cost(tau, sketch).item() < 0.05


# ------------------------------------------------------- dtype, device, numpy
def test_dtype_follows_tau_and_numpy_agrees() -> None:
    rng = np.random.default_rng(1)
    tau_np = rng.normal(size=(5, 8, 3))
    for interaction in (Point([0.1, 0.2, 0.3]), Sketch(rng.normal(size=(4, 3))), Nudge(tau_np[0, :2])):
        ref = xi.alignment_cost(torch.as_tensor(tau_np), interaction).numpy()
        np.testing.assert_allclose(xi.alignment_cost_np(tau_np, interaction), ref)
        np.testing.assert_allclose(xi.alignment_cost_np(tau_np.tolist(), interaction), ref)
        c32 = xi.alignment_cost(torch.as_tensor(tau_np, dtype=torch.float32), interaction)
        assert c32.dtype == torch.float32
        np.testing.assert_allclose(c32.numpy(), ref, rtol=1e-5)
    nudge_np = xi.alignment_cost_np(tau_np, Nudge(tau_np[0, :2]))
    assert nudge_np[0] == 0.0 and np.all(np.isinf(nudge_np[1:]))
    assert xi.alignment_cost_np(tau_np, Point([0, 0, 0])).dtype == np.float64


def test_raw_arrays_and_tensors_accepted_as_interaction_data() -> None:
    tau = torch.randn(2, 6, 2, dtype=torch.float64)
    sk = np.array([[0.0, 0.0], [1.0, 1.0]])
    ref = xi.sketch_cost(tau, Sketch(sk))
    torch.testing.assert_close(xi.sketch_cost(tau, sk), ref)
    torch.testing.assert_close(xi.sketch_cost(tau, torch.as_tensor(sk, dtype=torch.float32)), ref, rtol=1e-6, atol=1e-6)
    torch.testing.assert_close(xi.point_cost(tau, [1.0, 2.0]), xi.point_cost(tau, Point([1.0, 2.0])))


# ---------------------------------------------------------------------- errors
def test_errors_name_the_argument() -> None:
    tau = torch.zeros(2, 4, 2, dtype=torch.float64)
    with pytest.raises(ValueError, match=r"`tau` must have shape \(B, T, d\)"):
        xi.point_cost(tau[0], Point([0, 0]))
    with pytest.raises(TypeError, match=r"`tau` must be a torch\.Tensor"):
        xi.point_cost(np.zeros((2, 4, 2)), Point([0, 0]))  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="floating-point"):
        xi.point_cost(torch.zeros(2, 4, 2, dtype=torch.long), Point([0, 0]))
    with pytest.raises(ValueError, match="`target` must have state dimension 2"):
        xi.point_cost(tau, Point([0, 0, 0]))
    with pytest.raises(ValueError, match="`sketch` must have 2-D shape with state dimension 2"):
        xi.sketch_cost(tau, torch.zeros(3, 3))
    with pytest.raises(ValueError, match="`sketch` must be finite"):
        xi.sketch_cost(tau, torch.tensor([[0.0, 0.0], [float("nan"), 0.0]]))
    with pytest.raises(ValueError, match="k=5 states but `tau` only T=4"):
        xi.apply_nudge(tau, Nudge(np.zeros((5, 2))))
    with pytest.raises(ValueError, match="k=5 states"):
        xi.nudge_cost(tau, Nudge(np.zeros((5, 2))))
    with pytest.raises(ValueError, match="`atol` must be >= 0"):
        xi.nudge_cost(tau, Nudge(np.zeros((1, 2))), atol=-1.0)
    with pytest.raises(TypeError, match="`interaction` must be a Point, Sketch or Nudge"):
        xi.alignment_cost(tau, np.zeros(2))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="`tau` must have shape"):
        xi.alignment_cost_np(np.zeros((4, 2)), Point([0, 0]))
    with pytest.raises(TypeError, match="`tau` must hold real numbers"):
        xi.alignment_cost_np(np.array([[["a"]]]), Point([0]))


def test_core_does_not_import_torch() -> None:
    code = "import sys, steer_envs, steer_envs.core; assert 'torch' not in sys.modules, 'torch imported'"
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
