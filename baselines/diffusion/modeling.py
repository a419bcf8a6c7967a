"""Diffusion Policy (Chi et al. 2023): a 1D temporal U-Net denoising plans, sampled by DDIM.

The denoiser is Diffusion Policy's conditional U-Net: residual blocks of
``Conv1d -> GroupNorm -> SiLU`` (Chi et al. use Mish, a nearly identical curve
with a much slower CPU kernel) whose features are FiLM-modulated (per-channel
scale and bias) by the diffusion-step embedding concatenated with the global
condition, the normalized observation history (optionally through
:class:`~steer_envs.baselines.diffusion.network.ObsEncoder`). Sampling runs a diffusers ``DDIMScheduler`` with epsilon
parameterization and ``clip_sample``; whatever the network's target
(:attr:`DiffusionConfig.prediction`), samplers see an epsilon predictor,
:meth:`DiffusionPolicy.predict_noise`, so the guided samplers (BI, GD, SS)
can run and steer the denoising loop (:class:`steer_envs.core.DiffusionPolicyLike`).
:meth:`DiffusionPolicy.accelerate` speeds up the denoiser of inference calls
on CPU (a TorchScript trace per input shape, ``torch.compile``, or an ONNX
Runtime session).

The policy is domain-agnostic: observation and action sizes, normalization
and the plan layout come from :class:`DiffusionConfig`, the statistics from
the training data.

>>> import numpy as np
>>> cfg = DiffusionConfig(obs_dim=7, action_dim=4, horizon=8, down_dims=(8, 16), obs_embed_dim=8)
>>> policy = DiffusionPolicy(cfg)
>>> policy.sample(np.zeros(7), 3, generator=np.random.default_rng(0)).shape
(3, 8, 4)
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any, Protocol, cast

import numpy as np
import torch
from diffusers import DDIMScheduler
from torch import nn

from steer_envs.baselines.common.torch_policy import TorchPolicy, check_tensor
from steer_envs.baselines.diffusion.acceleration import ACCELERATIONS, AcceleratedNetwork
from steer_envs.baselines.diffusion.configuration import DiffusionConfig
from steer_envs.baselines.diffusion.network import DiffusionNet
from steer_envs.core.validation import describe, integer, real_array

__all__ = ["ACCELERATIONS", "DiffusionPolicy"]

#: the checkpoint format written before the policy factory (still readable).
LEGACY_FORMAT = "steer_envs.baselines.diffusion/1"


class _Scheduler(Protocol):
    """The members of diffusers' ``DDIMScheduler`` this module uses."""

    alphas_cumprod: torch.Tensor
    timesteps: torch.Tensor
    config: Any

    def set_timesteps(self, num_inference_steps: int) -> None: ...

    def step(self, model_output: torch.Tensor, timestep: Any, sample: torch.Tensor) -> Any: ...

    def add_noise(self, original: torch.Tensor, noise: torch.Tensor, timesteps: torch.Tensor) -> torch.Tensor: ...


