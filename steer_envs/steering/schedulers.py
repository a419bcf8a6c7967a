"""The scheduler arithmetic the guided samplers need, for any DDPM/DDIM-style (variance-preserving) scheduler.

BI, GD and SS (:mod:`~steer_envs.steering.diffusion`) add guidance to the
*noise* estimate ``eps`` and re-noise clean-plan estimates, so they need
``x_t = sqrt(abar_t) x_0 + sqrt(1 - abar_t) eps``, i.e. a scheduler with
``alphas_cumprod`` (diffusers' ``DDPMScheduler``, ``DDIMScheduler``, or
anything alike). Whatever the network predicts is converted to ``eps`` for
guidance and back to the scheduler's own ``prediction_type`` for its
``step``:

=================  =======================================================
prediction_type    network output ``o`` -> ``eps``
=================  =======================================================
``epsilon``        ``eps = o``
``sample``         ``eps = (x_t - sqrt(abar) o) / sqrt(1 - abar)`` (x0-prediction)
``v_prediction``   ``eps = sqrt(abar) o + sqrt(1 - abar) x_t``
=================  =======================================================

A stochastic ``step`` (DDPM's posterior noise) draws from a
``torch.Generator`` that :func:`step_generator` seeds from the sampler's numpy
generator, so steering stays reproducible without touching torch's global
generator (and without changing the numpy stream the initial noise comes from).

:func:`check_scheduler` refuses, naming the scheduler, what these formulas are
not correct for: no ``alphas_cumprod`` (flow-matching schedulers), an
``init_noise_sigma`` other than 1 (sigma-space schedulers such as Euler), or
multistep solvers that keep past model outputs (DPM-Solver, UniPC), which SS's
re-noising to the same level would corrupt.

>>> import torch
>>> from diffusers import DDIMScheduler
>>> s = DDIMScheduler(num_train_timesteps=100, prediction_type="sample")
>>> check_scheduler(s, "GD")
'sample'
>>> x, x0 = torch.ones(1, 4, 2), torch.zeros(1, 4, 2)
>>> eps = to_epsilon(x0, x, 50, s)
>>> torch.allclose(from_epsilon(eps, x, 50, s), x0, atol=1e-5)
True
"""

from __future__ import annotations

import inspect
from typing import Any

import numpy as np
import torch

__all__ = ["PREDICTION_TYPES", "check_scheduler", "from_epsilon", "prediction_type", "step_generator", "to_epsilon"]

#: the network parameterisations the samplers convert (diffusers' ``prediction_type`` names)
PREDICTION_TYPES = ("epsilon", "sample", "v_prediction")


def prediction_type(scheduler: Any) -> str:
    """``scheduler.config.prediction_type`` (``"epsilon"`` when the scheduler has no config)."""
    config = getattr(scheduler, "config", None)
    value = getattr(config, "prediction_type", "epsilon") if config is not None else "epsilon"
    return "epsilon" if value is None else str(value)


def check_scheduler(scheduler: Any, who: str) -> str:
    """The scheduler's prediction type, or ``ValueError`` naming ``who`` when the samplers cannot be correct for it."""
    name = type(scheduler).__name__
    kind = prediction_type(scheduler)
    if kind not in PREDICTION_TYPES:
        raise ValueError(
            f"{who}: policy.scheduler ({name}) has prediction_type={kind!r}; the guided samplers convert "
            f"{', '.join(PREDICTION_TYPES)} only"
        )
    if getattr(scheduler, "alphas_cumprod", None) is None:
        raise ValueError(
            f"{who}: policy.scheduler ({name}) has no alphas_cumprod; BI, GD and SS need a DDPM/DDIM-style "
            "(variance-preserving) scheduler, not a flow-matching or sigma-space one"
        )
    sigma = float(torch.as_tensor(getattr(scheduler, "init_noise_sigma", 1.0)).reshape(-1)[0])
    if abs(sigma - 1.0) > 1e-6:
        raise ValueError(
            f"{who}: policy.scheduler ({name}) starts from noise of scale {sigma:.3g} (a sigma-space scheduler); "
            "BI, GD and SS need a DDPM/DDIM-style scheduler (init_noise_sigma == 1)"
        )
    if hasattr(scheduler, "model_outputs") or hasattr(scheduler, "solver_order"):
        raise ValueError(
            f"{who}: policy.scheduler ({name}) is a multistep solver that keeps past model outputs; SS's "
            "re-noising and guidance would corrupt its history: use a DDIMScheduler or DDPMScheduler"
        )
    return kind


def _abar(scheduler: Any, t: Any, like: torch.Tensor) -> torch.Tensor:
    value = torch.as_tensor(scheduler.alphas_cumprod)[int(t)]
    return value.to(device=like.device, dtype=like.dtype)


def to_epsilon(output: torch.Tensor, x: torch.Tensor, t: Any, scheduler: Any) -> torch.Tensor:
    """The noise estimate implied by the network's ``output`` at ``(x, t)`` (``output`` itself for epsilon)."""
    kind = prediction_type(scheduler)
    if kind == "epsilon":
        return output
    abar = _abar(scheduler, t, x)
    if kind == "sample":
        return (x - abar.sqrt() * output) / (1 - abar).sqrt()
    return abar.sqrt() * output + (1 - abar).sqrt() * x


def from_epsilon(eps: torch.Tensor, x: torch.Tensor, t: Any, scheduler: Any) -> torch.Tensor:
    """Inverse of :func:`to_epsilon`: ``eps`` in the scheduler's own ``prediction_type``, for its ``step``."""
    kind = prediction_type(scheduler)
    if kind == "epsilon":
        return eps
    abar = _abar(scheduler, t, x)
    x0 = (x - (1 - abar).sqrt() * eps) / abar.sqrt()
    if kind == "sample":
        return x0
    return abar.sqrt() * eps - (1 - abar).sqrt() * x0


def step_generator(scheduler: Any, rng: np.random.Generator, device: Any) -> dict[str, Any]:
    """``{"generator": torch.Generator}`` for a ``step`` that takes one, seeded from ``rng``; ``{}`` otherwise.

    The seed comes from a child of ``rng``'s seed sequence (``rng.spawn``), so the
    numpy stream the samplers draw their noise from is unchanged; a generator
    without a seed sequence gives one draw of its own stream instead.
    """
    try:
        accepted = "generator" in inspect.signature(scheduler.step).parameters
    except (TypeError, ValueError):
        accepted = False
    if not accepted:
        return {}
    try:
        child = rng.spawn(1)[0]
    except (TypeError, ValueError):
        child = rng
    seed = int(child.integers(0, 2**63 - 1))
    return {"generator": torch.Generator(device=torch.device(device)).manual_seed(seed)}
