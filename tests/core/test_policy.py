"""Policy protocols: structural checks and a minimal diffusion policy run through the contract."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from stub_policies import ExactDiffusion, RandomLines

from steer_envs.core import DiffusionPolicyLike, NoiseSchedulerLike, TrajectoryPolicy, VelocityPolicy


def test_trajectory_policy_protocol() -> None:
    policy = RandomLines(step=0.1)
    assert isinstance(policy, TrajectoryPolicy)
    assert not isinstance(policy, DiffusionPolicyLike)
    plans = policy.sample(np.zeros(2), 5, generator=np.random.default_rng(3))
    assert plans.shape == (5, policy.horizon, policy.action_dim)
    again = policy.sample(np.zeros(2), 5, generator=np.random.default_rng(3))
    np.testing.assert_array_equal(plans, again)

    class NoHorizon:
        action_dim = 2

        def sample(self, obs: Any, n: int, *, generator: Any = None) -> np.ndarray:
            return np.zeros((n, 1, 2))

    assert not isinstance(NoHorizon(), TrajectoryPolicy)


def test_velocity_policy_protocol() -> None:
    def attractor(x: np.ndarray) -> np.ndarray:
        return -x

    assert isinstance(attractor, VelocityPolicy)
    assert not isinstance(np.zeros(2), VelocityPolicy)


torch = pytest.importorskip("torch")
diffusers = pytest.importorskip("diffusers")


class _GaussianDiffusionPolicy(ExactDiffusion):
    """Exact epsilon-predictor for data x0 ~ N(mu, s^2 I): a diffusion policy with a known answer."""

    horizon = 6
    action_dim = 2

    def __init__(self, mu: np.ndarray, std: float = 1e-3) -> None:
        self.mu = torch.as_tensor(mu, dtype=torch.float64)
        self.var = std**2
        self.low, self.high = -5.0, 5.0
        self.scheduler = diffusers.DDIMScheduler(
            num_train_timesteps=100, beta_schedule="squaredcos_cap_v2", clip_sample=False
        )

    def encode_obs(self, obs: Any) -> torch.Tensor:
        return torch.as_tensor(obs, dtype=torch.float64)

    def predict_noise(self, x_t: torch.Tensor, t: Any, cond: torch.Tensor) -> torch.Tensor:
        abar = self.scheduler.alphas_cumprod[int(t)].to(torch.float64)
        mean = self.normalize(self.mu + cond)
        return (1 - abar).sqrt() * (x_t - abar.sqrt() * mean) / (abar * self.var + 1 - abar)

    def normalize(self, traj: Any) -> Any:
        return 2 * (traj - self.low) / (self.high - self.low) - 1

    def unnormalize(self, traj: Any) -> Any:
        return (traj + 1) / 2 * (self.high - self.low) + self.low


def test_diffusers_scheduler_and_diffusion_policy_satisfy_the_contract() -> None:
    mu = np.stack([np.linspace(0, 1, 6), np.linspace(0, -1, 6)], axis=1)
    policy = _GaussianDiffusionPolicy(mu)
    assert isinstance(policy.scheduler, NoiseSchedulerLike)
    assert isinstance(policy, DiffusionPolicyLike) and isinstance(policy, TrajectoryPolicy)
    obs = np.array([0.5, 0.25])
    plans = policy.sample(obs, 4, generator=np.random.default_rng(0))
    assert plans.shape == (4, 6, 2)
    np.testing.assert_allclose(plans, np.broadcast_to(mu + obs, plans.shape), atol=0.05)
    x = policy.normalize(np.array([1.0, -2.0]))
    np.testing.assert_allclose(policy.unnormalize(x), [1.0, -2.0])
    assert list(policy.scheduler.timesteps) == list(range(90, -1, -10))
