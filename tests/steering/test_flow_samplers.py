"""BI, GD and SS on flow-matching policies: each one's equations and defining property, on an exact flow."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest
from stub_policies import LineModes, RandomLines
from test_samplers import counted_samplers, network_evals

torch = pytest.importorskip("torch")

from steer_envs.core.interaction import Point, Sketch  # noqa: E402
from steer_envs.core.policy import DiffusionPolicyLike, FlowPolicyLike  # noqa: E402
from steer_envs.steering import (  # noqa: E402
    SAMPLERS,
    BiasedInitialization,
    GuidedDiffusion,
    StochasticSampling,
    make_sampler,
)
from steer_envs.steering.diffusion import NormalizedObjective  # noqa: E402
from steer_envs.steering.flow import integrate_plans, is_flow_policy, train_timesteps  # noqa: E402

OBS = np.zeros(2)


class FlowMixture(LineModes):
    """Exact rectified-flow velocity of a Gaussian mixture of straight-line plans from the agent (K headings).

    Data: ``x1 ~ N(m_k, std^2 I)`` with ``m_k = normalize(obs + s * L * u_k)`` for
    ``s`` in ``(0, 1]``, heading ``u_k``, equal weights: the diffusion test double's
    modes (:class:`LineModes`, ``geometry`` its arguments). At ``(x, tau)``,
    ``x ~ N(tau m_k, (tau^2 std^2 + (1 - tau)^2) I)`` under component ``k`` and
    ``E[x1 - x0 | x, k] = m_k + (tau std^2 - (1 - tau)) / var * (x - tau m_k)``;
    the velocity is their posterior-weighted mean. ``sample`` is
    :func:`integrate_plans`. Records every ``(x, tau)`` it is called with and
    checks ``tau`` is a float in ``[0, 1)`` (integration never evaluates at 1).
    """

    action_dim = 2
    num_inference_steps = 10
    device = torch.device("cpu")
    dtype = torch.float64

    def __init__(self, **geometry: Any) -> None:
        super().__init__(**geometry)
        self.inputs: list[tuple[torch.Tensor, float]] = []

    @property
    def calls(self) -> int:
        return len(self.inputs)

    def predict_velocity(self, x: torch.Tensor, tau: Any, cond: torch.Tensor) -> torch.Tensor:
        assert isinstance(tau, float) and 0.0 <= tau < 1.0, tau
        self.inputs.append((x.detach().clone(), tau))
        s2 = self.std**2
        var = tau**2 * s2 + (1 - tau) ** 2
        diff = x.to(torch.float64)[:, None] - tau * cond[None]
        logw = -(diff**2).sum((-1, -2)) / (2 * var)
        weights = (logw - logw.logsumexp(dim=1, keepdim=True)).exp()[:, :, None, None]
        velocity = cond[None] + (tau * s2 - (1 - tau)) / var * diff
        return (weights * velocity).sum(1).to(x.dtype)

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        return integrate_plans(self, obs, n, generator)


class StandStill(FlowMixture):
    """``v = 0``: plans move only by guidance, so each step's displacement is the guidance term itself."""

    def predict_velocity(self, x: torch.Tensor, tau: Any, cond: torch.Tensor) -> torch.Tensor:
        super().predict_velocity(x, tau, cond)
        return torch.zeros_like(x)


def sketch_at(angle_deg: float, length: float = 3.0, points: int = 20) -> Sketch:
    a = np.deg2rad(angle_deg)
    return Sketch(np.linspace(0, 1, points)[:, None] * length * np.array([np.cos(a), np.sin(a)]))


def run(name: str, policy: Any, interaction: Any, *, seed: int = 0, n: int = 32, **kwargs: Any) -> Any:
    return make_sampler(name, **kwargs)(policy, OBS, interaction, n, generator=np.random.default_rng(seed))


@pytest.fixture
def policy() -> FlowMixture:
    return FlowMixture()


def reference(policy: FlowMixture, interaction: Any, seed: int, n: int, *, beta: float, m: int) -> np.ndarray:
    """GD/SS written out from the brief's equations, independently of steer_envs.steering.flow."""
    rng = np.random.default_rng(seed)
    k_steps, t_big = policy.num_inference_steps, 100
    objective = NormalizedObjective(policy, interaction, torch.float64)
    cond = policy.encode_obs(OBS)
    shape = (n, policy.horizon, 2)
    x = torch.as_tensor(rng.standard_normal(shape))
    for k in range(k_steps):
        tau = k / k_steps
        t_ddim = t_big * (k_steps - 1 - k) / k_steps  # DDIM's number for this step: guided where > 0
        for j in range(m):
            v = policy.predict_velocity(x, tau, cond)
            if t_ddim > 0:
                v = v - beta / max(tau, 1 / k_steps) * objective.grad(x)  # eps_hat = eps + beta grad xi
            if j < m - 1:
                x = tau * (x + (1 - tau) * v) + (1 - tau) * torch.as_tensor(rng.standard_normal(shape))
            else:
                x = x + v / k_steps
    return policy.unnormalize(x).numpy()


