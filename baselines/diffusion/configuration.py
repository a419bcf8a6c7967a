"""Diffusion Policy's config and its training presets.

:class:`DiffusionConfig` holds the features (from the dataset), the plan
layout, the U-Net and the DDIM settings. :data:`PRESETS` are named
(config, training settings) pairs for :mod:`steer_envs.baselines.training`:

* ``cpu``: the network and optimizer of the shipped Maze2D checkpoint, sized
  for a CPU: v-prediction and plans relative to the current state (a small
  network's epsilon errors are amplified by ``1 / sqrt(abar)`` in the plan it
  implies at high noise), a plan-index channel and observation Fourier features.
* ``blockstack``: the shipped BlockStack skill policy: one whole pick-or-place
  skill per plan (32 waypoints of ``[x, y, z, gripper]``, one observation of
  the scene), absolute plans, DDIM with 100 steps as in the thesis.
* ``kitchen``: the Kitchen skill policy: the ``blockstack`` network and sampler
  on one door or bowl skill per plan (32 waypoints of ``[x, y, z, yaw, gripper]``).
* ``itps``: the public ITPS Maze2D config (Chi et al.'s U-Net at full width,
  epsilon prediction, absolute plans), a GPU job.

>>> cfg = DiffusionConfig(obs_dim=7, action_dim=4, horizon=16, down_dims=(8, 16))
>>> cfg.exec_start, cfg.window_layout
(1, {'n_obs': 2, 'horizon': 16, 'action_start': -1})
>>> sorted(PRESETS)
['blockstack', 'cpu', 'itps', 'kitchen']
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from steer_envs.baselines.common.configuration import PolicyConfig, Preset, TrainSettings, check_int, int_tuple
from steer_envs.core.validation import boolean, one_of, real_scalar

__all__ = [
    "BETA_SCHEDULES",
    "MAX_HORIZON",
    "MAX_TIMESTEPS",
    "PREDICTIONS",
    "PRESETS",
    "DiffusionConfig",
    "PlanNetConfig",
]

#: the network's target: the noise (Chi et al.) or the velocity v = sqrt(abar) eps - sqrt(1 - abar) x0.
PREDICTIONS = ("epsilon", "v")
#: the longest plan and the most diffusion steps a config may have (ITPS: 64 and 100)
MAX_HORIZON = 2**16
MAX_TIMESTEPS = 100_000
#: the noise schedules of diffusers' ``DDIMScheduler``.
BETA_SCHEDULES = ("linear", "scaled_linear", "squaredcos_cap_v2")


@dataclass(frozen=True, kw_only=True)
class PlanNetConfig(PolicyConfig):
    """Features, plan layout and U-Net of a policy that generates whole plans (DP, the flow policy).

    Plans use LeRobot's layout: ``horizon`` waypoints starting at the action of
    the oldest observed step, so ``plan[n_obs_steps - 1]`` is the current
    step's action and ``plan[exec_start:]`` is executed.

    Attributes:
        horizon: waypoints per plan (a multiple of ``2 ** (len(down_dims) - 1)``).
        n_obs_steps: observations of history in the condition.
        down_dims: U-Net channel widths per level.
        kernel_size, n_groups: convolution kernel (odd) and GroupNorm groups.
        step_embed_dim: noise-level embedding width (even).
        num_train_timesteps: noise levels: DDIM's diffusion steps; a flow's time ``tau``
            in ``[0, 1]`` enters the embedding as ``tau * num_train_timesteps``.
        num_inference_steps: DDIM steps, or a flow's Euler steps, per plan.
        time_channel: append the plan index (in [-1, 1]) as an input channel.
        obs_embed_dim: width of an MLP over Fourier features of the normalized
            observation history (0: the history enters FiLM directly).
        obs_octaves: Fourier frequencies ``pi * 2**k``, ``k < obs_octaves`` (at most 30).

    Bounds beyond those of :class:`PolicyConfig`: ``horizon`` at most
    :data:`MAX_HORIZON`, ``num_train_timesteps`` at most :data:`MAX_TIMESTEPS`,
    at most 32 U-Net levels (a loaded checkpoint is also limited by the network
    size its config implies).
    """

    horizon: int = 64
    n_obs_steps: int = 2
    down_dims: tuple[int, ...] = (16, 32, 64)
    kernel_size: int = 5
    n_groups: int = 8
    step_embed_dim: int = 64
    num_train_timesteps: int = 100
    num_inference_steps: int = 10
    time_channel: bool = True
    obs_embed_dim: int = 256
    obs_octaves: int = 6

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "down_dims", int_tuple(self.down_dims, "down_dims", 1))
        for name in ("horizon", "n_obs_steps", "kernel_size", "n_groups", "step_embed_dim", "num_train_timesteps"):
            object.__setattr__(self, name, check_int(getattr(self, name), name))
        for name, top in (("horizon", MAX_HORIZON), ("num_train_timesteps", MAX_TIMESTEPS)):
            if getattr(self, name) > top:
                raise ValueError(f"{name} must be <= {top}, got {getattr(self, name)}")
        object.__setattr__(self, "num_inference_steps", check_int(self.num_inference_steps, "num_inference_steps"))
        if not self.down_dims or any(d % self.n_groups for d in self.down_dims):
            raise ValueError(f"down_dims must be positive multiples of n_groups={self.n_groups}, got {self.down_dims}")
        if self.kernel_size % 2 == 0:
            raise ValueError(f"kernel_size must be odd, got {self.kernel_size}")
        if self.step_embed_dim % 2:
            raise ValueError(f"step_embed_dim must be even, got {self.step_embed_dim}")
        if len(self.down_dims) > 32:
            raise ValueError(f"down_dims may have at most 32 U-Net levels, got {len(self.down_dims)}")
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
        for name in ("obs_embed_dim", "obs_octaves"):
            object.__setattr__(self, name, check_int(getattr(self, name), name, 0))
        if self.obs_octaves > 30:
            raise ValueError(f"obs_octaves must be <= 30 (frequencies pi * 2**k), got {self.obs_octaves}")
        object.__setattr__(self, "time_channel", boolean(self.time_channel, "time_channel"))

    def parameter_count(self) -> int | None:
        """Numbers in the network's state dict, from the config alone (see :class:`DiffusionNet`).

        >>> PlanNetConfig(obs_dim=2, action_dim=2).parameter_count()
        707250
        """
        self.require_features()
        assert self.obs_dim is not None and self.action_dim is not None
        cond = self.n_obs_steps * self.obs_dim
        total = 0
        if self.obs_embed_dim:
            e = self.obs_embed_dim
            total += cond * (1 + 2 * self.obs_octaves) * e + e + 2 * (e * e + e)
            cond = e
        s, k = self.step_embed_dim, self.kernel_size
        total += s * 4 * s + 4 * s + 4 * s * s + s  # step MLP
        film_in = s + cond

        def block(a: int, b: int) -> int:  # two conv + GroupNorm blocks, FiLM, residual 1x1 conv
            return (a * b * k + b) + 2 * b + (b * b * k + b) + 2 * b + film_in * 2 * b + 2 * b + (a * b + b) * (a != b)

        dims = [self.action_dim + int(self.time_channel), *self.down_dims]
        levels = list(itertools.pairwise(dims))
        for i, (a, b) in enumerate(levels):
            total += block(a, b) + block(b, b) + (0 if i == len(levels) - 1 else b * b * 3 + b)
        total += 2 * block(self.down_dims[-1], self.down_dims[-1])
        for a, b in reversed(levels[1:]):
            total += block(2 * b, a) + block(a, a) + a * a * 4 + a
        d0 = self.down_dims[0]
        total += d0 * d0 * k + d0 + 2 * d0 + d0 * self.action_dim + self.action_dim
        return total

    @property
    def exec_start(self) -> int:
        """Index of the first executed waypoint: ``plan[:n_obs_steps - 1]`` re-states observed steps."""
        return self.n_obs_steps - 1

    @property
    def window_layout(self) -> dict[str, int]:
        """``PlanWindows`` arguments for this layout (plans start ``n_obs_steps - 1`` steps back)."""
        return {"n_obs": self.n_obs_steps, "horizon": self.horizon, "action_start": 1 - self.n_obs_steps}


@dataclass(frozen=True, kw_only=True)
class DiffusionConfig(PlanNetConfig):
    """:class:`PlanNetConfig` plus the DDIM sampler of a :class:`~steer_envs.baselines.diffusion.DiffusionPolicy`.

    Attributes:
        beta_schedule, clip_sample_range: the DDIM scheduler (diffusers ``DDIMScheduler``,
            ``num_train_timesteps`` steps; ``beta_schedule`` one of :data:`BETA_SCHEDULES`).
        prediction: the network's target, ``"epsilon"`` or ``"v"``; samplers
            always see epsilon (``predict_noise`` converts v exactly).
    """

    beta_schedule: str = "squaredcos_cap_v2"
    clip_sample_range: float = 1.0
    prediction: str = "v"

    def __post_init__(self) -> None:
        super().__post_init__()
        one_of(self.beta_schedule, "beta_schedule", BETA_SCHEDULES)
        one_of(self.prediction, "prediction", PREDICTIONS)
        clip = real_scalar(self.clip_sample_range, "clip_sample_range", low=0.0, low_inclusive=False)
        object.__setattr__(self, "clip_sample_range", clip)


#: the optimizer of Diffusion Policy / ITPS (betas, weight decay); the cpu preset raises the learning rate.
_DP_TRAIN = TrainSettings(lr=2e-3, weight_decay=1e-6, betas=(0.95, 0.999), static_history_prob=0.2)

#: the shipped skill policies (BlockStack, Kitchen): one whole skill per plan of 32 waypoints, DDIM with 100 steps
_SKILL_PLANS = DiffusionConfig(
    horizon=32, n_obs_steps=1, down_dims=(32, 64, 128), num_inference_steps=100, relative=False
)
_SKILL_PLANS_TRAIN = _DP_TRAIN.replace(steps=30_000, lr=1e-3)

#: named (config, training) presets; the feature fields are taken from the dataset.
PRESETS: dict[str, Preset[DiffusionConfig]] = {
    "cpu": Preset(
        DiffusionConfig(relative=True, down_dims=(32, 64, 128)),
        _DP_TRAIN.replace(steps=40_000, batch_size=256),
        "the shipped Maze2D checkpoint: a 1.7M-parameter U-Net, v target, plans relative to the agent, "
        "40k steps at batch 256 (10.2M samples)",
    ),
    "blockstack": Preset(
        _SKILL_PLANS,
        _SKILL_PLANS_TRAIN,
        "the shipped BlockStack checkpoint: one pick-or-place skill per plan (32 waypoints x [x, y, z, "
        "gripper], steer_envs.data.blockstack_plans), DDIM with 100 steps as in the thesis",
    ),
    "kitchen": Preset(
        _SKILL_PLANS,
        _SKILL_PLANS_TRAIN,
        "the shipped Kitchen skill policy: one door or bowl skill per plan (32 waypoints x [x, y, z, yaw, "
        "gripper], steer_envs.data.kitchen_plans) from the microwave and sink demos merged, DDIM with 100 steps",
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
