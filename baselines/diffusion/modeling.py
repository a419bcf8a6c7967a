"""Diffusion Policy (Chi et al. 2023) for Maze2D, in the ITPS configuration scaled down for the CPU.

The denoiser is Diffusion Policy's 1D temporal U-Net: residual blocks of
``Conv1d -> GroupNorm -> SiLU`` whose features are FiLM-modulated (per-channel
scale and bias) by the diffusion-step embedding concatenated with the global
condition, here the last ``n_obs_steps`` agent positions. Sampling runs a
diffusers :class:`~diffusers.DDIMScheduler` with the ITPS maze settings (100
training steps, ``squaredcos_cap_v2``, epsilon parameterization,
``clip_sample`` +-1, 10 inference steps: t = 90, 80, ..., 0): samplers see an
epsilon predictor, :meth:`DiffusionPolicy.predict_noise`.

What differs from ITPS, and why (2 shared CPU cores instead of a GPU for 100k
steps at batch 256, i.e. ~1/200 of the training compute):

* widths: down dims 16/32/64 instead of 128/256/512 (a 10-step batch of 32
  costs 10 passes of a 0.7M-parameter net);
* SiLU instead of Mish (nearly the same curve; torch's CPU Mish kernel is
  ~40x slower than SiLU and took a third of the sampling time);
* by default the network is trained with the *v* target (Salimans & Ho 2022)
  on plans *relative to the current position* (``relative``), plus a
  plan-index input channel and a Fourier-feature MLP encoding the observation.
  ``predict_noise`` converts v to the epsilon it implies exactly, so the
  scheduler and the guidance math are unchanged. In short CPU runs the ITPS
  parameterization (``prediction="epsilon"``, absolute plans) mislocated plans
  by several cells at high noise, where epsilon errors are amplified by
  ``1/sqrt(abar)``; ``DiffusionConfig(prediction="epsilon", relative=False,
  time_channel=False, obs_embed_dim=0)`` is Chi et al.'s network (with SiLU).

Plans use LeRobot's layout (ITPS): ``horizon`` waypoints starting at the
*current* position, so ``plan[0]`` is where the agent is and
``plan[exec_start:]`` (63 waypoints) are executed. Positions and plans are
min-max normalized to [-1, 1] with the training data's bounds.

:class:`DiffusionPolicy` satisfies :class:`steer_envs.core.DiffusionPolicyLike`,
so the guided samplers (BI, GD, SS) can run and steer its denoising loop.
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from diffusers import DDIMScheduler
from diffusers.models.embeddings import get_timestep_embedding
from torch import nn

from steer_envs.baselines.common.torch_policy import (
    TorchPolicy,
    as_coords,
    obs_history,
    read_checkpoint,
    write_checkpoint,
)

__all__ = ["ConditionalUnet1D", "DiffusionConfig", "DiffusionNet", "DiffusionPolicy", "ObsEncoder"]

FORMAT = "steer_envs.baselines.diffusion/1"
#: the network's target: the noise (Chi et al., ITPS) or the velocity v = sqrt(abar) eps - sqrt(1 - abar) x0.
PREDICTIONS = ("epsilon", "v")


@dataclass(frozen=True)
class DiffusionConfig:
    """Architecture and sampling settings; defaults = the shipped checkpoint (departures from ITPS: module doc)."""

    horizon: int = 64
    n_obs_steps: int = 2
    action_dim: int = 2
    down_dims: tuple[int, ...] = (16, 32, 64)
    kernel_size: int = 5
    n_groups: int = 8
    step_embed_dim: int = 64
    num_train_timesteps: int = 100
    num_inference_steps: int = 10
    beta_schedule: str = "squaredcos_cap_v2"
    clip_sample_range: float = 1.0
    prediction: str = "v"
    relative: bool = True
    time_channel: bool = True
    obs_embed_dim: int = 256
    obs_octaves: int = 6

    def __post_init__(self) -> None:
        object.__setattr__(self, "down_dims", tuple(int(d) for d in self.down_dims))
        for name in ("horizon", "n_obs_steps", "action_dim", "kernel_size", "n_groups", "step_embed_dim"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{name} must be a positive int, got {value!r}")
        if not self.down_dims or any(d < 1 or d % self.n_groups for d in self.down_dims):
            raise ValueError(f"down_dims must be positive multiples of n_groups={self.n_groups}, got {self.down_dims}")
        if self.kernel_size % 2 == 0:
            raise ValueError(f"kernel_size must be odd, got {self.kernel_size}")
        if self.step_embed_dim % 2:
            raise ValueError(f"step_embed_dim must be even, got {self.step_embed_dim}")
        stride = 2 ** (len(self.down_dims) - 1)
        if self.horizon % stride:
            raise ValueError(f"horizon must be a multiple of {stride} for {len(self.down_dims)} U-Net levels")
        if not 1 <= self.num_inference_steps <= self.num_train_timesteps:
            raise ValueError(
                f"num_inference_steps must be in [1, num_train_timesteps={self.num_train_timesteps}], "
                f"got {self.num_inference_steps}"
            )
        if self.prediction not in PREDICTIONS:
            raise ValueError(f"prediction must be one of {PREDICTIONS}, got {self.prediction!r}")
        for name in ("obs_embed_dim", "obs_octaves"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < 0:
                raise ValueError(f"{name} must be an int >= 0, got {value!r}")
        if not (np.isfinite(self.clip_sample_range) and self.clip_sample_range > 0):
            raise ValueError(f"clip_sample_range must be a positive float, got {self.clip_sample_range!r}")

    @property
    def exec_start(self) -> int:
        """Index of the first executed waypoint: ``plan[:n_obs_steps - 1]`` re-states observed positions."""
        return self.n_obs_steps - 1

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["down_dims"] = list(self.down_dims)
        return out


# ----------------------------------------------------------------- network
class _ConvBlock(nn.Sequential):
    """``Conv1d -> GroupNorm -> SiLU`` (length preserving)."""

    def __init__(self, c_in: int, c_out: int, kernel: int, groups: int) -> None:
        super().__init__(nn.Conv1d(c_in, c_out, kernel, padding=kernel // 2), nn.GroupNorm(groups, c_out), nn.SiLU())


class _FiLMResBlock(nn.Module):
    """Two conv blocks; the first one's output is scaled and shifted per channel from the condition."""

    def __init__(self, c_in: int, c_out: int, cond_dim: int, kernel: int, groups: int) -> None:
        super().__init__()
        self.block1 = _ConvBlock(c_in, c_out, kernel, groups)
        self.block2 = _ConvBlock(c_out, c_out, kernel, groups)
        self.film = nn.Sequential(nn.SiLU(), nn.Linear(cond_dim, 2 * c_out))
        self.residual = nn.Conv1d(c_in, c_out, 1) if c_in != c_out else nn.Identity()

    def forward(self, x: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        scale, bias = self.film(cond).unsqueeze(-1).chunk(2, dim=1)
        h = self.block1(x) * scale + bias
        return self.block2(h) + self.residual(x)


class ConditionalUnet1D(nn.Module):
    """Diffusion Policy's temporal U-Net: ``(B, T, d)`` noisy plans -> ``(B, T, d)`` noise estimates.

    Each level has two FiLM residual blocks and halves the length (all but the
    last); two more blocks sit in the middle; the up path mirrors the down path
    with skip connections. The condition is ``[step embedding, global_cond]``.
    """

    def __init__(
        self,
        input_dim: int,
        global_cond_dim: int,
        down_dims: tuple[int, ...] = (16, 32, 64),
        kernel_size: int = 5,
        n_groups: int = 8,
        step_embed_dim: int = 64,
        out_dim: int | None = None,
    ) -> None:
        super().__init__()
        self.step_embed_dim = step_embed_dim
        self.step_mlp = nn.Sequential(
            nn.Linear(step_embed_dim, 4 * step_embed_dim), nn.SiLU(), nn.Linear(4 * step_embed_dim, step_embed_dim)
        )
        cond_dim = step_embed_dim + global_cond_dim
        dims = [input_dim, *down_dims]
        levels = list(itertools.pairwise(dims))

        def block(a: int, b: int) -> _FiLMResBlock:
            return _FiLMResBlock(a, b, cond_dim, kernel_size, n_groups)

        self.down = nn.ModuleList()
        for i, (a, b) in enumerate(levels):
            last = i == len(levels) - 1
            sample = nn.Identity() if last else nn.Conv1d(b, b, 3, stride=2, padding=1)
            self.down.append(nn.ModuleList([block(a, b), block(b, b), sample]))
        self.mid = nn.ModuleList([block(down_dims[-1], down_dims[-1]), block(down_dims[-1], down_dims[-1])])
        self.up = nn.ModuleList()
        for a, b in reversed(levels[1:]):
            upsample = nn.ConvTranspose1d(a, a, 4, stride=2, padding=1)
            self.up.append(nn.ModuleList([block(2 * b, a), block(a, a), upsample]))
        self.final = nn.Sequential(
            _ConvBlock(down_dims[0], down_dims[0], kernel_size, n_groups),
            nn.Conv1d(down_dims[0], input_dim if out_dim is None else out_dim, 1),
        )

    def forward(self, x: torch.Tensor, timestep: torch.Tensor, global_cond: torch.Tensor) -> torch.Tensor:
        """``x (B, T, d)``, ``timestep (B,)``, ``global_cond (B, c)`` -> ``(B, T, d)``."""
        emb = get_timestep_embedding(timestep, self.step_embed_dim, flip_sin_to_cos=True, downscale_freq_shift=1)
        cond = torch.cat([self.step_mlp(emb.to(x.dtype)), global_cond], dim=-1)
        h = x.transpose(1, 2)
        skips = []
        for res1, res2, downsample in self.down:
            h = res2(res1(h, cond), cond)
            skips.append(h)
            h = downsample(h)
        for res in self.mid:
            h = res(h, cond)
        for res1, res2, upsample in self.up:
            h = torch.cat([h, skips.pop()], dim=1)
            h = upsample(res2(res1(h, cond), cond))
        return self.final(h).transpose(1, 2)


class ObsEncoder(nn.Module):
    """Normalized position history ``(B, c)`` -> ``(B, embed_dim)``: Fourier features + MLP.

    Raw coordinates enter FiLM only linearly; sines and cosines at ``octaves``
    frequencies let a small network resolve walls a cell apart.
    """

    def __init__(self, in_dim: int, embed_dim: int, octaves: int) -> None:
        super().__init__()
        self.register_buffer("freqs", math.pi * 2.0 ** torch.arange(octaves, dtype=torch.float32), persistent=False)
        features = in_dim * (1 + 2 * octaves)
        self.mlp = nn.Sequential(
            nn.Linear(features, embed_dim),
            nn.SiLU(),
            nn.Linear(embed_dim, embed_dim),
            nn.SiLU(),
            nn.Linear(embed_dim, embed_dim),
        )

    def forward(self, cond: torch.Tensor) -> torch.Tensor:
        angles = (cond[..., None] * self.freqs).flatten(1)
        return self.mlp(torch.cat([cond, angles.sin(), angles.cos()], dim=-1))


class DiffusionNet(nn.Module):
    """Observation encoder (optional) + :class:`ConditionalUnet1D`: the trainable part of the policy."""

    def __init__(self, cfg: DiffusionConfig) -> None:
        super().__init__()
        cond_dim = cfg.n_obs_steps * cfg.action_dim
        if cfg.obs_embed_dim:
            self.obs_encoder: nn.Module = ObsEncoder(cond_dim, cfg.obs_embed_dim, cfg.obs_octaves)
            cond_dim = cfg.obs_embed_dim
        else:
            self.obs_encoder = nn.Identity()
        extra = 1 if cfg.time_channel else 0
        self.unet = ConditionalUnet1D(
            cfg.action_dim + extra,
            cond_dim,
            cfg.down_dims,
            cfg.kernel_size,
            cfg.n_groups,
            cfg.step_embed_dim,
            out_dim=cfg.action_dim,
        )
        if cfg.time_channel:  # plan index in [-1, 1]: convolutions alone only see it through edge effects
            self.register_buffer("ramp", torch.linspace(-1, 1, cfg.horizon)[None, :, None], persistent=False)
        self.time_channel = cfg.time_channel

    def forward(self, x: torch.Tensor, timestep: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        if self.time_channel:
            x = torch.cat([x, self.ramp.expand(x.shape[0], -1, -1).to(x.dtype)], dim=-1)
        return self.unet(x, timestep, self.obs_encoder(cond))


# ------------------------------------------------------------------ policy
class DiffusionPolicy(TorchPolicy):
    """Maze2D Diffusion Policy: observation history -> batch of plans by DDIM (a ``DiffusionPolicyLike``).

    Args:
        config: architecture and sampling settings.
        low, high: per-coordinate bounds of positions in the training data;
            ``normalize`` maps ``[low, high]`` to ``[-1, 1]``.
        seed: seed of the initial weights.
        device: torch device of the network.
    """

    def __init__(
        self,
        config: DiffusionConfig | None = None,
        low: Any = (0.0, 0.0),
        high: Any = (1.0, 1.0),
        *,
        seed: int = 0,
        device: str | torch.device = "cpu",
    ) -> None:
        self.config = config if config is not None else DiffusionConfig()
        if not isinstance(self.config, DiffusionConfig):
            raise TypeError(f"config must be a DiffusionConfig, got {type(config).__name__}")
        d = self.config.action_dim
        lo, hi = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
        if lo.shape != (d,) or hi.shape != (d,) or not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise ValueError(f"low and high must be finite arrays of shape ({d},), got {lo.shape} and {hi.shape}")
        if np.any(hi <= lo):
            raise ValueError(f"high must exceed low in every coordinate, got low={lo.tolist()} high={hi.tolist()}")
        self.low, self.high = lo, hi
        self._init_network(lambda: DiffusionNet(self.config), seed, device)
        self._low_t = torch.as_tensor(lo, dtype=torch.float32, device=self._device)
        self._high_t = torch.as_tensor(hi, dtype=torch.float32, device=self._device)
        self.scheduler = DDIMScheduler(
            num_train_timesteps=self.config.num_train_timesteps,
            beta_schedule=self.config.beta_schedule,
            clip_sample=True,
            clip_sample_range=self.config.clip_sample_range,
            prediction_type="epsilon",
            set_alpha_to_one=True,
            steps_offset=0,
        )
        self.num_inference_steps = self.config.num_inference_steps

    # ------------------------------------------------------------ protocol
    @property
    def horizon(self) -> int:
        """States per plan (64; ``plan[0]`` is the current position)."""
        return self.config.horizon

    @property
    def action_dim(self) -> int:
        return self.config.action_dim

    @property
    def n_obs_steps(self) -> int:
        """Positions of history the policy conditions on."""
        return self.config.n_obs_steps

    @property
    def exec_start(self) -> int:
        """Index of the first plan waypoint to execute (1: ``plan[0]`` is the current position)."""
        return self.config.exec_start

    def _moved(self) -> None:
        self._low_t, self._high_t = self._low_t.to(self._device), self._high_t.to(self._device)

    def normalize(self, traj: Any) -> Any:
        """Env units -> [-1, 1] per coordinate; numpy in numpy out, torch in torch out."""
        if isinstance(traj, torch.Tensor):
            lo, hi = self._low_t.to(traj.device, traj.dtype), self._high_t.to(traj.device, traj.dtype)
            return 2 * (traj - lo) / (hi - lo) - 1
        arr = as_coords(traj, self.action_dim, "traj")
        return 2 * (arr - self.low) / (self.high - self.low) - 1

    def unnormalize(self, traj: Any) -> Any:
        """Inverse of :meth:`normalize`."""
        if isinstance(traj, torch.Tensor):
            lo, hi = self._low_t.to(traj.device, traj.dtype), self._high_t.to(traj.device, traj.dtype)
            return (traj + 1) / 2 * (hi - lo) + lo
        arr = as_coords(traj, self.action_dim, "traj")
        return (arr + 1) / 2 * (self.high - self.low) + self.low

    def encode_obs(self, obs: Any) -> torch.Tensor:
        """Global condition ``(1, n_obs_steps * 2)``: the normalized position history (see ``obs_history``)."""
        hist = obs_history(obs, self.n_obs_steps)
        return self.normalize(torch.from_numpy(hist).to(self._device)).reshape(1, -1)

    def predict_noise(self, x_t: torch.Tensor, t: Any, cond: torch.Tensor) -> torch.Tensor:
        """``eps(x_t, t | cond)`` for normalized plans ``x_t (n, H, d)``; differentiable in ``x_t``.

        ``t`` is an int, a 0-d tensor or ``(n,)`` timesteps; ``cond`` (from
        :meth:`encode_obs`) has 1 or ``n`` rows.
        """
        if not isinstance(x_t, torch.Tensor) or x_t.ndim != 3 or x_t.shape[1:] != (self.horizon, self.action_dim):
            shape = tuple(x_t.shape) if isinstance(x_t, torch.Tensor) else type(x_t).__name__
            raise ValueError(f"x_t must be a tensor of shape (n, {self.horizon}, {self.action_dim}), got {shape}")
        n = x_t.shape[0]
        t = torch.as_tensor(t, device=x_t.device).reshape(-1)
        if t.numel() not in (1, n):
            raise ValueError(f"t must be a scalar or have {n} entries, got {t.numel()}")
        cond = torch.as_tensor(cond, device=x_t.device, dtype=x_t.dtype)
        if cond.ndim != 2 or cond.shape[0] not in (1, n) or cond.shape[1] != self.n_obs_steps * self.action_dim:
            raise ValueError(
                f"cond must have shape (1 or {n}, {self.n_obs_steps * self.action_dim}), got {tuple(cond.shape)}"
            )
        cond = cond.expand(n, -1)
        abar = self.scheduler.alphas_cumprod.to(x_t.device)[t.long()].to(x_t.dtype).reshape(-1, 1, 1)
        x_rel = self._centered(x_t, abar, cond)
        out = self.model(x_rel, t.expand(n), cond)
        if self.config.prediction == "epsilon":
            return out
        return (1 - abar).sqrt() * x_rel + abar.sqrt() * out  # epsilon implied by v (exact, no division)

    def _centered(self, x: torch.Tensor, abar: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """``x - sqrt(abar) * p`` with ``p`` the last observed position (normalized) when ``relative``.

        Noising commutes with this shift (the noise is unchanged), so the network
        sees and predicts plans relative to the agent, not absolute positions
        that GroupNorm would have to carry through every block.
        """
        if not self.config.relative:
            return x
        return x - abar.sqrt() * cond[:, None, -self.action_dim :]

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        """``n`` plans ``(n, horizon, 2)`` in env units by DDIM; the initial noise comes from ``generator``."""
        if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 1:
            raise ValueError(f"n must be a positive int, got {n!r}")
        if generator is not None and not isinstance(generator, np.random.Generator):
            raise TypeError(f"generator must be a numpy Generator or None, got {type(generator).__name__}")
        rng = generator if generator is not None else np.random.default_rng()
        noise = rng.standard_normal((int(n), self.horizon, self.action_dim), dtype=np.float32)
        with torch.no_grad():
            cond = self.encode_obs(obs)
            x = self.denoise(torch.from_numpy(noise).to(self._device), cond)
            return self.unnormalize(x).cpu().numpy().astype(np.float64)

    def denoise(self, x: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """Run the unguided DDIM loop from noise ``x`` (normalized space) to a plan."""
        self.scheduler.set_timesteps(self.num_inference_steps)
        for t in self.scheduler.timesteps:
            x = self.scheduler.step(self.predict_noise(x, t, cond), t, x).prev_sample
        return x

    # ------------------------------------------------------------ training
    @property
    def window_layout(self) -> dict[str, int]:
        """``PlanWindows`` arguments giving this policy's training pairs (LeRobot layout)."""
        return {"n_obs": self.n_obs_steps, "horizon": self.horizon, "action_start": 1 - self.n_obs_steps}

    def loss(self, obs: torch.Tensor, plans: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """Denoising MSE (epsilon or v target) on a batch: ``obs (B, n_obs, 2)``, ``plans (B, H, 2)`` in env units."""
        b = plans.shape[0]
        if obs.shape != (b, self.n_obs_steps, self.action_dim) or plans.shape[1:] != (self.horizon, self.action_dim):
            raise ValueError(
                f"expected obs (B, {self.n_obs_steps}, {self.action_dim}) and plans (B, {self.horizon}, "
                f"{self.action_dim}), got {tuple(obs.shape)} and {tuple(plans.shape)}"
            )
        x0 = self.normalize(plans.to(self._device, torch.float32))
        cond = self.normalize(obs.to(self._device, torch.float32)).reshape(b, -1)
        gen_device = generator.device if generator is not None else self._device
        noise = torch.randn(x0.shape, generator=generator, device=gen_device).to(self._device)
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
    def save(self, path: str | os.PathLike[str], extra: dict[str, Any] | None = None) -> Path:
        """Write weights, config and normalization bounds to a ``.safetensors`` file atomically."""
        config = {
            "format": FORMAT,
            "model": self.config.to_dict(),
            "low": self.low.tolist(),
            "high": self.high.tolist(),
            "extra": dict(extra or {}),
        }
        return write_checkpoint(path, self.model.state_dict(), config)

    @classmethod
    def load(cls, path: str | os.PathLike[str], device: str | torch.device = "cpu") -> DiffusionPolicy:
        """A policy from a file written by :meth:`save` (safetensors: loading runs no code)."""
        tensors, config = read_checkpoint(path, FORMAT)
        model_cfg = dict(config["model"])
        policy = cls(DiffusionConfig(**model_cfg), config["low"], config["high"], device=device)
        policy.model.load_state_dict(tensors)
        policy.model.to(policy.device).eval()
        policy.checkpoint_info = dict(config.get("extra", {}))
        return policy
