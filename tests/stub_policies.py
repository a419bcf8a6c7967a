"""Stand-in policies the steering, wrapper and policy-contract tests share: no trained network, known plans."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch


class StraightLine:
    """A non-diffusion TrajectoryPolicy: 8 waypoints from the agent's xy straight to (1, 1), every sample alike."""

    horizon, action_dim = 8, 2

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        path = np.linspace(np.asarray(obs, dtype=np.float64)[:2], [1.0, 1.0], self.horizon)
        return np.repeat(path[None], n, axis=0)


class RandomLines:
    """A non-diffusion TrajectoryPolicy: straight lines from the agent's xy in random headings, waypoints ``step``
    apart."""

    horizon = 8
    action_dim = 2

    def __init__(self, step: float = 0.3) -> None:
        self.step = step

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        rng = generator if generator is not None else np.random.default_rng()
        heading = rng.uniform(0, 2 * np.pi, size=(n, 1))
        direction = np.concatenate([np.cos(heading), np.sin(heading)], axis=1)[:, None, :]
        xy = np.asarray(obs, dtype=np.float64).reshape(-1)[:2]
        return xy + np.arange(1, self.horizon + 1)[None, :, None] * self.step * direction


class ExactDiffusion:
    """DDIM sampling of a diffusion stand-in whose noise prediction is exact (a known distribution of plans).

    Subclasses give ``horizon``, ``action_dim``, ``scheduler``, ``encode_obs``,
    ``predict_noise`` and ``unnormalize``; plans start from the generator's
    standard normal noise in :attr:`dtype`.
    """

    num_inference_steps = 10
    device = torch.device("cpu")
    dtype = torch.float64
    horizon: int
    action_dim: int
    scheduler: Any

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        rng = generator if generator is not None else np.random.default_rng()
        cond = self.encode_obs(obs)
        np_dtype = np.float32 if self.dtype == torch.float32 else np.float64
        x = torch.as_tensor(rng.standard_normal((n, self.horizon, self.action_dim), dtype=np_dtype), dtype=self.dtype)
        self.scheduler.set_timesteps(self.num_inference_steps)
        for t in self.scheduler.timesteps:
            x = self.scheduler.step(self.predict_noise(x, t, cond), t, x).prev_sample
        return self.unnormalize(x).numpy()

    def encode_obs(self, obs: Any) -> torch.Tensor:
        raise NotImplementedError

    def predict_noise(self, x_t: torch.Tensor, t: Any, cond: torch.Tensor) -> torch.Tensor:
        raise NotImplementedError

    def unnormalize(self, traj: Any) -> Any:
        raise NotImplementedError
