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


class LineModes:
    """The modes of the mixture test doubles: straight-line plans from the agent's xy in ``K`` headings.

    Mode ``k`` is ``xy + s * length * u_k`` at ``s = 1/steps, 2/steps, ..., 1``
    (heading ``u_k`` at ``angles_deg[k]``, ``steps`` the ``horizon`` given); plans are normalized min-max to
    ``[-1, 1]`` over the box ``low``..``high``. The policy's condition is its
    modes, normalized (:meth:`encode_obs`); ``std`` is the modes' spread.
    """

    def __init__(
        self,
        angles_deg: tuple[float, ...] = (0.0, 90.0, 180.0, 270.0),
        *,
        horizon: int = 16,
        length: float = 3.0,
        std: float = 0.02,
        low: tuple[float, float] = (-5.0, -5.0),
        high: tuple[float, float] = (5.0, 5.0),
    ) -> None:
        a = np.deg2rad(np.asarray(angles_deg, dtype=np.float64))
        self.dirs = np.stack([np.cos(a), np.sin(a)], axis=1)
        self.horizon = self.steps = horizon  # a subclass may plan fewer states than its modes have
        self.length, self.std = length, std
        self.low, self.high = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)

    def modes(self, xy: Any) -> np.ndarray:
        """The ``(K, steps, 2)`` mode plans from ``xy`` (env units)."""
        steps = np.linspace(1.0 / self.steps, 1.0, self.steps)[None, :, None] * self.length
        return np.asarray(xy, dtype=np.float64)[None, None, :2] + steps * self.dirs[:, None, :]

    def encode_obs(self, obs: Any) -> torch.Tensor:
        arr = np.asarray(obs, dtype=np.float64)
        return torch.as_tensor(self.normalize(self.modes(arr.reshape(-1, arr.shape[-1])[-1, :2])))

    def normalize(self, traj: Any) -> Any:
        lo, hi = (torch.as_tensor(v) for v in (self.low, self.high)) if torch.is_tensor(traj) else (self.low, self.high)
        return 2 * (traj - lo) / (hi - lo) - 1

    def unnormalize(self, traj: Any) -> Any:
        lo, hi = (torch.as_tensor(v) for v in (self.low, self.high)) if torch.is_tensor(traj) else (self.low, self.high)
        return (traj + 1) / 2 * (hi - lo) + lo

    def off_manifold(self, plans: np.ndarray, obs: Any) -> np.ndarray:
        """Mean per-step distance of every plan to its nearest mode (env units)."""
        return np.linalg.norm(plans[:, None] - self.modes(obs)[None], axis=-1).mean(-1).min(axis=1)


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


class Corridor(ExactDiffusion):
    """Exact diffusion policy whose plans are straight lines ``length`` long from the agent along +-row / +-column.

    Normalization maps the Maze2D large map's cell range to [-1, 1]; ``std`` is
    the plans' spread. ``n_obs_steps = 2`` and ``exec_start = 1`` mimic
    LeRobot's DP (``plan[0]`` restates the position). Needs diffusers.
    """

    action_dim = 2
    n_obs_steps = 2
    exec_start = 1

    def __init__(self, horizon: int = 12, length: float = 2.2, std: float = 0.01) -> None:
        import diffusers

        self.scheduler = diffusers.DDIMScheduler(
            num_train_timesteps=100, beta_schedule="squaredcos_cap_v2", clip_sample=True
        )
        self.dirs = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
        self.horizon, self.length, self.std = horizon, length, std
        self.low, self.high = np.array([0.0, 0.0]), np.array([8.0, 11.0])

    def encode_obs(self, obs: Any) -> torch.Tensor:
        xy = np.asarray(obs, dtype=np.float64).reshape(-1, np.shape(obs)[-1])[-1, :2]
        steps = np.linspace(0.0, 1.0, self.horizon)[None, :, None] * self.length
        return torch.as_tensor(self.normalize(xy[None, None] + steps * self.dirs[:, None, :]))

    def predict_noise(self, x_t: torch.Tensor, t: Any, cond: torch.Tensor) -> torch.Tensor:
        abar = self.scheduler.alphas_cumprod[int(t)].to(torch.float64)
        var = abar * self.std**2 + 1 - abar
        diff = x_t.to(torch.float64)[:, None] - abar.sqrt() * cond[None]
        logw = -(diff**2).sum((-1, -2)) / (2 * var)
        weights = (logw - logw.logsumexp(dim=1, keepdim=True)).exp()[:, :, None, None]
        return (1 - abar).sqrt() * (weights * diff).sum(1) / var

    def normalize(self, traj: Any) -> Any:
        return 2 * (traj - self.low) / (self.high - self.low) - 1

    def unnormalize(self, traj: Any) -> Any:
        lo, hi = (
            (torch.as_tensor(self.low), torch.as_tensor(self.high)) if torch.is_tensor(traj) else (self.low, self.high)
        )
        return (traj + 1) / 2 * (hi - lo) + lo
