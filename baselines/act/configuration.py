"""ACT's config and its training presets.

:class:`ACTConfig` holds the features (from the dataset), the chunk length,
the transformer sizes and the CVAE loss weight. :data:`PRESETS`:

* ``cpu``: the shipped Maze2D checkpoint (d_model 128, 2/1/1 layers), sized for a CPU.
* ``itps``: the public ITPS Maze2D config (d_model 512, 8 heads, 4/1/4 layers), a GPU job.

>>> cfg = ACTConfig(obs_dim=7, action_dim=4, chunk_size=16)
>>> cfg.horizon, cfg.window_layout
(16, {'n_obs': 1, 'horizon': 16, 'action_start': 0})
"""

from __future__ import annotations

from dataclasses import dataclass

from steer_envs.baselines.common.configuration import PolicyConfig, Preset, TrainSettings, check_int
from steer_envs.core.validation import real_scalar

__all__ = ["MAX_CHUNK", "MAX_LAYERS", "PRESETS", "ACTConfig"]

#: the most transformer layers of each stack, and the longest chunk
MAX_LAYERS = 256
MAX_CHUNK = 2**16


@dataclass(frozen=True, kw_only=True)
class ACTConfig(PolicyConfig):
    """Features, chunk and networks of an :class:`~steer_envs.baselines.act.ACTPolicy`.

    ACT conditions on the current observation only and predicts the next
    ``chunk_size`` actions (all executed). Observations and actions are
    standardized (``normalization="mean_std"``) by default, as in ACT.

    Attributes:
        chunk_size: actions per chunk (the plan horizon).
        d_model, n_heads, dim_feedforward: transformer width, heads, FFN width.
        n_encoder_layers, n_decoder_layers, n_vae_encoder_layers: layer counts.
        latent_dim: size of the CVAE latent ``z``.
        dropout: transformer dropout.
        kl_weight: weight of KL(q(z | s, a) || N(0, I)) in the loss.

    Bounds beyond those of :class:`PolicyConfig`: at most :data:`MAX_LAYERS`
    layers per stack and a ``chunk_size`` of at most :data:`MAX_CHUNK`.
    """

    normalization: str = "mean_std"
    chunk_size: int = 64
    d_model: int = 128
    n_heads: int = 4
    dim_feedforward: int = 256
    n_encoder_layers: int = 2
    n_decoder_layers: int = 1
    n_vae_encoder_layers: int = 1
    latent_dim: int = 32
    dropout: float = 0.1
    kl_weight: float = 10.0

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in (
            "chunk_size",
            "d_model",
            "n_heads",
            "dim_feedforward",
            "n_encoder_layers",
            "n_decoder_layers",
            "n_vae_encoder_layers",
            "latent_dim",
        ):
            object.__setattr__(self, name, check_int(getattr(self, name), name))
        for name in ("n_encoder_layers", "n_decoder_layers", "n_vae_encoder_layers"):
            if getattr(self, name) > MAX_LAYERS:
                raise ValueError(f"{name} must be <= {MAX_LAYERS}, got {getattr(self, name)}")
        if self.chunk_size > MAX_CHUNK:
            raise ValueError(f"chunk_size must be <= {MAX_CHUNK}, got {self.chunk_size}")
        if self.d_model % self.n_heads:
            raise ValueError(f"d_model ({self.d_model}) must be a multiple of n_heads ({self.n_heads})")
        if self.d_model % 2:
            raise ValueError(f"d_model must be even (sinusoidal positions), got {self.d_model}")
        dropout = real_scalar(self.dropout, "dropout", low=0.0, high=1.0, high_inclusive=False)
        object.__setattr__(self, "dropout", dropout)
        object.__setattr__(self, "kl_weight", real_scalar(self.kl_weight, "kl_weight", low=0.0))

    def parameter_count(self) -> int | None:
        """Numbers in the network's state dict, from the config alone (see :class:`ACTModel`).

        >>> ACTConfig(obs_dim=2, action_dim=2).parameter_count()
        618690
        """
        self.require_features()
        assert self.obs_dim is not None and self.action_dim is not None
        d, ff, lat = self.d_model, self.dim_feedforward, self.latent_dim
        attention = 4 * d * d + 4 * d
        feedforward = 2 * d * ff + ff + d
        encoder_layer = attention + feedforward + 4 * d
        decoder_layer = 2 * attention + feedforward + 6 * d
        total = d + (self.obs_dim * d + d) + (self.action_dim * d + d)  # CLS token, VAE input projections
        total += self.n_vae_encoder_layers * encoder_layer + d * 2 * lat + 2 * lat
        total += (lat * d + d) + (self.obs_dim * d + d) + 2 * d  # latent / state projections, positions
        total += self.n_encoder_layers * encoder_layer + self.chunk_size * d
        total += self.n_decoder_layers * decoder_layer + d * self.action_dim + self.action_dim
        return total

    @property
    def horizon(self) -> int:
        """Waypoints per plan (the chunk size)."""
        return self.chunk_size

    @property
    def n_obs_steps(self) -> int:
        """ACT conditions on the current observation only."""
        return 1

    @property
    def exec_start(self) -> int:
        """Every waypoint of a chunk is executed."""
        return 0

    @property
    def window_layout(self) -> dict[str, int]:
        """``PlanWindows`` arguments: the current observation and the next ``chunk_size`` actions."""
        return {"n_obs": 1, "horizon": self.chunk_size, "action_start": 0}


_ACT_TRAIN = TrainSettings(lr=3e-4, weight_decay=1e-4, betas=(0.9, 0.999))

#: named (config, training) presets; the feature fields are taken from the dataset.
PRESETS: dict[str, Preset[ACTConfig]] = {
    "cpu": Preset(
        ACTConfig(),
        _ACT_TRAIN.replace(steps=3_000),
        "the shipped Maze2D checkpoint: d_model 128, 2 encoder / 1 decoder / 1 VAE-encoder layers",
    ),
    "itps": Preset(
        ACTConfig(
            d_model=512,
            n_heads=8,
            dim_feedforward=3200,
            n_encoder_layers=4,
            n_decoder_layers=1,
            n_vae_encoder_layers=4,
        ),
        _ACT_TRAIN.replace(steps=100_000, batch_size=256, lr=1e-5),
        "ITPS's Maze2D ACT at full size (a GPU job)",
    ),
}
