"""A flow-matching policy: Diffusion Policy's U-Net trained on a velocity field, sampled by a few Euler steps.

Rectified flow (Liu et al. 2023; the form of pi0 / SmolVLA's action experts):
noise ``x_0 ~ N(0, I)`` at time ``tau = 0`` flows to a normalized plan ``x_1``
at ``tau = 1`` along ``x_tau = tau * x_1 + (1 - tau) * x_0``, whose velocity is
``x_1 - x_0``; the network learns it by regression at ``tau ~ U(0, 1)`` and
sampling integrates ``dx/dtau = v(x, tau | obs)`` with
``num_inference_steps`` Euler steps. The network, its conditioning, the plan
layout, normalization and plans relative to the agent are Diffusion
Policy's (:class:`~steer_envs.baselines.diffusion.network.DiffusionNet`), so
a flow and a DP of one preset match in parameters and training samples.

It is a :class:`~steer_envs.core.policy.FlowPolicyLike`: the six ITPS
samplers steer it (BI, GD and SS in the flow's own form,
:mod:`steer_envs.steering.flow`). Its no-grad network calls run as fast as
DP's (:meth:`accelerate`: ONNX Runtime, OpenVINO, ...). It trains through
:mod:`steer_envs.baselines.training` (``--policy flow``) with the same
checkpoints, resumable runs and ``--check``.

>>> import numpy as np
>>> policy = FlowPolicy(FlowConfig(obs_dim=2, action_dim=2, horizon=8, down_dims=(8, 16), obs_embed_dim=8))
>>> policy.sample(np.zeros(2), 3, generator=np.random.default_rng(0)).shape
(3, 8, 2)
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import torch
from torch import nn

from steer_envs.baselines.common.torch_policy import TorchPolicy, check_tensor
from steer_envs.baselines.diffusion.acceleration import AcceleratedNetwork
from steer_envs.baselines.diffusion.network import DiffusionNet
from steer_envs.baselines.flow.configuration import FlowConfig
from steer_envs.core.validation import describe, integer

__all__ = ["FlowPolicy"]


class FlowPolicy(TorchPolicy, AcceleratedNetwork):
    """A rectified-flow plan policy (see the module docstring); ``name = "flow"`` in the policy factory.

    Args:
        config: a :class:`FlowConfig` with its feature fields set.
        stats, seed, device: as :class:`~steer_envs.baselines.common.torch_policy.TorchPolicy`.
    """

    name = "flow"
    config_class = FlowConfig
    config: FlowConfig

    def __init__(
        self,
        config: FlowConfig,
        stats: Any = None,
        *,
        seed: int = 0,
        device: str | torch.device = "cpu",
    ) -> None:
        super().__init__(config, stats, seed=seed, device=device)
        #: Euler steps per plan (the samplers read it; change it to trade speed for accuracy)
        self.num_inference_steps = self.config.num_inference_steps

    def _build_model(self) -> nn.Module:
        return DiffusionNet(self.config)

    def with_steps(self, steps: int) -> FlowPolicy:
        """This policy sampled with ``steps`` Euler steps: a copy sharing the network (this one is unchanged).

        Fewer steps call the network fewer times per plan; a shared policy (one
        per process) keeps its own steps for every other caller.

        >>> policy = FlowPolicy(FlowConfig(obs_dim=2, action_dim=2, horizon=8, down_dims=(8, 16)))
        >>> policy.with_steps(4).num_inference_steps, policy.num_inference_steps
        (4, 10)
        """
        fewer = copy.copy(self)
        fewer.num_inference_steps = integer(steps, "steps", low=1, high=1000, owner="FlowPolicy.with_steps")
        return fewer

    # ------------------------------------------------------------ FlowPolicyLike
    def predict_velocity(self, x: torch.Tensor, tau: Any, cond: torch.Tensor) -> torch.Tensor:
        """``v(x, tau | cond)`` for normalized plans ``x (n, H, d)``; differentiable in ``x``.

        ``tau`` is a real in ``[0, 1]`` or ``(n,)`` of them; ``cond`` a ``(1 or n, n_obs_steps * obs_dim)``
        tensor from :meth:`encode_obs`. ``TypeError`` / ``ValueError`` naming the argument otherwise.
        """
        owner = "FlowPolicy.predict_velocity"
        if not isinstance(x, torch.Tensor) or not x.is_floating_point():
            raise TypeError(f"{owner}: x must be a floating-point torch.Tensor, got {describe(x)}")
        check_tensor(x, "x", (None, self.horizon, self.action_dim), owner=owner)
        n = x.shape[0]
        taus = torch.as_tensor(tau, dtype=x.dtype, device=x.device).reshape(-1)
        if taus.numel() not in (1, n) or not bool(((taus >= 0) & (taus <= 1)).all()):
            raise ValueError(f"{owner}: tau must be one value or {n} values in [0, 1], got {taus.tolist()[:8]}")
        width = self.n_obs_steps * self.obs_dim
        shape_ok = isinstance(cond, torch.Tensor) and cond.ndim == 2 and cond.shape[1] == width
        if not shape_ok or cond.shape[0] not in (1, n):
            what = tuple(cond.shape) if isinstance(cond, torch.Tensor) else describe(cond)
            raise ValueError(f"{owner}: cond must be a (1 or {n}, {width}) tensor from encode_obs, got {what}")
        rows = cond.to(device=x.device, dtype=x.dtype)
        level = taus.reshape(-1, 1, 1)
        anchor = self._anchor(rows)  # the current position the plan is relative to (0 for absolute plans)
        out = self._network(x - level * anchor, taus * self.config.num_train_timesteps, rows)
        return out + anchor

    def _anchor(self, cond: torch.Tensor) -> torch.Tensor:
        """``(rows, 1, d)``: the current value of ``action_obs_indices`` for relative plans, else 0."""
        if not self.config.relative or self.config.action_obs_indices is None:
            return torch.zeros(1, 1, self.action_dim, dtype=cond.dtype, device=cond.device)
        current = cond.reshape(cond.shape[0], self.n_obs_steps, self.obs_dim)[:, -1]
        return current[:, None, list(self.config.action_obs_indices)]

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        """``n`` plans ``(n, horizon, action_dim)`` in data units by Euler integration from ``generator``'s noise.

        The initial noise is a float32 standard normal draw, as Diffusion
        Policy's, so a flow and a DP see the same noise for the same generator state.
        """
        rng = self._sample_args(n, generator)
        with torch.no_grad():
            cond = self.encode_obs(obs)
            noise = rng.standard_normal((int(n), self.horizon, self.action_dim), dtype=np.float32)
            x = self.integrate(torch.from_numpy(noise).to(self._device), cond)
            return self.unnormalize(x).cpu().numpy().astype(np.float64)

    def integrate(self, x: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """The unguided Euler loop from noise ``x`` (normalized space, ``tau = 0``) to a plan (``tau = 1``)."""
        steps = self.num_inference_steps
        for k in range(steps):
            x = x + self.predict_velocity(x, k / steps, cond) / steps
        return x

    # ------------------------------------------------------------ training
    def loss(self, obs: torch.Tensor, plans: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """Flow-matching MSE: ``obs (B, n_obs_steps, obs_dim)``, ``plans (B, H, action_dim)`` real finite tensors.

        ``tau ~ U(0, 1)``, ``x_tau = tau * x_1 + (1 - tau) * x_0``, target ``x_1 - x_0``
        (relative to the current position for relative plans).
        """
        x1, cond, noise, gen_device = self._noised_batch(obs, plans, generator)
        b = plans.shape[0]
        tau = torch.rand((b,), generator=generator, device=gen_device).to(self._device)
        level = tau.reshape(-1, 1, 1)
        anchor = self._anchor(cond)
        x_tau = level * x1 + (1 - level) * noise
        out = self.model(x_tau - level * anchor, tau * self.config.num_train_timesteps, cond)
        return nn.functional.mse_loss(out, x1 - noise - anchor)
