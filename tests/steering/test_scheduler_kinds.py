"""The guided samplers on any DDPM/DDIM-style scheduler: x0 and v prediction, DDPM's noise, refusals."""

from __future__ import annotations

from typing import Any

import diffusers
import numpy as np
import pytest
import torch

from steer_envs.steering import make_sampler
from steer_envs.steering.diffusion import denoise_plans
from steer_envs.steering.schedulers import check_scheduler, from_epsilon, to_epsilon
from tests.steering.test_samplers import OBS, MixturePolicy, sketch_at

SAMPLERS = ("BI", "GD", "SS")


class ReparameterisedMixture(MixturePolicy):
    """The exact mixture, its network output given as x0 (``sample``) or ``v`` instead of epsilon."""

    def __init__(self, prediction_type: str, scheduler: str = "DDIM") -> None:
        super().__init__()
        kinds = {"DDIM": diffusers.DDIMScheduler, "DDPM": diffusers.DDPMScheduler}
        self.scheduler = kinds[scheduler](
            num_train_timesteps=100,
            beta_schedule="squaredcos_cap_v2",
            clip_sample=True,
            prediction_type=prediction_type,
        )

    def predict_noise(self, x_t: torch.Tensor, t: Any, cond: torch.Tensor) -> torch.Tensor:
        return from_epsilon(super().predict_noise(x_t, t, cond), x_t, t, self.scheduler)

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        return denoise_plans(self, obs, n, generator if generator is not None else np.random.default_rng())


def plans(name: str, policy: Any, seed: int = 0) -> np.ndarray:
    sampler = make_sampler(name)
    return sampler(policy, OBS, sketch_at(30.0), 8, generator=np.random.default_rng(seed)).plans


@pytest.mark.parametrize("kind", ["sample", "v_prediction"])
@pytest.mark.parametrize("name", SAMPLERS)
def test_x0_and_v_prediction_steer_as_epsilon_does(kind: str, name: str) -> None:
    reference = plans(name, MixturePolicy())
    np.testing.assert_allclose(plans(name, ReparameterisedMixture(kind)), reference, atol=1e-4)


@pytest.mark.parametrize("name", ["RS", *SAMPLERS])
def test_ddpm_steering_is_seeded(name: str) -> None:
    policy = ReparameterisedMixture("epsilon", scheduler="DDPM")
    policy.num_inference_steps = 20
    state = torch.random.get_rng_state()
    first, again, other = plans(name, policy, 3), plans(name, policy, 3), plans(name, policy, 4)
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first, other)
    assert torch.equal(torch.random.get_rng_state(), state), "torch's global generator must stay untouched"


def test_unguided_guidance_reproduces_denoise_plans() -> None:
    policy = ReparameterisedMixture("sample", scheduler="DDPM")
    unguided = make_sampler("GD", guide_ratio=0.0)(policy, OBS, sketch_at(0.0), 8, generator=np.random.default_rng(5))
    plain = make_sampler("RS")(policy, OBS, None, 8, generator=np.random.default_rng(5))
    np.testing.assert_allclose(unguided.plans, plain.plans)


def test_conversions_are_inverse() -> None:
    x = torch.randn(3, 4, 2, dtype=torch.float64)
    out = torch.randn(3, 4, 2, dtype=torch.float64)
    for kind in ("epsilon", "sample", "v_prediction"):
        scheduler = diffusers.DDIMScheduler(num_train_timesteps=100, prediction_type=kind)
        np.testing.assert_allclose(from_epsilon(to_epsilon(out, x, 40, scheduler), x, 40, scheduler), out, atol=1e-10)


@pytest.mark.parametrize(
    ("scheduler", "match"),
    [
        (diffusers.EulerDiscreteScheduler(num_train_timesteps=100), "sigma-space"),
        (diffusers.DPMSolverMultistepScheduler(num_train_timesteps=100), "multistep"),
        (diffusers.FlowMatchEulerDiscreteScheduler(num_train_timesteps=100), "no alphas_cumprod"),
    ],
)
def test_schedulers_the_samplers_cannot_be_correct_for_are_refused(scheduler: Any, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        check_scheduler(scheduler, "SS")
    policy = MixturePolicy()
    policy.scheduler = scheduler
    with pytest.raises(ValueError, match=f"StochasticSampling: policy.scheduler .{type(scheduler).__name__}.*{match}"):
        make_sampler("SS")(policy, OBS, sketch_at(0.0), 2)