# ------------------------------------------------------------------ the test double and RS/PR/OP
def test_the_test_double_is_a_flow_policy_whose_integration_lands_on_its_modes(policy: FlowMixture) -> None:
    assert isinstance(policy, FlowPolicyLike) and not isinstance(policy, DiffusionPolicyLike)
    assert is_flow_policy(policy) and not is_flow_policy(RandomLines())
    plans = policy.sample(OBS, 64, generator=np.random.default_rng(1))
    assert plans.shape == (64, 16, 2) and plans.dtype == np.float64
    assert policy.off_manifold(plans, OBS).max() < 0.1  # every plan ends on a straight-line mode
    nearest = np.argmin(np.linalg.norm(plans[:, None] - policy.modes(OBS)[None], axis=-1).mean(-1), axis=1)
    assert len(set(nearest.tolist())) == 4  # and the batch is multimodal
    assert [tau for _, tau in policy.inputs] == [k / 10 for k in range(10)]  # K Euler steps, tau_k = k / K


@pytest.mark.parametrize("name", sorted(SAMPLERS))
def test_all_six_samplers_run_on_a_flow_policy_and_a_seed_fixes_the_plans(policy: FlowMixture, name: str) -> None:
    sketch = sketch_at(60.0, points=25)
    a, b, c = (run(name, policy, sketch, seed=s, n=6) for s in (7, 7, 8))
    np.testing.assert_array_equal(a.plans, b.plans)
    assert a.chosen == b.chosen and a.sampler == name
    assert not np.array_equal(a.plans, c.plans)
    assert a.plans.shape == (6, 16, 2) and a.costs.shape == (6,) and np.all(np.isfinite(a.costs))


# ------------------------------------------------------------------ GD and SS
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_gd_without_guidance_is_rs_and_ss_with_m1_is_gd(policy: FlowMixture, dtype: torch.dtype) -> None:
    policy.dtype = dtype  # float32 policies get float32 noise draws, as their own sampler
    sketch = sketch_at(45.0)
    unguided = run("GD", policy, sketch, seed=4, n=8, guide_ratio=0.0)
    rs = run("RS", policy, sketch, seed=4, n=8)
    np.testing.assert_array_equal(unguided.plans, rs.plans)
    gd = run("GD", policy, sketch, seed=4, n=8, guide_ratio=60.0)
    ss1 = run("SS", policy, sketch, seed=4, n=8, guide_ratio=60.0, mcmc_steps=1)
    np.testing.assert_array_equal(ss1.plans, gd.plans)
    assert not np.allclose(gd.plans, rs.plans)


@pytest.mark.parametrize(("name", "beta", "m"), [("GD", 20.0, 1), ("SS", 60.0, 4), ("SS", 5.0, 2)])
def test_gd_and_ss_follow_the_guided_velocity_equations(policy: FlowMixture, name: str, beta: float, m: int) -> None:
    sketch = sketch_at(30.0)
    kwargs = {"guide_ratio": beta} if name == "GD" else {"guide_ratio": beta, "mcmc_steps": m}
    got = run(name, policy, sketch, seed=3, n=5, **kwargs)
    np.testing.assert_allclose(got.plans, reference(FlowMixture(), sketch, 3, 5, beta=beta, m=m), atol=1e-10)


