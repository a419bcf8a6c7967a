"""ACT, the action-chunking transformer (Zhao et al. 2023), for Maze2D in the ITPS configuration, CPU-sized.

A conditional VAE. Training: a transformer *VAE encoder* reads
``[CLS, state, action chunk]`` and outputs the posterior ``q(z | s, a)``
(latent 32); the *policy* is a transformer encoder over ``[z, state]`` tokens
and a transformer decoder whose ``chunk_size`` learned queries cross-attend to
it and regress the chunk. Loss: L1 on the normalized chunk + ``kl_weight``
(10) x KL(q || N(0, I)). At inference the latent is drawn from N(0, I) (ITPS)
instead of ACT's ``z = 0``, so a batch of plans comes out; with KL weight 10 it
is nearly unimodal, which is the thesis's point about ACT.

ITPS maze config: d_model 512, 8 heads, FFN 3200, 4 encoder / 1 decoder / 4
VAE-encoder layers. Here: d_model 128, 4 heads, FFN 256, 2 / 1 / 1 layers, so
it trains on 2 CPU cores. One observation step (the current xy); the chunk is
the next ``chunk_size`` waypoints (``plan[0]`` = next position, all executed).
States and actions are normalized by the data's mean and std (ITPS).

With ``relative`` the chunk is regressed relative to the current position
(normalized units) instead of as absolute positions (ITPS, the default). In
CPU-budget runs neither reaches ITPS's ACT (collision 0.16 from rest): absolute
chunks (shipped, 3000 steps) start 0.3-0.8 cells from the agent and collide in
0.54 of plans; relative chunks (2000 steps) start at the agent but collide in
0.70. Both collapse the latent (KL ~1e-6).

:class:`ACTPolicy` satisfies :class:`steer_envs.core.TrajectoryPolicy`.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from steer_envs.baselines.common.torch_policy import (
    TorchPolicy,
    as_coords,
    obs_history,
    read_checkpoint,
    write_checkpoint,
)

__all__ = ["ACTConfig", "ACTModel", "ACTPolicy"]

FORMAT = "steer_envs.baselines.act/1"


@dataclass(frozen=True)
class ACTConfig:
    """Architecture and loss settings (defaults: ITPS maze config with CPU-sized widths)."""

    chunk_size: int = 64
    state_dim: int = 2
    action_dim: int = 2
    d_model: int = 128
    n_heads: int = 4
    dim_feedforward: int = 256
    n_encoder_layers: int = 2
    n_decoder_layers: int = 1
    n_vae_encoder_layers: int = 1
    latent_dim: int = 32
    dropout: float = 0.1
    kl_weight: float = 10.0
    relative: bool = False

    def __post_init__(self) -> None:
        for name in (
            "chunk_size",
            "state_dim",
            "action_dim",
            "d_model",
            "n_heads",
            "dim_feedforward",
            "n_encoder_layers",
            "n_decoder_layers",
            "n_vae_encoder_layers",
            "latent_dim",
        ):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{name} must be a positive int, got {value!r}")
        if self.d_model % self.n_heads:
            raise ValueError(f"d_model ({self.d_model}) must be a multiple of n_heads ({self.n_heads})")
        if self.d_model % 2:
            raise ValueError(f"d_model must be even (sinusoidal positions), got {self.d_model}")
        if not 0 <= self.dropout < 1:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout!r}")
        if not (np.isfinite(self.kl_weight) and self.kl_weight >= 0):
            raise ValueError(f"kl_weight must be a finite float >= 0, got {self.kl_weight!r}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _sinusoid(n: int, d: int) -> torch.Tensor:
    """Fixed sinusoidal position table ``(n, d)`` (Transformer / ACT VAE encoder)."""
    pos = torch.arange(n, dtype=torch.float32)[:, None]
    freq = torch.exp(-np.log(10000.0) * torch.arange(0, d, 2, dtype=torch.float32) / d)
    table = torch.zeros(n, d)
    table[:, 0::2], table[:, 1::2] = torch.sin(pos * freq), torch.cos(pos * freq)
    return table


class ACTModel(nn.Module):
    """The CVAE networks: :meth:`posterior` (training only) and :meth:`decode` (the policy)."""

    def __init__(self, cfg: ACTConfig) -> None:
        super().__init__()
        d = cfg.d_model
        self.cfg = cfg

        def encoder(layers: int) -> nn.TransformerEncoder:
            layer = nn.TransformerEncoderLayer(d, cfg.n_heads, cfg.dim_feedforward, cfg.dropout, batch_first=True)
            return nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)

        # VAE encoder q(z | state, chunk)
        self.vae_cls = nn.Parameter(torch.zeros(1, 1, d))
        self.vae_state_proj = nn.Linear(cfg.state_dim, d)
        self.vae_action_proj = nn.Linear(cfg.action_dim, d)
        self.vae_encoder = encoder(cfg.n_vae_encoder_layers)
        self.vae_out = nn.Linear(d, 2 * cfg.latent_dim)
        self.register_buffer("vae_pos", _sinusoid(cfg.chunk_size + 2, d)[None], persistent=False)
        # policy: encoder over [z, state], decoder with chunk_size learned queries
        self.latent_proj = nn.Linear(cfg.latent_dim, d)
        self.state_proj = nn.Linear(cfg.state_dim, d)
        self.enc_pos = nn.Parameter(torch.zeros(1, 2, d))
        self.encoder = encoder(cfg.n_encoder_layers)
        self.queries = nn.Parameter(torch.zeros(1, cfg.chunk_size, d))
        layer = nn.TransformerDecoderLayer(d, cfg.n_heads, cfg.dim_feedforward, cfg.dropout, batch_first=True)
        self.decoder = nn.TransformerDecoder(layer, cfg.n_decoder_layers)
        self.head = nn.Linear(d, cfg.action_dim)
        for p in (self.vae_cls, self.enc_pos, self.queries):
            nn.init.normal_(p, std=0.02)

    def posterior(self, state: torch.Tensor, actions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``mu, logvar`` ``(B, latent)`` of q(z | state ``(B, s)``, actions ``(B, chunk, a)``)."""
        b = state.shape[0]
        tokens = torch.cat(
            [self.vae_cls.expand(b, -1, -1), self.vae_state_proj(state)[:, None], self.vae_action_proj(actions)], dim=1
        )
        out = self.vae_encoder(tokens + self.vae_pos)[:, 0]
        mu, logvar = self.vae_out(out).chunk(2, dim=-1)
        return mu, logvar

    def decode(self, state: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """Normalized chunk ``(B, chunk, a)`` from state ``(B, s)`` and latent ``(B, latent)``."""
        b = state.shape[0]
        memory = self.encoder(torch.stack([self.latent_proj(z), self.state_proj(state)], dim=1) + self.enc_pos)
        return self.head(self.decoder(self.queries.expand(b, -1, -1), memory))


class ACTPolicy(TorchPolicy):
    """Maze2D ACT: current xy -> batch of chunks, latent ``z ~ N(0, I)`` per plan (a ``TrajectoryPolicy``).

    Args:
        config: architecture and loss settings.
        mean, std: per-coordinate mean and std of positions in the training data.
        seed: seed of the initial weights.
        device: torch device of the network.
    """

    n_obs_steps = 1
    exec_start = 0

    def __init__(
        self,
        config: ACTConfig | None = None,
        mean: Any = (0.0, 0.0),
        std: Any = (1.0, 1.0),
        *,
        seed: int = 0,
        device: str | torch.device = "cpu",
    ) -> None:
        self.config = config if config is not None else ACTConfig()
        if not isinstance(self.config, ACTConfig):
            raise TypeError(f"config must be an ACTConfig, got {type(config).__name__}")
        if self.config.state_dim != self.config.action_dim:
            raise ValueError("ACTPolicy needs state_dim == action_dim (both are xy positions)")
        d = self.config.action_dim
        mu, sd = np.asarray(mean, dtype=np.float64), np.asarray(std, dtype=np.float64)
        if mu.shape != (d,) or sd.shape != (d,) or not (np.all(np.isfinite(mu)) and np.all(np.isfinite(sd))):
            raise ValueError(f"mean and std must be finite arrays of shape ({d},), got {mu.shape} and {sd.shape}")
        if np.any(sd <= 0):
            raise ValueError(f"std must be positive, got {sd.tolist()}")
        self.mean, self.std = mu, sd
        self._init_network(lambda: ACTModel(self.config), seed, device)

    @property
    def horizon(self) -> int:
        """Waypoints per plan (the chunk size, 64)."""
        return self.config.chunk_size

    @property
    def action_dim(self) -> int:
        return self.config.action_dim

    def normalize(self, traj: Any) -> Any:
        """Env units -> standardized (mean 0, std 1 on the data); numpy or torch."""
        if isinstance(traj, torch.Tensor):
            return (traj - traj.new_tensor(self.mean)) / traj.new_tensor(self.std)
        return (as_coords(traj, self.action_dim, "traj") - self.mean) / self.std

    def unnormalize(self, traj: Any) -> Any:
        """Inverse of :meth:`normalize`."""
        if isinstance(traj, torch.Tensor):
            return traj * traj.new_tensor(self.std) + traj.new_tensor(self.mean)
        return as_coords(traj, self.action_dim, "traj") * self.std + self.mean

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        """``n`` chunks ``(n, horizon, 2)`` in env units, one latent ``z ~ N(0, I)`` from ``generator`` each."""
        if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 1:
            raise ValueError(f"n must be a positive int, got {n!r}")
        if generator is not None and not isinstance(generator, np.random.Generator):
            raise TypeError(f"generator must be a numpy Generator or None, got {type(generator).__name__}")
        rng = generator if generator is not None else np.random.default_rng()
        state = obs_history(obs, 1)[-1]
        z = rng.standard_normal((int(n), self.config.latent_dim), dtype=np.float32)
        with torch.no_grad():
            s = self.normalize(torch.from_numpy(state).to(self._device)).expand(int(n), -1)
            out = self.model.decode(s, torch.from_numpy(z).to(self._device))
            if self.config.relative:
                out = out + s[:, None]
            return self.unnormalize(out).cpu().numpy().astype(np.float64)

    # ------------------------------------------------------------ training
    @property
    def window_layout(self) -> dict[str, int]:
        """``PlanWindows`` arguments giving this policy's training pairs (LeRobot ACT layout)."""
        return {"n_obs": 1, "horizon": self.horizon, "action_start": 0}

    def loss(self, obs: torch.Tensor, plans: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """L1 + ``kl_weight`` x KL on a batch: ``obs (B, 1, 2)``, ``plans (B, chunk, 2)`` in env units."""
        b, d = plans.shape[0], self.action_dim
        if obs.shape != (b, 1, d) or plans.shape[1:] != (self.horizon, d):
            raise ValueError(
                f"expected obs (B, 1, {d}) and plans (B, {self.horizon}, {d}), "
                f"got {tuple(obs.shape)} and {tuple(plans.shape)}"
            )
        state = self.normalize(obs[:, -1].to(self._device, torch.float32))
        target = self.normalize(plans.to(self._device, torch.float32))
        if self.config.relative:
            target = target - state[:, None]
        mu, logvar = self.model.posterior(state, target)
        gen_device = generator.device if generator is not None else self._device
        eps = torch.randn(mu.shape, generator=generator, device=gen_device).to(self._device)
        z = mu + torch.exp(0.5 * logvar) * eps
        l1 = (self.model.decode(state, z) - target).abs().mean()
        kl = (-0.5 * (1 + logvar - mu.pow(2) - logvar.exp())).sum(-1).mean()
        return l1 + self.config.kl_weight * kl

    # --------------------------------------------------------- persistence
    def save(self, path: str | os.PathLike[str], extra: dict[str, Any] | None = None) -> Path:
        """Write weights, config and normalization stats to a ``.safetensors`` file atomically."""
        config = {
            "format": FORMAT,
            "model": self.config.to_dict(),
            "mean": self.mean.tolist(),
            "std": self.std.tolist(),
            "extra": dict(extra or {}),
        }
        return write_checkpoint(path, self.model.state_dict(), config)

    @classmethod
    def load(cls, path: str | os.PathLike[str], device: str | torch.device = "cpu") -> ACTPolicy:
        """A policy from a file written by :meth:`save` (safetensors: loading runs no code)."""
        tensors, config = read_checkpoint(path, FORMAT)
        policy = cls(ACTConfig(**config["model"]), config["mean"], config["std"], device=device)
        policy.model.load_state_dict(tensors)
        policy.model.to(policy.device).eval()
        policy.checkpoint_info = dict(config.get("extra", {}))
        return policy
