"""ITPS samplers: each one's defining property, on an exact diffusion policy of straight-line plans."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from stub_policies import ExactDiffusion, LineModes, RandomLines

torch = pytest.importorskip("torch")
diffusers = pytest.importorskip("diffusers")

from steer_envs.core.interaction import Nudge, Point, Sketch  # noqa: E402
from steer_envs.core.policy import DiffusionPolicyLike, TrajectoryPolicy  # noqa: E402
from steer_envs.steering import (  # noqa: E402
    SAMPLERS,
    BiasedInitialization,
    GuidedDiffusion,
    OutputPerturbation,
    PostHocRanking,
    RandomSampling,
    StochasticSampling,
    benchmark_latency,
    make_sampler,
    output_perturbation_point,
    place_observation,
)
from steer_envs.steering.objectives import alignment_cost_np  # noqa: E402


class MixturePolicy(LineModes, ExactDiffusion):
    """Exact epsilon of a Gaussian mixture of straight-line plans from the agent (K headings).

    Data: ``x0 = normalize(obs + s * L * u_k)`` for ``s`` in ``(0, 1]`` and heading
    ``u_k`` with equal weights, isotropic std ``std`` (normalized units): the
    modes of :class:`LineModes`, ``geometry`` its arguments. The noise estimate
    at level ``t`` is the mixture's score in closed form, so every sampler runs
    against a known distribution. Counts ``predict_noise`` calls and records the
    observations ``sample`` saw.
    """

    action_dim = 2

    def __init__(self, **geometry: Any) -> None:
        super().__init__(**geometry)
        self.scheduler = diffusers.DDIMScheduler(
            num_train_timesteps=100, beta_schedule="squaredcos_cap_v2", clip_sample=True
        )
        self.calls = 0
        self.first_inputs: list[Any] = []
        self.seen_obs: list[np.ndarray] = []

    def predict_noise(self, x_t: torch.Tensor, t: Any, cond: torch.Tensor) -> torch.Tensor:
        if self.calls == 0:
            self.first_inputs.append((x_t.detach().clone(), int(t)))
        self.calls += 1
        abar = self.scheduler.alphas_cumprod[int(t)].to(torch.float64)
        var = abar * self.std**2 + 1 - abar
        diff = x_t.to(torch.float64)[:, None] - abar.sqrt() * cond[None]
        logw = -(diff**2).sum((-1, -2)) / (2 * var)
        weights = (logw - logw.logsumexp(dim=1, keepdim=True)).exp()[:, :, None, None]
        return ((1 - abar).sqrt() * (weights * diff).sum(1) / var).to(x_t.dtype)

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        self.seen_obs.append(np.array(obs))
        return super().sample(obs, n, generator=generator)


def sketch_at(angle_deg: float, length: float = 3.0, points: int = 20, origin: Any = (0.0, 0.0)) -> Sketch:
    a = np.deg2rad(angle_deg)
    direction = np.array([np.cos(a), np.sin(a)])
    return Sketch(np.asarray(origin, dtype=np.float64) + np.linspace(0, 1, points)[:, None] * length * direction)


OBS = np.zeros(2)


@pytest.fixture
def policy() -> MixturePolicy:
    return MixturePolicy()


def run(name: str, policy: Any, interaction: Any, *, seed: int = 0, n: int = 32, **kwargs: Any) -> Any:
    return make_sampler(name, **kwargs)(policy, OBS, interaction, n, generator=np.random.default_rng(seed))


def test_the_test_double_is_a_diffusion_policy_with_the_expected_modes(policy: MixturePolicy) -> None:
    assert isinstance(policy, DiffusionPolicyLike) and isinstance(RandomLines(), TrajectoryPolicy)
    assert not isinstance(RandomLines(), DiffusionPolicyLike)
    plans = policy.sample(OBS, 64, generator=np.random.default_rng(1))
    off = policy.off_manifold(plans, OBS)
    assert off.max() < 0.2  # every sample lands on one of the straight-line modes
    nearest = np.argmin(np.linalg.norm(plans[:, None] - policy.modes(OBS)[None], axis=-1).mean(-1), axis=1)
    assert len(set(nearest.tolist())) == 4  # and the batch is multimodal


def test_pr_picks_the_min_cost_plan_of_the_batch_rs_draws_from(policy: MixturePolicy) -> None:
    sketch = sketch_at(80.0)
    rs, pr = run("RS", policy, sketch, seed=5), run("PR", policy, sketch, seed=5)
    np.testing.assert_array_equal(rs.plans, pr.plans)  # same generator state -> same batch
    np.testing.assert_allclose(pr.costs, alignment_cost_np(pr.plans, sketch))
    assert pr.chosen == int(np.argmin(pr.costs))
    assert pr.costs[pr.chosen] == pr.costs.min() < np.median(pr.costs)
    picks = {run("RS", policy, sketch, seed=s, n=8).chosen for s in range(12)}
    assert len(picks) > 3  # RS picks at random, not by cost
    assert rs.sampler == "RS" and pr.sampler == "PR" and rs.perturbed_state is None


@pytest.mark.parametrize("angle", [45.0, 30.0])
def test_gd_and_ss_reduce_the_cost_relative_to_rs(policy: MixturePolicy, angle: float) -> None:
    sketch = sketch_at(angle)  # between two modes: unsteered samples are mostly far from it
    rs, gd, ss = (run(name, policy, sketch, seed=3) for name in ("RS", "GD", "SS"))
    assert gd.costs.mean() < rs.costs.mean() - 0.1
    assert ss.costs.mean() < 0.7 * rs.costs.mean()
    assert ss.costs.min() <= rs.costs.min() + 0.05  # SS finds the closest mode PR could pick, or better
    assert gd.chosen == int(np.argmin(gd.costs)) and ss.chosen == int(np.argmin(ss.costs))


def test_ss_stays_on_the_data_manifold_where_gd_leaves_it(policy: MixturePolicy) -> None:
    """Thesis Fig. 2.3: GD samples a *sum* of policy and objective (off-distribution), SS their product."""
    sketch = sketch_at(30.0)
    gd, ss = run("GD", policy, sketch, seed=2), run("SS", policy, sketch, seed=2)
    gd_off, ss_off = policy.off_manifold(gd.plans, OBS).mean(), policy.off_manifold(ss.plans, OBS).mean()
    assert ss_off < 0.15 < gd_off
    assert ss.costs.mean() < gd.costs.mean()


def counted_samplers() -> dict[str, Any]:
    """The samplers whose network evaluations the count tests check (GD, SS with 4 and 2 MCMC steps, BI)."""
    return {
        "GD": GuidedDiffusion(),
        "SS": StochasticSampling(),
        "SS2": StochasticSampling(mcmc_steps=2),
        "BI": BiasedInitialization(),
    }


def network_evals(policy: Any, samplers: dict[str, Any]) -> dict[str, int]:
    """Each sampler's network evaluations (``policy.calls``) in one call for 4 plans toward ``sketch_at(45)``.

    Checks that the sampler's own count (``timings["network_evals"]``) agrees and that it timed the call.
    """
    counts = {}
    for name, sampler in samplers.items():
        before = policy.calls
        result = sampler(policy, OBS, sketch_at(45.0), 4, generator=np.random.default_rng(0))
        counts[name] = policy.calls - before
        assert result.timings["network_evals"] == counts[name] and result.timings["total_ms"] > 0
    return counts


def test_ss_costs_m_times_the_network_evaluations_of_gd(policy: MixturePolicy) -> None:
    assert network_evals(policy, counted_samplers()) == {"GD": 10, "SS": 40, "SS2": 20, "BI": 6}


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_gd_without_guidance_is_the_policys_own_sampler_and_ss_with_m1_is_gd(
    policy: MixturePolicy, dtype: torch.dtype
) -> None:
    policy.dtype = dtype  # float32 policies get float32 noise draws: the same initial noise as their own sampler
    sketch = sketch_at(45.0)
    unguided = run("GD", policy, sketch, seed=4, n=8, guide_ratio=0.0)
    own = policy.sample(OBS, 8, generator=np.random.default_rng(4))
    np.testing.assert_allclose(unguided.plans, own, atol=1e-9 if dtype == torch.float64 else 1e-5)
    gd = run("GD", policy, sketch, seed=4, n=8, guide_ratio=60.0)
    ss1 = run("SS", policy, sketch, seed=4, n=8, guide_ratio=60.0, mcmc_steps=1)
    np.testing.assert_allclose(ss1.plans, gd.plans, atol=1e-12)


def test_bi_starts_from_the_sketch_at_t50_and_stays_near_it(policy: MixturePolicy) -> None:
    sketch = sketch_at(45.0)
    result = run("BI", policy, sketch, seed=0, init_std=0.0)
    x_first, t_first = policy.first_inputs[-1]
    assert t_first == 50
    goal = policy.normalize(sketch.resample(policy.horizon).points)
    np.testing.assert_allclose(x_first.numpy(), np.broadcast_to(goal, x_first.shape), atol=1e-12)
    policy.calls = 0
    noisy = run("BI", policy, sketch, seed=0)
    x_noisy, _ = policy.first_inputs[-1]
    residual = (x_noisy.numpy() - goal).reshape(-1)
    assert abs(residual.std() - 0.5) < 0.05 and abs(residual.mean()) < 0.05  # sketch + 0.5 N(0, I)
    rs = run("RS", policy, sketch, seed=0)
    assert noisy.costs.mean() < 0.7 * rs.costs.mean() and result.costs.mean() < 0.7 * rs.costs.mean()


def test_op_moves_the_agent_onto_the_sketch_and_samples_from_there(policy: MixturePolicy) -> None:
    sketch = Sketch(np.stack([np.linspace(0, 3, 30), np.linspace(0, 1.5, 30)], axis=1))
    result = run("OP", policy, sketch, seed=1)
    np.testing.assert_allclose(result.perturbed_state, sketch.points[20])
    np.testing.assert_allclose(policy.seen_obs[-1], sketch.points[20])
    modes = policy.modes(sketch.points[20])
    assert policy.off_manifold(result.plans, sketch.points[20]).max() < 0.2
    assert np.linalg.norm(modes[:, 0] - result.plans[:, 0][:, None], axis=-1).min(axis=1).max() < 0.3
    assert result.chosen == int(np.argmin(result.costs))

    wall = OutputPerturbation(collides=lambda p: p[:, 0] > 1.0)  # "walls" beyond x = 1
    moved = wall(policy, OBS, sketch, 4, generator=np.random.default_rng(0))
    first = int(np.argmax(sketch.points[:, 0] > 1.0))
    np.testing.assert_allclose(moved.perturbed_state, sketch.points[first - 1])


def test_output_perturbation_point_rules() -> None:
    pts = np.stack([np.arange(30.0), np.zeros(30)], axis=1)
    sketch = Sketch(pts)
    np.testing.assert_array_equal(output_perturbation_point(sketch), pts[20])
    np.testing.assert_array_equal(output_perturbation_point(Sketch(pts[:10])), pts[9])  # clamped to the sketch
    np.testing.assert_array_equal(output_perturbation_point(sketch, 20, lambda p: p[:, 0] >= 7), pts[6])
    np.testing.assert_array_equal(output_perturbation_point(sketch, 20, lambda p: p[:, 0] >= 25), pts[20])
    np.testing.assert_array_equal(output_perturbation_point(sketch, 20, lambda p: p[:, 0] < 1), pts[20])  # start
    with pytest.raises(ValueError, match="one flag per sketch point"):
        output_perturbation_point(sketch, 20, lambda p: np.zeros(3, dtype=bool))
    with pytest.raises(ValueError, match="index"):
        output_perturbation_point(sketch, 0)
    with pytest.raises(TypeError, match="Sketch"):
        output_perturbation_point(Point([0.0, 0.0]))  # type: ignore[arg-type]


def test_op_with_a_nudge_executes_it_and_place_observation_keeps_the_history_shape(policy: MixturePolicy) -> None:
    nudge = Nudge([[0.5, 0.0], [1.0, 0.5]])
    result = OutputPerturbation()(policy, OBS, nudge, 6, generator=np.random.default_rng(0))
    np.testing.assert_allclose(result.perturbed_state, [1.0, 0.5])
    assert np.all(result.costs == np.inf)  # fresh plans do not start with the nudge; the pick is random
    history = np.array([[0.0, 0.0, 1.0, 1.0], [0.1, 0.0, 1.0, 1.0]], dtype=np.float32)
    placed = place_observation(history, [2.0, 3.0])
    np.testing.assert_array_equal(placed, [[2, 3, 0, 0], [2, 3, 0, 0]])
    assert placed.dtype == np.float32 and history[0, 0] == 0.0
    with pytest.raises(ValueError, match="at least 2 entries"):
        place_observation(np.zeros(1), [1.0, 2.0])


@pytest.mark.parametrize("name", sorted(SAMPLERS))
def test_every_sampler_is_deterministic_given_a_seeded_generator(policy: MixturePolicy, name: str) -> None:
    sketch = sketch_at(60.0, points=25)
    a, b, c = (run(name, policy, sketch, seed=s, n=6) for s in (7, 7, 8))
    np.testing.assert_array_equal(a.plans, b.plans)
    assert a.chosen == b.chosen
    assert not np.array_equal(a.plans, c.plans)
    assert a.plans.shape == (6, policy.horizon, 2) and a.costs.shape == (6,) and a.sampler == name


def test_point_interactions_steer_too(policy: MixturePolicy) -> None:
    target = Point([2.0, 2.0])
    rs, ss, bi = (run(name, policy, target, seed=0) for name in ("RS", "SS", "BI"))
    assert ss.costs.mean() < rs.costs.mean() and bi.costs.mean() < rs.costs.mean()


def test_diffusion_samplers_reject_other_policies_and_interactions_are_checked(policy: MixturePolicy) -> None:
    sketch = sketch_at(45.0)
    for cls in (BiasedInitialization, GuidedDiffusion, StochasticSampling):
        with pytest.raises(TypeError, match="DiffusionPolicyLike"):
            cls()(RandomLines(), OBS, sketch, 4)
    for cls in (RandomSampling, PostHocRanking, OutputPerturbation):
        assert cls()(RandomLines(), OBS, sketch, 4, generator=np.random.default_rng(0)).plans.shape == (4, 8, 2)
    with pytest.raises(TypeError, match="TrajectoryPolicy"):
        RandomSampling()(object(), OBS, sketch, 4)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="Sketch, Nudge"):
        OutputPerturbation()(policy, OBS, Point([1.0, 1.0]), 4)
    with pytest.raises(TypeError, match="Point, Sketch"):
        PostHocRanking()(policy, OBS, Nudge([[0.0, 0.0]]), 4)
    with pytest.raises(TypeError, match="Point, Sketch"):
        GuidedDiffusion()(policy, OBS, None, 4)
    with pytest.raises(ValueError, match="dimension 2"):
        PostHocRanking()(policy, OBS, Sketch(np.zeros((3, 3))), 4)
    unsteered = RandomSampling()(policy, OBS, None, 3, generator=np.random.default_rng(0))
    assert np.all(np.isnan(unsteered.costs)) and 0 <= unsteered.chosen < 3
    with pytest.raises(ValueError, match="`n`"):
        RandomSampling()(policy, OBS, sketch, 0)
    with pytest.raises(TypeError, match="generator"):
        RandomSampling()(policy, OBS, sketch, 2, generator=np.random.RandomState(0))  # type: ignore[arg-type]


def test_constructor_and_scheduler_validation(policy: MixturePolicy) -> None:
    with pytest.raises(ValueError, match="guide_ratio"):
        GuidedDiffusion(guide_ratio=-1.0)
    with pytest.raises(ValueError, match="mcmc_steps"):
        StochasticSampling(mcmc_steps=0)
    with pytest.raises(ValueError, match="start_t"):
        BiasedInitialization(start_t=-1)
    with pytest.raises(ValueError, match="index"):
        OutputPerturbation(index=0)
    with pytest.raises(ValueError, match="one of"):
        make_sampler("XX")
    assert isinstance(make_sampler("ss"), StochasticSampling) and "guide_ratio=60.0" in repr(make_sampler("SS"))
    policy.scheduler = diffusers.EulerDiscreteScheduler(num_train_timesteps=100)
    with pytest.raises(ValueError, match=r"GuidedDiffusion: policy.scheduler \(EulerDiscreteScheduler\)"):
        GuidedDiffusion()(policy, OBS, sketch_at(0.0), 2)


def test_policies_that_diffuse_a_longer_tensor_than_they_execute(policy: MixturePolicy) -> None:
    class Longer(MixturePolicy):
        """Diffuses 16 states, returns the last 15 as the plan."""

        def __init__(self) -> None:
            super().__init__(horizon=16)
            self.diffusion_horizon = 16
            self.horizon = 15

        def extract_plan(self, traj: np.ndarray) -> np.ndarray:
            return traj[:, 1:]

    long = Longer()
    result = run("SS", long, sketch_at(45.0), n=4)
    assert result.plans.shape == (4, 15, 2)
    assert long.first_inputs[-1][0].shape == (4, 16, 2)  # the denoised tensor has the diffusion horizon
    long.extract_plan = lambda traj: traj  # type: ignore[method-assign]
    with pytest.raises(ValueError, match=r"plans of shape \(4, 15, 2\)"):
        run("SS", long, sketch_at(45.0), n=4, seed=1)


def test_benchmark_latency_times_every_sampler(policy: MixturePolicy) -> None:
    samplers = {"GD": GuidedDiffusion(), "SS": StochasticSampling()}
    policy.calls = 0
    ms = benchmark_latency(policy, samplers, OBS, sketch_at(45.0), batch=4, repeats=2, warmup=1)
    assert set(ms) == {"GD", "SS"} and all(v > 0 for v in ms.values())
    assert policy.calls == 3 * (10 + 40)  # (warmup + repeats) rounds of both samplers
    with pytest.raises(ValueError, match="non-empty"):
        benchmark_latency(policy, {}, OBS, sketch_at(0.0))
    with pytest.raises(TypeError, match="Sampler"):
        benchmark_latency(policy, {"x": object()}, OBS, sketch_at(0.0))  # type: ignore[dict-item]
    with pytest.raises(ValueError, match="repeats"):
        benchmark_latency(policy, samplers, OBS, sketch_at(0.0), repeats=0)


class LinePolicy3(RandomLines):
    """Straight lines in xy plus a third entry (a gripper-like command) the user does not draw."""

    action_dim = 3
    interaction_dims = (0, 1)

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        xy = super().sample(obs, n, generator=generator)
        return np.concatenate([xy, np.full((*xy.shape[:2], 1), 50.0)], axis=2)


def test_interaction_dims_rank_plans_on_the_drawn_entries_only() -> None:
    policy = LinePolicy3()
    sketch = sketch_at(45.0, length=2.4, points=8)
    result = PostHocRanking()(policy, OBS, sketch, 16, generator=np.random.default_rng(0))
    assert np.allclose(result.costs, alignment_cost_np(result.plans[..., :2], sketch))
    assert result.chosen == int(np.argmin(result.costs)) and result.costs.max() < 10  # the 50s are not compared


def test_interaction_dims_steer_the_drawn_entries_of_a_diffusion_policy(policy: MixturePolicy) -> None:
    full = run("GD", policy, sketch_at(90.0))
    policy.interaction_dims = (0, 1)  # all entries: the same call
    assert np.array_equal(run("GD", policy, sketch_at(90.0)).plans, full.plans)
    policy.interaction_dims = (1,)  # steer y only: a 1-D sketch going up
    up = Sketch(np.linspace(0.0, 3.0, 16)[:, None])
    steered, free = run("GD", policy, up, guide_ratio=20.0), run("RS", policy, up)
    assert steered.costs.mean() < free.costs.mean()
    assert np.allclose(steered.costs, alignment_cost_np(steered.plans[..., 1:], up))
    assert run("BI", policy, up).plans.shape == (32, 16, 2)


@pytest.mark.parametrize(
    ("dims", "error", "match"),
    [((2,), ValueError, "interaction_dims"), ((1, 0), ValueError, "increasing"), ("01", TypeError, "interaction_dims")],
)
def test_bad_interaction_dims_are_refused(policy: MixturePolicy, dims: Any, error: type, match: str) -> None:
    policy.interaction_dims = dims
    with pytest.raises(error, match=match):
        run("PR", policy, sketch_at(0.0))


def test_a_sketch_of_the_wrong_size_for_the_interaction_dims_is_refused(policy: MixturePolicy) -> None:
    policy.interaction_dims = (0,)
    with pytest.raises(ValueError, match="dimension"):
        run("GD", policy, sketch_at(0.0))


@pytest.mark.parametrize("interaction", [Point([1.0, -2.0]), Sketch(np.linspace((0.0, 0.0), (3.0, 4.0), 7))])
def test_the_guidance_gradient_is_autograds(interaction: Any) -> None:
    """The closed-form grad of xi (mean per-step L2) equals autograd's, for a policy's full and partial dims."""
    from steer_envs.steering.diffusion import NormalizedObjective

    policy = MixturePolicy()
    objective = NormalizedObjective(policy, interaction, torch.float64)
    x = torch.randn(5, policy.horizon, 2, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    x[0, 3] = objective.as_trajectory(policy.horizon)[3]  # a step on its goal: gradient 0, not NaN
    xg = x.clone().requires_grad_(True)
    (expected,) = torch.autograd.grad(objective.cost(xg).sum(), xg)
    got = objective.grad(x)
    torch.testing.assert_close(got, expected, rtol=1e-12, atol=1e-12)
    assert torch.all(got[0, 3] == 0)
    objective.dims = (1,)  # an interaction on some of the action's dimensions: the others get no gradient
    objective.target = objective.target[..., 1:]
    objective._goals.clear()
    xg = x.clone().requires_grad_(True)
    (expected,) = torch.autograd.grad(objective.cost(xg).sum(), xg)
    torch.testing.assert_close(objective.grad(x), expected, rtol=1e-12, atol=1e-12)
    assert torch.all(objective.grad(x)[..., 0] == 0)


def test_clipped_model_output_keeps_strong_guidance_from_drifting_to_the_clip_bounds(policy: MixturePolicy) -> None:
    """diffusers' DDIM reuses eps_hat after clipping x0: a strong push then moves x_t along the cost gradient."""
    sketch = sketch_at(45.0)
    rs = run("RS", policy, sketch, seed=3, n=16)
    for beta in (20.0, 100.0):
        default = run("GD", policy, sketch, seed=3, n=16, guide_ratio=beta)
        clipped = run("GD", policy, sketch, seed=3, n=16, guide_ratio=beta, use_clipped_model_output=True)
        assert clipped.costs.mean() < default.costs.mean() - 0.3
        assert clipped.costs.mean() < rs.costs.mean()
    default = run("GD", policy, sketch, seed=3, n=16, guide_ratio=400.0)
    clipped = run("GD", policy, sketch, seed=3, n=16, guide_ratio=400.0, use_clipped_model_output=True)
    assert np.abs(policy.normalize(default.plans)).max() > 0.99  # carried to the clip bounds
    assert np.abs(policy.normalize(clipped.plans)).max() < 0.9
    assert default.costs.mean() > 2 * rs.costs.mean()
    ss = run("SS", policy, sketch, seed=3, n=16, use_clipped_model_output=True)
    assert ss.costs.mean() < rs.costs.mean()


def test_clipped_model_output_is_checked(policy: MixturePolicy) -> None:
    with pytest.raises(TypeError, match="use_clipped_model_output"):
        GuidedDiffusion(use_clipped_model_output="yes")  # type: ignore[arg-type]
    assert "use_clipped_model_output=True" in repr(make_sampler("SS", use_clipped_model_output=True))
    policy.scheduler = diffusers.DDPMScheduler(num_train_timesteps=100, clip_sample=True)
    assert GuidedDiffusion()(policy, OBS, sketch_at(0.0), 2).plans.shape == (2, policy.horizon, 2)
    with pytest.raises(ValueError, match="use_clipped_model_output"):
        GuidedDiffusion(use_clipped_model_output=True)(policy, OBS, sketch_at(0.0), 2)