def test_guidance_steps_the_velocity_by_beta_over_tau_floored_at_the_step_size() -> None:
    """With ``v = 0`` step ``k`` moves ``x`` by ``-(beta / max(tau_k, 1/K)) grad xi / K``; the last step is unguided."""
    still = StandStill()
    target = Point([2.0, -1.0])
    objective = NormalizedObjective(still, target, torch.float64)
    plans = GuidedDiffusion(guide_ratio=0.5)(still, OBS, target, 3, generator=np.random.default_rng(0)).plans
    xs = [x for x, _ in still.inputs]  # x at tau = 0, 0.1, ..., 0.9
    for k in range(9):
        expected = xs[k] - 0.5 / max(k / 10, 0.1) * objective.grad(xs[k]) / 10  # tau = 0 -> 1 / K, no division by 0
        torch.testing.assert_close(xs[k + 1], expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(plans, still.unnormalize(xs[9]).numpy(), atol=1e-12)  # no guidance on the last step


@pytest.mark.parametrize(("min_guided_t", "guided"), [(0, 9), (50, 4), (85, 1), (90, 0)])
def test_min_guided_t_switches_guidance_off_on_the_steps_ddim_numbers_at_or_below_it(
    min_guided_t: int, guided: int
) -> None:
    """Step ``k`` counts as DDIM's step ``t_k = T (K - 1 - k) / K``: the same steps as a DDPM's ``t > min_guided_t``."""
    still = StandStill()
    GuidedDiffusion(min_guided_t=min_guided_t)(still, OBS, sketch_at(0.0), 2, generator=np.random.default_rng(0))
    xs = [x for x, _ in still.inputs]
    moved = [not torch.equal(a, b) for a, b in itertools.pairwise(xs)]
    assert sum(moved) == guided and moved == sorted(moved, reverse=True)  # the first `guided` steps


@pytest.mark.parametrize("angle", [30.0, 60.0])
def test_gd_and_ss_pull_the_batch_to_the_sketch_and_stay_on_the_modes(policy: FlowMixture, angle: float) -> None:
    sketch = sketch_at(angle)  # between two modes: unsteered samples are mostly far from it
    rs, gd, ss = (run(name, policy, sketch, seed=2) for name in ("RS", "GD", "SS"))
    assert gd.costs.mean() < 0.6 * rs.costs.mean() and ss.costs.mean() < 0.6 * rs.costs.mean()
    assert ss.costs.min() <= rs.costs.min() + 0.05  # SS finds the closest mode PR could pick
    assert policy.off_manifold(gd.plans, OBS).mean() < 0.1 and policy.off_manifold(ss.plans, OBS).mean() < 0.1
    assert gd.chosen == int(np.argmin(gd.costs)) and ss.chosen == int(np.argmin(ss.costs))


def test_ss_stays_nearer_the_data_than_gd_at_the_same_guide_ratio(policy: FlowMixture) -> None:
    sketch = sketch_at(30.0)
    for seed in range(3):
        gd, ss = (run(name, policy, sketch, seed=seed, guide_ratio=60.0) for name in ("GD", "SS"))
        assert policy.off_manifold(ss.plans, OBS).mean() < 0.6 * policy.off_manifold(gd.plans, OBS).mean()


def test_network_evaluations_of_the_flow_forms(policy: FlowMixture) -> None:
    samplers = {
        **counted_samplers(),
        "BI0": BiasedInitialization(start_t=0),
        "BI100": BiasedInitialization(start_t=100),
    }
    counts = network_evals(policy, samplers)
    assert counts == {"GD": 10, "SS": 40, "SS2": 20, "BI": 5, "BI0": 0, "BI100": 10}


def test_clipped_model_output_changes_nothing_for_a_flow(policy: FlowMixture) -> None:
    sketch = sketch_at(45.0)
    plain = run("GD", policy, sketch, seed=1, n=4)
    clipped = run("GD", policy, sketch, seed=1, n=4, use_clipped_model_output=True)
    np.testing.assert_array_equal(plain.plans, clipped.plans)


# ------------------------------------------------------------------ BI
def test_bi_starts_from_the_sketch_at_tau_half_and_stays_near_it(policy: FlowMixture) -> None:
    sketch = sketch_at(45.0)
    exact = run("BI", policy, sketch, seed=0, init_std=0.0)
    x_first, tau_first = policy.inputs[0]
    assert tau_first == 0.5 and [tau for _, tau in policy.inputs] == [0.5, 0.6, 0.7, 0.8, 0.9]
    goal = policy.normalize(sketch.resample(policy.horizon).points)
    np.testing.assert_allclose(x_first.numpy(), np.broadcast_to(goal, x_first.shape), atol=1e-12)
    policy.inputs.clear()
    noisy = run("BI", policy, sketch, seed=0)
    residual = (policy.inputs[0][0].numpy() - goal).reshape(-1)
    assert abs(residual.std() - 0.5) < 0.05 and abs(residual.mean()) < 0.05  # sketch + 0.5 N(0, I)
    rs = run("RS", policy, sketch, seed=0)
    assert noisy.costs.mean() < 0.7 * rs.costs.mean() and exact.costs.mean() < 0.7 * rs.costs.mean()
    assert policy.off_manifold(noisy.plans, OBS).mean() < 0.1


def test_bi_reads_t_from_the_policy_and_rounds_tau_start_up_to_the_grid(policy: FlowMixture) -> None:
    sketch = sketch_at(45.0)
    policy.num_train_timesteps = 1000  # start_t = 150 of 1000: tau 0.85 -> the last step only
    run("BI", policy, sketch, n=2, start_t=150)
    assert [tau for _, tau in policy.inputs] == [0.9] and train_timesteps(policy) == 1000
    untouched = run("BI", policy, sketch, n=2, init_std=0.0)  # start_t = 50 of 1000: tau 0.95, no step left
    assert len(policy.inputs) == 1 and untouched.timings["network_evals"] == 0
    np.testing.assert_allclose(untouched.plans[0], sketch.resample(policy.horizon).points, atol=1e-12)
    del policy.num_train_timesteps
    policy.config = type("Config", (), {"num_train_timesteps": 10})()  # a config's T counts too
    policy.inputs.clear()
    run("BI", policy, sketch, n=2, start_t=3)  # tau_start 0.7 exactly: integer arithmetic, no float slack
    assert [tau for _, tau in policy.inputs] == [0.7, 0.8, 0.9]


def test_point_interactions_steer_a_flow_too(policy: FlowMixture) -> None:
    target = Point([2.0, 2.0])
    rs, gd, ss, bi = (run(name, policy, target, seed=0) for name in ("RS", "GD", "SS", "BI"))
    assert max(gd.costs.mean(), ss.costs.mean(), bi.costs.mean()) < rs.costs.mean()


def test_interaction_dims_steer_the_drawn_entries_of_a_flow(policy: FlowMixture) -> None:
    policy.interaction_dims = (1,)  # steer y only: a 1-D sketch going up
    up = Sketch(np.linspace(0.0, 3.0, 16)[:, None])
    steered, free = run("GD", policy, up), run("RS", policy, up)
    assert steered.costs.mean() < 0.5 * free.costs.mean()
    assert run("SS", policy, up, n=4).plans.shape == run("BI", policy, up, n=4).plans.shape == (4, 16, 2)


# ------------------------------------------------------------------ contracts and bad input
def test_a_policy_that_is_both_is_denoised_and_other_policies_are_refused_naming_both_protocols() -> None:
    diffusers = pytest.importorskip("diffusers")

    class Both(FlowMixture):
        scheduler = diffusers.DDIMScheduler(num_train_timesteps=100)
        noise_calls = 0

        def predict_noise(self, x: torch.Tensor, t: Any, cond: Any) -> torch.Tensor:
            self.noise_calls += 1
            return torch.zeros_like(x)

    both = Both()
    assert isinstance(both, DiffusionPolicyLike) and not is_flow_policy(both)
    run("GD", both, sketch_at(0.0), n=2)
    assert both.noise_calls == 10 and both.calls == 0
    for cls in (BiasedInitialization, GuidedDiffusion, StochasticSampling):
        with pytest.raises(TypeError, match=r"DiffusionPolicyLike .* or a FlowPolicyLike .*predict_velocity"):
            cls()(RandomLines(), OBS, sketch_at(0.0), 4)


@pytest.mark.parametrize("name", ["BI", "GD", "SS"])
@pytest.mark.parametrize(
    ("output", "match"),
    [
        (lambda x: x[:, :-1], r"predict_velocity must return a tensor of shape \(3, 16, 2\), got \(3, 15, 2\)"),
        (lambda x: x.numpy(), "predict_velocity must return a tensor of shape"),
        (lambda x: torch.full_like(x, float("nan")), "non-finite plans"),
    ],
)
def test_bad_velocities_are_named(policy: FlowMixture, name: str, output: Any, match: str) -> None:
    policy.predict_velocity = lambda x, tau, cond: output(torch.zeros_like(x))  # type: ignore[method-assign]
    with pytest.raises(ValueError, match=match):
        run(name, policy, sketch_at(0.0), n=3)
    with pytest.raises(ValueError, match=match):
        integrate_plans(policy, OBS, 3, np.random.default_rng(0))


@pytest.mark.parametrize(
    ("attribute", "value", "error", "match"),
    [
        ("num_inference_steps", 0, ValueError, "num_inference_steps"),
        ("num_inference_steps", 2.5, TypeError, "num_inference_steps"),
        ("num_train_timesteps", 0, ValueError, "num_train_timesteps"),
        ("num_train_timesteps", "100", TypeError, "num_train_timesteps"),
    ],
)
def test_bad_step_counts_are_named(policy: FlowMixture, attribute: str, value: Any, error: type, match: str) -> None:
    setattr(policy, attribute, value)
    with pytest.raises(error, match=match):
        run("BI", policy, sketch_at(0.0), n=2)
    if attribute == "num_inference_steps":
        with pytest.raises(error, match=match):
            integrate_plans(policy, OBS, 2, np.random.default_rng(0))


def test_integrate_plans_checks_its_arguments(policy: FlowMixture) -> None:
    with pytest.raises(ValueError, match="`n`"):
        integrate_plans(policy, OBS, 0, np.random.default_rng(0))
    with pytest.raises(TypeError, match="generator"):
        integrate_plans(policy, OBS, 2, np.random.RandomState(0))  # type: ignore[arg-type]
    assert integrate_plans(policy, OBS, 2, None).shape == (2, 16, 2)
