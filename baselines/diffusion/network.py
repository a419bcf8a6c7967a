"""The denoising network of :class:`~steer_envs.baselines.diffusion.DiffusionPolicy`: a FiLM-conditioned 1D U-Net.

Residual blocks of ``Conv1d -> GroupNorm -> SiLU`` whose features are
FiLM-modulated by the diffusion-step embedding and the global condition (the
normalized observation history, optionally through :class:`ObsEncoder`). Its
own module so that the policy, its ONNX export and the accelerated runners
all depend on it without depending on each other.

>>> from steer_envs.baselines.diffusion import DiffusionConfig
>>> net = DiffusionNet(DiffusionConfig(obs_dim=3, action_dim=2, horizon=8, down_dims=(8, 16)))
>>> net(torch.zeros(1, 8, 2), torch.zeros(1), torch.zeros(1, 6)).shape
torch.Size([1, 8, 2])
"""

from __future__ import annotations

import itertools
import math
from typing import cast

import torch
from diffusers.models.embeddings import get_timestep_embedding
from torch import nn

from steer_envs.baselines.diffusion.configuration import PlanNetConfig

__all__ = ["ConditionalUnet1D", "DiffusionNet", "ObsEncoder"]


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
        for level in self.down:
            res1, res2, downsample = cast(nn.ModuleList, level)
            h = res2(res1(h, cond), cond)
            skips.append(h)
            h = downsample(h)
        for res in self.mid:
            h = res(h, cond)
        for level in self.up:
            res1, res2, upsample = cast(nn.ModuleList, level)
            h = torch.cat([h, skips.pop()], dim=1)
            h = upsample(res2(res1(h, cond), cond))
        return self.final(h).transpose(1, 2)


class ObsEncoder(nn.Module):
    """Normalized observation history ``(B, c)`` -> ``(B, embed_dim)``: Fourier features + MLP.

    Raw inputs enter FiLM only linearly; sines and cosines at ``octaves``
    frequencies let a small network resolve fine spatial detail (e.g. walls
    close to the agent).
    """

    freqs: torch.Tensor

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

    ramp: torch.Tensor

    def __init__(self, cfg: PlanNetConfig) -> None:
        super().__init__()
        if cfg.obs_dim is None or cfg.action_dim is None:
            raise ValueError("DiffusionNet needs cfg.obs_dim and cfg.action_dim")
        cond_dim = cfg.n_obs_steps * cfg.obs_dim
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
        """Network output ``(B, T, action_dim)`` for noisy plans ``x``, steps ``timestep (B,)``, condition ``cond``."""
        if self.time_channel:
            x = torch.cat([x, self.ramp.expand(x.shape[0], -1, -1).to(x.dtype)], dim=-1)
        return self.unet(x, timestep, self.obs_encoder(cond))
