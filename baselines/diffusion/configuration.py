"""Diffusion Policy's config and its training presets.

:class:`DiffusionConfig` holds the features (from the dataset), the plan
layout, the U-Net and the DDIM settings. :data:`PRESETS` are named
(config, training settings) pairs for :mod:`steer_envs.baselines.training`:

* ``cpu``: the network and optimizer of the shipped Maze2D checkpoint, sized
  for a CPU: v-prediction and plans relative to the current state (a small
  network's epsilon errors are amplified by ``1 / sqrt(abar)`` in the plan it
  implies at high noise), a plan-index channel and observation Fourier features.
* ``itps``: the public ITPS Maze2D config (Chi et al.'s U-Net at full width,
  epsilon prediction, absolute plans), a GPU job.

>>> cfg = DiffusionConfig(obs_dim=7, action_dim=4, horizon=16, down_dims=(8, 16))
>>> cfg.exec_start, cfg.window_layout
(1, {'n_obs': 2, 'horizon': 16, 'action_start': -1})
>>> sorted(PRESETS)
['cpu', 'itps']
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from steer_envs.baselines.common.configuration import PolicyConfig, Preset, TrainSettings, check_int

__all__ = ["PREDICTIONS", "PRESETS", "DiffusionConfig"]

#: the network's target: the noise (Chi et al.) or the velocity v = sqrt(abar) eps - sqrt(1 - abar) x0.
PREDICTIONS = ("epsilon", "v")


@dataclass(frozen=True, kw_only=True)
class DiffusionConfig(PolicyConfig):
    """Features, plan layout, network and sampler of a :class:`~steer_envs.baselines.diffusion.DiffusionPolicy`.

    Plans use LeRobot's layout: ``horizon`` waypoints starting at the action of
    the oldest observed step, so ``plan[n_obs_steps - 1]`` is the current
    step's action and ``plan[exec_start:]`` is executed.

    Attributes:
        horizon: waypoints per plan (a multiple of ``2 ** (len(down_dims) - 1)``).
        n_obs_steps: observations of history in the condition.
        down_dims: U-Net channel widths per level.
        kernel_size, n_groups: convolution kernel (odd) and GroupNorm groups.
        step_embed_dim: diffusion-step embedding width (even).
        num_train_timesteps, num_inference_steps, beta_schedule, clip_sample_range:
            the DDIM scheduler (diffusers ``DDIMScheduler``).
        prediction: the network's target, ``"epsilon"`` or ``"v"``; samplers
            always see epsilon (``predict_noise`` converts v exactly).
        time_channel: append the plan index (in [-1, 1]) as an input channel.
        obs_embed_dim: width of an MLP over Fourier features of the normalized
            observation history (0: the history enters FiLM directly).
        obs_octaves: Fourier frequencies ``pi * 2**k``, ``k < obs_octaves``.
    """

    horizon: int = 64
    n_obs_steps: int = 2
    down_dims: tuple[int, ...] = (16, 32, 64)
    kernel_size: int = 5
    n_groups: int = 8
    step_embed_dim: int = 64
    num_train_timesteps: int = 100
    num_inference_steps: int = 10
    beta_schedule: str = "squaredcos_cap_v2"
    clip_sample_range: float = 1.0
    prediction: str = "v"
    time_channel: bool = True
    obs_embed_dim: int = 256
    obs_octaves: int = 6

    def __post_init__(self) -> None:
        super().__post_init__()
        try:
            object.__setattr__(self, "down_dims", tuple(int(d) for d in self.down_dims))
        except (TypeError, ValueError):
            raise TypeError(f"down_dims must be a sequence of ints, got {self.down_dims!r}") from None
        for name in ("horizon", "n_obs_steps", "kernel_size", "n_groups", "step_embed_dim", "num_train_timesteps"):
            check_int(getattr(self, name), name)
        if not self.down_dims or any(d < 1 or d % self.n_groups for d in self.down_dims):
            raise ValueError(f"down_dims must be positive multiples of n_groups={self.n_groups}, got {self.down_dims}")
        if self.kernel_size % 2 == 0:
            raise ValueError(f"kernel_size must be odd, got {self.kernel_size}")
        if self.step_embed_dim % 2:
            raise ValueError(f"step_embed_dim must be even, got {self.step_embed_dim}")
        stride = 2 ** (len(self.down_dims) - 1)
        if self.horizon % stride:
            raise ValueError(
                f"horizon must be a multiple of {stride} for {len(self.down_dims)} U-Net levels, got {self.horizon}"
            )
        if not 1 <= self.num_inference_steps <= self.num_train_timesteps:
            raise ValueError(
                f"num_inference_steps must be in [1, num_train_timesteps={self.num_train_timesteps}], "
                f"got {self.num_inference_steps}"
            )
        if self.prediction not in PREDICTIONS:
            raise ValueError(f"prediction must be one of {PREDICTIONS}, got {self.prediction!r}")
        for name in ("obs_embed_dim", "obs_octaves"):
            check_int(getattr(self, name), name, 0)
        if not (np.isfinite(self.clip_sample_range) and self.clip_sample_range > 0):
            raise ValueError(f"clip_sample_range must be a positive float, got {self.clip_sample_range!r}")
        if not isinstance(self.time_channel, bool):
            raise TypeError(f"time_channel must be a bool, got {type(self.time_channel).__name__}")

    @property
    def exec_start(self) -> int:
        """Index of the first executed waypoint: ``plan[:n_obs_steps - 1]`` re-states observed steps."""
        return self.n_obs_steps - 1

    @property
    def window_layout(self) -> dict[str, int]:
        """``PlanWindows`` arguments for this layout (plans start ``n_obs_steps - 1`` steps back)."""
        return {"n_obs": self.n_obs_steps, "horizon": self.horizon, "action_start": 1 - self.n_obs_steps}


#: the optimizer of Diffusion Policy / ITPS (betas, weight decay); the cpu preset raises the learning rate.
_DP_TRAIN = TrainSettings(lr=2e-3, weight_decay=1e-6, betas=(0.95, 0.999), static_history_prob=0.2)

#: named (config, training) presets; the feature fields are taken from the dataset.
PRESETS: dict[str, Preset[DiffusionConfig]] = {
    "cpu": Preset(
        DiffusionConfig(relative=True),
        _DP_TRAIN.replace(steps=30_000),
        "the shipped Maze2D checkpoint: a 0.7M-parameter U-Net, v target, plans relative to the agent",
    ),
    "itps": Preset(
        DiffusionConfig(
            down_dims=(128, 256, 512),
            step_embed_dim=128,
            prediction="epsilon",
            relative=False,
            time_channel=False,
            obs_embed_dim=0,
        ),
        _DP_TRAIN.replace(steps=100_000, batch_size=256, lr=1e-4, warmup_steps=500),
        "ITPS's Maze2D Diffusion Policy at full size (about 16M parameters; a GPU job)",
    ),
}
