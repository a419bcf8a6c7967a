"""The flow-matching policy: protocol, exact velocity, Euler sampling, training, checkpoints, the training CLI."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from samples import maze_walk_fixture
from tiny_policies import TINY_UNET as TINY
from tiny_policies import UNET_ARCH as ARCH
from tiny_policies import same_stats, tiny_policy

from steer_envs.baselines.diffusion import DiffusionConfig
from steer_envs.baselines.factory import get_preset, load_policy, make_policy
from steer_envs.baselines.flow import FlowConfig, FlowPolicy
from steer_envs.baselines.training import train_policy
from steer_envs.core import DiffusionPolicyLike, TrajectoryPolicy
from steer_envs.core.policy import FlowPolicyLike

STATS = same_stats({"min": (0.0, 0.0), "max": (8.0, 11.0)})

walk = maze_walk_fixture(seed=3)


def _tiny(seed: int = 0, **changes) -> FlowPolicy:
    return tiny_policy(FlowPolicy, FlowConfig, TINY, STATS, seed, **changes)


def test_protocols_and_matched_size() -> None:
    policy = _tiny()
    assert isinstance(policy, FlowPolicyLike) and isinstance(policy, TrajectoryPolicy)
    assert not isinstance(policy, DiffusionPolicyLike)  # no scheduler: the samplers take the flow's own form
    features = {"obs_dim": 2, "action_dim": 2, "action_obs_indices": (0, 1)}
    dp = get_preset("dp", "cpu").model.replace(**features)
    flow = get_preset("flow", "cpu").model.replace(**features)
    assert flow.parameter_count() == dp.parameter_count()
    assert get_preset("flow", "cpu").train == get_preset("dp", "cpu").train
    assert {k: v for k, v in dp.to_dict().items() if k in FlowConfig.field_names()} == flow.to_dict()
    assert set(DiffusionConfig.field_names()) - set(FlowConfig.field_names()) == {
        "beta_schedule",
        "clip_sample_range",
        "prediction",
    }


@pytest.mark.parametrize("relative", [False, True])
def test_an_exact_network_flows_noise_to_the_plan(relative: bool) -> None:
    """A network that outputs the exact (relative) velocity of one plan carries any noise onto that plan."""
    policy = _tiny(relative=relative)
    obs = np.array([[2.0, 3.0], [2.5, 3.5]])
    cond = policy.encode_obs(obs)
    plan = torch.linspace(-0.5, 0.5, 16)[None, :, None].repeat(1, 1, 2)
    anchor = cond[:, None, -2:] if relative else torch.zeros(1, 1, 2)

    def exact(x: torch.Tensor, timestep: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        tau = (timestep / policy.config.num_train_timesteps).reshape(-1, 1, 1)
        x_abs = x + tau * anchor  # the network sees the plan relative to the agent
        noise = (x_abs - tau * plan) / (1 - tau)
        return plan - noise - anchor

    policy.model.forward = exact  # type: ignore[method-assign]
    policy.num_inference_steps = 4
    out = policy.integrate(torch.randn(3, 16, 2, generator=torch.Generator().manual_seed(0)), cond)
    torch.testing.assert_close(out, plan.expand(3, -1, -1), atol=1e-5, rtol=1e-5)
    # the loss of the exact network is zero
    x1 = policy.unnormalize(plan.expand(2, -1, -1))
    policy.model.forward = lambda x, timestep, c: torch.zeros_like(x)  # type: ignore[method-assign]
    assert policy.loss(torch.from_numpy(np.repeat(obs[None], 2, 0)).float(), x1.float()) > 0


def test_sampling_is_reproducible_and_draws_dps_noise() -> None:
    policy = _tiny(seed=1)
    a = policy.sample([1.0, 2.0], 4, generator=np.random.default_rng(3))
    b = policy.sample([1.0, 2.0], 4, generator=np.random.default_rng(3))
    assert a.shape == (4, 16, 2) and np.array_equal(a, b)
    assert not np.array_equal(a, policy.sample([1.0, 2.0], 4, generator=np.random.default_rng(4)))


def test_predict_velocity_is_differentiable_and_checks_its_input() -> None:
    policy = _tiny()
    cond = policy.encode_obs([1.0, 2.0])
    x = torch.zeros(2, 16, 2, requires_grad=True)
    policy.predict_velocity(x, 0.3, cond).sum().backward()
    assert x.grad is not None and torch.isfinite(x.grad).all()
    with pytest.raises(ValueError, match="tau must be one value or 2 values in"):
        policy.predict_velocity(x, 1.5, cond)
    with pytest.raises(ValueError, match="cond must be a"):
        policy.predict_velocity(x, 0.3, torch.zeros(1, 3))
    with pytest.raises(TypeError, match=r"x must be a floating-point torch\.Tensor"):
        policy.predict_velocity(np.zeros((2, 16, 2)), 0.3, cond)  # type: ignore[arg-type]


def test_tiny_training_reduces_loss_and_round_trips(walk, tmp_path: Path) -> None:
    settings = get_preset("flow", "cpu").train.replace(steps=80, batch_size=32, warmup_steps=10, log_every=20, seed=5)
    config = get_preset("flow", "cpu").model.replace(**ARCH)
    policy = make_policy(config, dataset=walk, seed=5)
    record = train_policy(policy, walk, settings, progress=False)
    losses = [loss for _, loss in record["losses"]]
    assert losses[-1] < 0.85 * losses[0]
    path = policy.save(tmp_path / "flow.safetensors")
    loaded = load_policy(path)
    assert isinstance(loaded, FlowPolicy) and loaded.config == policy.config
    obs = np.array([2.0, 2.0])
    np.testing.assert_array_equal(
        loaded.sample(obs, 2, generator=np.random.default_rng(0)),
        policy.sample(obs, 2, generator=np.random.default_rng(0)),
    )


def test_the_training_entry_point_trains_and_checks_a_flow(walk, tmp_path: Path) -> None:
    from steer_envs.data.trajectories import save_trajectories

    data = save_trajectories(walk, tmp_path / "walk.npz")
    out = tmp_path / "flow.safetensors"
    base = [sys.executable, "-m", "steer_envs.baselines.training", "--dataset", str(data), "--no-progress"]
    tiny = ["--model", "down_dims=[8,16]", "--model", "horizon=16", "--model", "obs_embed_dim=16"]
    train = [*base, "--policy", "flow", *tiny, "--steps", "20", "--train", "log_every=5", "--out", str(out)]
    done = subprocess.run(train, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert isinstance(load_policy(out), FlowPolicy)
    check = subprocess.run([*base, "--check", str(out.with_suffix(".json")), "--check-steps", "10"],
                           capture_output=True, text=True, timeout=600)  # fmt: skip
    assert check.returncode == 0, check.stdout[-2000:] + check.stderr[-2000:]


@pytest.mark.parametrize("mode", ["trace", "onnx"])
def test_accelerated_velocities_and_plans_match_eager(mode: str) -> None:
    """A flow runs its network as DP does: eager's velocities within float32 rounding, gradients left eager."""
    if mode == "onnx":
        pytest.importorskip("onnxruntime")
    eager, fast = _tiny(), _tiny().accelerate(mode)
    assert fast.acceleration == mode and eager.acceleration == "none"
    x, cond = torch.randn(5, eager.horizon, 2, generator=torch.Generator().manual_seed(0)), eager.encode_obs([2.0, 3.0])
    with torch.no_grad():
        for tau in (0.0, 0.4, 0.95):
            want, got = eager.predict_velocity(x, tau, cond), fast.predict_velocity(x, tau, cond)
            assert (got - want).abs().max() <= 1e-4 * want.abs().max(), (tau, (got - want).abs().max())
    plans = [p.sample([2.0, 3.0], 4, generator=np.random.default_rng(1)) for p in (eager, fast)]
    np.testing.assert_allclose(plans[1], plans[0], atol=1e-4)
    x.requires_grad_(True)
    fast.predict_velocity(x, 0.5, cond).square().sum().backward()
    assert x.grad is not None and x.grad.abs().sum() > 0
    fewer = fast.with_steps(3)
    assert fewer.acceleration == mode and fewer.num_inference_steps == 3 and fast.num_inference_steps != 3
    with pytest.raises(ValueError, match="mode"):
        _tiny().accelerate("cuda")