# ------------------------------------------------------------------ policy
class DiffusionPolicy(TorchPolicy, AcceleratedNetwork):
    """Observation history -> batch of plans by DDIM (a ``DiffusionPolicyLike``).

    Args:
        config: a :class:`DiffusionConfig` with its features set.
        stats: normalization statistics ``{"observation": ..., "action": ...}``
            (e.g. ``dataset.stats()``); ``None``: data already normalized.
        seed: seed of the initial weights.
        device: torch device of the network.

    >>> import numpy as np
    >>> cfg = DiffusionConfig(obs_dim=2, action_dim=2, horizon=8, down_dims=(8, 16), obs_embed_dim=8)
    >>> box = {"min": [0.0, 0.0], "max": [4.0, 4.0]}
    >>> policy = DiffusionPolicy(cfg, {"observation": box, "action": box})
    >>> policy.normalize(np.array([[2.0, 4.0]])).tolist()
    [[0.0, 1.0]]
    """

    name = "dp"
    config_class = DiffusionConfig
    legacy_format = LEGACY_FORMAT
    config: DiffusionConfig

    def __init__(
        self,
        config: DiffusionConfig,
        stats: Mapping[str, Any] | None = None,
        *,
        seed: int = 0,
        device: str | torch.device = "cpu",
    ) -> None:
        super().__init__(config, stats, seed=seed, device=device)
        self.scheduler = cast(
            _Scheduler,
            DDIMScheduler(
                num_train_timesteps=self.config.num_train_timesteps,
                beta_schedule=self.config.beta_schedule,
                clip_sample=True,
                clip_sample_range=self.config.clip_sample_range,
                prediction_type="epsilon",
                set_alpha_to_one=True,
                steps_offset=0,
            ),
        )
        self.num_inference_steps = self.config.num_inference_steps

    def with_steps(self, steps: int) -> DiffusionPolicy:
        """This policy sampled with ``steps`` DDIM steps: a copy sharing the network and its acceleration.

        Fewer steps call the network fewer times per plan (the steering
        samplers' cost is DDIM steps x SS's MCMC steps); this policy keeps its
        own steps for every other caller.

        >>> policy = DiffusionPolicy(DiffusionConfig(obs_dim=2, action_dim=2, horizon=8, down_dims=(8, 16)))
        >>> policy.with_steps(4).num_inference_steps, policy.num_inference_steps
        (4, 10)
        """
        fewer = copy.copy(self)
        fewer.scheduler = copy.deepcopy(self.scheduler)  # set_timesteps changes it: one per step count
        fewer.num_inference_steps = integer(
            steps, "steps", low=1, high=self.config.num_train_timesteps, owner="DiffusionPolicy.with_steps"
        )
        return fewer

    def _build_model(self) -> nn.Module:
        return DiffusionNet(self.config)

    # ------------------------------------------------------------ protocol
    def predict_noise(self, x_t: torch.Tensor, t: Any, cond: torch.Tensor) -> torch.Tensor:
        """``eps(x_t, t | cond)`` for normalized plans ``x_t (n, H, d)``; differentiable in ``x_t``.

        ``x_t`` is a finite floating-point tensor; ``t`` an int, a 0-d integer
        tensor or ``(n,)`` integer timesteps in ``[0, num_train_timesteps)``;
        ``cond`` (from :meth:`encode_obs`) a finite ``(1 or n, n_obs_steps *
        obs_dim)`` tensor. ``TypeError`` / ``ValueError`` naming the argument otherwise.
        """
        owner = "DiffusionPolicy.predict_noise"
        if not isinstance(x_t, torch.Tensor) or not x_t.is_floating_point():
            what = f"dtype {x_t.dtype}" if isinstance(x_t, torch.Tensor) else describe(x_t)
            raise TypeError(f"{owner}: x_t must be a floating-point torch.Tensor, got {what}")
        check_tensor(x_t, "x_t", (None, self.horizon, self.action_dim), owner=owner)
        n = x_t.shape[0]
        t = self._timesteps(t, n, x_t.device)
        if isinstance(cond, np.ndarray):
            cond = torch.from_numpy(real_array(cond, "cond", owner=owner))
        if not isinstance(cond, torch.Tensor):
            raise TypeError(f"{owner}: cond must be a torch.Tensor (from encode_obs), got {describe(cond)}")
        width = self.n_obs_steps * self.obs_dim
        if cond.ndim != 2 or cond.shape[0] not in (1, n) or cond.shape[1] != width:
            raise ValueError(f"{owner}: cond must have shape (1 or {n}, {width}), got {tuple(cond.shape)}")
        check_tensor(cond, "cond", (None, width), owner=owner)
        rows = cond.to(device=x_t.device, dtype=x_t.dtype)  # 1 or n rows; broadcast below
        abar = self.scheduler.alphas_cumprod.to(x_t.device)[t.long()].to(x_t.dtype).reshape(-1, 1, 1)
        x_rel = self._centered(x_t, abar, rows)
        out = self._network(x_rel, t, rows)
        if self.config.prediction == "epsilon":
            return out
        return (1 - abar).sqrt() * x_rel + abar.sqrt() * out  # epsilon implied by v (exact, no division)

    def _timesteps(self, t: Any, n: int, device: torch.device) -> torch.Tensor:
        """``t`` as a 1-D integer tensor of 1 or ``n`` diffusion steps in ``[0, num_train_timesteps)``."""
        owner = "DiffusionPolicy.predict_noise"
        if isinstance(t, torch.Tensor):
            if t.is_floating_point() or t.is_complex() or t.dtype == torch.bool:
                raise TypeError(f"{owner}: t must hold integer timesteps, got dtype {t.dtype}")
        elif isinstance(t, np.ndarray):
            if t.dtype.kind not in "iu":
                raise TypeError(f"{owner}: t must hold integer timesteps, got dtype {t.dtype}")
        elif not isinstance(t, (int, np.integer)) or isinstance(t, (bool, np.bool_)):
            raise TypeError(f"{owner}: t must be an int or an integer tensor, got {describe(t)}")
        steps = torch.as_tensor(t, device=device).reshape(-1)
        if steps.numel() not in (1, n):
            raise ValueError(f"{owner}: t must be a scalar or have {n} entries, got {steps.numel()}")
        top = self.config.num_train_timesteps
        if bool(((steps < 0) | (steps >= top)).any()):
            raise ValueError(f"{owner}: t must be in [0, {top}), got {steps.tolist()[:8]}")
        return steps

    def _centered(self, x: torch.Tensor, abar: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """``x - sqrt(abar) * p`` with ``p`` the current values of ``action_obs_indices`` when ``relative``.

        Noising commutes with this shift (the noise is unchanged), so the network
        sees and predicts plans relative to the current state, not absolute
        values that GroupNorm would have to carry through every block.
        """
        if not self.config.relative or self.config.action_obs_indices is None:
            return x
        current = cond.reshape(cond.shape[0], self.n_obs_steps, self.obs_dim)[:, -1]
        return x - abar.sqrt() * current[:, None, list(self.config.action_obs_indices)]

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        """``n`` plans ``(n, horizon, action_dim)`` in data units by DDIM, the initial noise from ``generator``.

        ``obs`` is an env observation or a history of them, oldest first (finite
        real numbers, see :func:`~steer_envs.baselines.common.torch_policy.observation_history`);
        ``n`` an int in ``[1, max_samples]``; ``generator`` a numpy ``Generator`` or ``None``.
        """
        rng = self._sample_args(n, generator)
        with torch.no_grad():
            cond = self.encode_obs(obs)
        noise = rng.standard_normal((int(n), self.horizon, self.action_dim), dtype=np.float32)
        with torch.no_grad():
            x = self.denoise(torch.from_numpy(noise).to(self._device), cond)
            return self.unnormalize(x).cpu().numpy().astype(np.float64)

    def denoise(self, x: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """Run the unguided DDIM loop from noise ``x`` (normalized space) to a plan."""
        self.scheduler.set_timesteps(self.num_inference_steps)
        for t in self.scheduler.timesteps:
            x = self.scheduler.step(self.predict_noise(x, t, cond), t, x).prev_sample
        return x

    # ------------------------------------------------------------ training
    def loss(self, obs: torch.Tensor, plans: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """Denoising MSE (epsilon or v target): ``obs (B, n_obs_steps, obs_dim)``, ``plans (B, H, action_dim)``.

        Both real finite tensors; ``generator`` a ``torch.Generator`` or ``None``.
        """
        x0, cond, noise, gen_device = self._noised_batch(obs, plans, generator)
        b = plans.shape[0]
        t = torch.randint(0, self.config.num_train_timesteps, (b,), generator=generator, device=gen_device)
        t = t.to(self._device)
        x_t = self.scheduler.add_noise(x0, noise, t)
        abar = self.scheduler.alphas_cumprod.to(self._device)[t].reshape(-1, 1, 1)
        out = self.model(self._centered(x_t, abar, cond), t, cond)
        if self.config.prediction == "epsilon":
            return nn.functional.mse_loss(out, noise)
        x0_rel = self._centered(x0, torch.ones_like(abar), cond)
        return nn.functional.mse_loss(out, abar.sqrt() * noise - (1 - abar).sqrt() * x0_rel)

    # --------------------------------------------------------- persistence
    @classmethod
    def upgrade_legacy_config(cls, values: Mapping[str, Any]) -> DiffusionConfig:
        """The config of a pre-factory DP (2-D positions; observation = the xy of the env observation)."""
        old = dict(values)
        d = int(old.get("action_dim", 2))
        return DiffusionConfig.from_dict(
            {
                **old,
                "obs_dim": d,
                "normalization": "min_max",
                "obs_indices": list(range(d)),
                "action_obs_indices": list(range(d)),
            }
        )

    @classmethod
    def upgrade_legacy(cls, header: Mapping[str, Any]) -> tuple[DiffusionConfig, dict[str, Any]]:
        """Config and statistics of a pre-factory checkpoint (one min-max box for positions and plans)."""
        bounds = {"min": header["low"], "max": header["high"]}
        return cls.upgrade_legacy_config(header["model"]), {"observation": bounds, "action": bounds}
