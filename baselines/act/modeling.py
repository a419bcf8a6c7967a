"""ACT, the action-chunking transformer (Zhao et al. 2023): a conditional VAE over action chunks.

Training: a transformer *VAE encoder* reads ``[CLS, observation, action
chunk]`` and outputs the posterior ``q(z | s, a)``; the *policy* is a
transformer encoder over ``[z, observation]`` tokens and a transformer decoder
whose ``chunk_size`` learned queries cross-attend to it and regress the chunk.
Loss: L1 on the normalized chunk + ``kl_weight`` x KL(q || N(0, I)). At
inference the latent is drawn from N(0, I) (as ITPS does) instead of ACT's
``z = 0``, so a batch of plans comes out. :class:`ACTPolicy` satisfies
:class:`steer_envs.core.TrajectoryPolicy` (it has no denoiser to steer).

>>> import numpy as np
>>> cfg = ACTConfig(obs_dim=7, action_dim=4, chunk_size=8, d_model=16, n_heads=2, dim_feedforward=16)
>>> ACTPolicy(cfg).sample(np.zeros(7), 3, generator=np.random.default_rng(0)).shape
(3, 8, 4)
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from torch import nn

from steer_envs.baselines.act.configuration import ACTConfig
from steer_envs.baselines.common.torch_policy import TorchPolicy

__all__ = ["ACTModel", "ACTPolicy"]

#: the checkpoint format written before the policy factory (still readable).
LEGACY_FORMAT = "steer_envs.baselines.act/1"


def _sinusoid(n: int, d: int) -> torch.Tensor:
    """Fixed sinusoidal position table ``(n, d)`` (Transformer / ACT VAE encoder)."""
    pos = torch.arange(n, dtype=torch.float32)[:, None]
    freq = torch.exp(-np.log(10000.0) * torch.arange(0, d, 2, dtype=torch.float32) / d)
    table = torch.zeros(n, d)
    table[:, 0::2], table[:, 1::2] = torch.sin(pos * freq), torch.cos(pos * freq)
    return table


class ACTModel(nn.Module):
    """The CVAE networks: :meth:`posterior` (training only) and :meth:`decode` (the policy)."""

    vae_pos: torch.Tensor

    def __init__(self, cfg: ACTConfig) -> None:
        super().__init__()
        if cfg.obs_dim is None or cfg.action_dim is None:
            raise ValueError("ACTModel needs cfg.obs_dim and cfg.action_dim")
        d = cfg.d_model
        self.cfg = cfg

        def encoder(layers: int) -> nn.TransformerEncoder:
            layer = nn.TransformerEncoderLayer(d, cfg.n_heads, cfg.dim_feedforward, cfg.dropout, batch_first=True)
            return nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)

        # VAE encoder q(z | state, chunk)
        self.vae_cls = nn.Parameter(torch.zeros(1, 1, d))
        self.vae_state_proj = nn.Linear(cfg.obs_dim, d)
        self.vae_action_proj = nn.Linear(cfg.action_dim, d)
        self.vae_encoder = encoder(cfg.n_vae_encoder_layers)
        self.vae_out = nn.Linear(d, 2 * cfg.latent_dim)
        self.register_buffer("vae_pos", _sinusoid(cfg.chunk_size + 2, d)[None], persistent=False)
        # policy: encoder over [z, state], decoder with chunk_size learned queries
        self.latent_proj = nn.Linear(cfg.latent_dim, d)
        self.state_proj = nn.Linear(cfg.obs_dim, d)
        self.enc_pos = nn.Parameter(torch.zeros(1, 2, d))
        self.encoder = encoder(cfg.n_encoder_layers)
        self.queries = nn.Parameter(torch.zeros(1, cfg.chunk_size, d))
        layer = nn.TransformerDecoderLayer(d, cfg.n_heads, cfg.dim_feedforward, cfg.dropout, batch_first=True)
        self.decoder = nn.TransformerDecoder(layer, cfg.n_decoder_layers)
        self.head = nn.Linear(d, cfg.action_dim)
        for p in (self.vae_cls, self.enc_pos, self.queries):
            nn.init.normal_(p, std=0.02)

    def posterior(self, state: torch.Tensor, actions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``mu, logvar`` ``(B, latent)`` of q(z | observation ``(B, s)``, actions ``(B, chunk, a)``)."""
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
    """Current observation -> batch of action chunks, one latent ``z ~ N(0, I)`` per plan (a ``TrajectoryPolicy``).

    Args:
        config: an :class:`ACTConfig` with its features set.
        stats: normalization statistics ``{"observation": ..., "action": ...}``
            (e.g. ``dataset.stats()``); ``None``: data already normalized.
        seed: seed of the initial weights.
        device: torch device of the network.

    >>> import numpy as np
    >>> cfg = ACTConfig(obs_dim=2, action_dim=2, chunk_size=4, d_model=8, n_heads=1, dim_feedforward=8)
    >>> moments = {"mean": [1.0, 1.0], "std": [2.0, 2.0]}
    >>> policy = ACTPolicy(cfg, {"observation": moments, "action": moments})
    >>> policy.normalize(np.array([[3.0, 1.0]])).tolist()
    [[1.0, 0.0]]
    """

    name = "act"
    config_class = ACTConfig
    legacy_format = LEGACY_FORMAT
    config: ACTConfig
    model: ACTModel

    def _build_model(self) -> nn.Module:
        return ACTModel(self.config)

    def _anchor(self, state: torch.Tensor) -> torch.Tensor:
        """The normalized current values of ``action_obs_indices``, ``(B, 1, action_dim)`` (``relative``)."""
        assert self.config.action_obs_indices is not None
        return state[:, None, list(self.config.action_obs_indices)]

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        """``n`` chunks ``(n, horizon, action_dim)`` in data units, one latent ``z ~ N(0, I)`` each from ``generator``.

        ``obs`` is the env observation (or a history, of which the last entry counts): finite
        real numbers (see :func:`~steer_envs.baselines.common.torch_policy.observation_history`);
        ``n`` an int in ``[1, max_samples]``; ``generator`` a numpy ``Generator`` or ``None``.
        """
        rng = self._sample_args(n, generator)
        state = self.observation_history(obs)[-1]
        z = rng.standard_normal((int(n), self.config.latent_dim), dtype=np.float32)
        with torch.no_grad():
            s = self.obs_normalizer.normalize(torch.from_numpy(state).to(self._device)).expand(int(n), -1)
            out = self.model.decode(s, torch.from_numpy(z).to(self._device))
            if self.config.relative:
                out = out + self._anchor(s)
            return self.unnormalize(out).cpu().numpy().astype(np.float64)

    # ------------------------------------------------------------ training
    def loss(self, obs: torch.Tensor, plans: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """L1 + ``kl_weight`` x KL on a batch: ``obs (B, 1, obs_dim)``, ``plans (B, chunk, action_dim)``.

        Both real finite tensors; ``generator`` a ``torch.Generator`` or ``None``.
        """
        self._check_batch(obs, plans, generator)
        state = self.obs_normalizer.normalize(obs[:, -1].to(self._device, torch.float32))
        target = self.normalize(plans.to(self._device, torch.float32))
        if self.config.relative:
            target = target - self._anchor(state)
        mu, logvar = self.model.posterior(state, target)
        gen_device = generator.device if generator is not None else self._device
        eps = torch.randn(mu.shape, generator=generator, device=gen_device).to(self._device)
        z = mu + torch.exp(0.5 * logvar) * eps
        l1 = (self.model.decode(state, z) - target).abs().mean()
        kl = (-0.5 * (1 + logvar - mu.pow(2) - logvar.exp())).sum(-1).mean()
        return l1 + self.config.kl_weight * kl

    # --------------------------------------------------------- persistence
    @classmethod
    def upgrade_legacy_config(cls, values: Mapping[str, Any]) -> ACTConfig:
        """The config of a pre-factory ACT (2-D positions; observation = the xy of the env observation)."""
        old = dict(values)
        d = int(old.pop("state_dim", old.get("action_dim", 2)))
        return ACTConfig.from_dict(
            {
                **old,
                "obs_dim": d,
                "normalization": "mean_std",
                "obs_indices": list(range(d)),
                "action_obs_indices": list(range(int(old.get("action_dim", d)))),
            }
        )

    @classmethod
    def upgrade_legacy(cls, header: Mapping[str, Any]) -> tuple[ACTConfig, dict[str, Any]]:
        """Config and statistics of a pre-factory checkpoint (one mean/std for positions and chunks)."""
        moments = {"mean": header["mean"], "std": header["std"]}
        return cls.upgrade_legacy_config(header["model"]), {"observation": moments, "action": moments}
