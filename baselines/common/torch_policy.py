"""Shared plumbing of the chunked trajectory policies (DP, ACT): the seeded network, observation histories, checkpoints.

A checkpoint is one safetensors file: the weights plus a JSON config in the
header's ``__metadata__`` (safetensors executes no code on load, unlike a
pickle). It is written atomically through :mod:`steer_envs.io`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, Self

import numpy as np
import torch
from safetensors.torch import load as st_load
from safetensors.torch import save as st_save

from steer_envs.io import atomic_write_bytes

__all__ = ["TorchPolicy", "as_coords", "obs_history", "read_checkpoint", "write_checkpoint"]


class TorchPolicy:
    """What DP and ACT share: a network built under a fixed seed, on a device, in eval mode.

    The network is built inside ``torch.random.fork_rng`` so the caller's RNG
    state is left alone and the same seed gives the same initial weights.
    """

    model: torch.nn.Module
    _device: torch.device

    def _init_network(self, build: Callable[[], torch.nn.Module], seed: Any, device: str | torch.device) -> None:
        if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
            raise ValueError(f"seed must be a non-negative int, got {seed!r}")
        self._device = torch.device(device)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(int(seed))
            self.model = build()
        self.model.to(self._device).eval()

    @property
    def device(self) -> torch.device:
        return self._device

    def to(self, device: str | torch.device) -> Self:
        """Move the network (and any other device-bound state, :meth:`_moved`) to ``device``; returns self."""
        self._device = torch.device(device)
        self.model.to(self._device)
        self._moved()
        return self

    def _moved(self) -> None:
        """Hook for subclasses with tensors besides the network (called by :meth:`to`)."""

    def num_parameters(self) -> int:
        """Trainable parameters of the network."""
        return sum(p.numel() for p in self.model.parameters())


def obs_history(obs: Any, n_obs: int) -> np.ndarray:
    """The last ``n_obs`` agent positions ``(n_obs, 2)`` float32 from an env observation.

    Accepts one observation ``(2,)`` (xy) or ``(4,)`` (xy + velocity), or a
    history ``(k, 2)`` / ``(k, 4)`` oldest first. A history shorter than
    ``n_obs`` is padded by repeating its oldest entry, as LeRobot fills its
    observation queue after a reset (a single observation = an agent at rest).
    """
    try:
        arr = np.asarray(obs, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"obs must be an array of xy positions, got {type(obs).__name__}") from None
    if arr.ndim == 1:
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[0] < 1 or arr.shape[1] not in (2, 4):
        raise ValueError(f"obs must have shape (2,), (4,), (k, 2) or (k, 4), got {np.shape(obs)}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("obs must be finite")
    xy = arr[-n_obs:, :2]
    if len(xy) < n_obs:
        xy = np.concatenate([np.repeat(xy[:1], n_obs - len(xy), axis=0), xy])
    return xy.astype(np.float32)


def as_coords(value: Any, d: int, name: str) -> np.ndarray:
    """``value`` as a float64 array of ``d``-dimensional points ``(..., d)``; raises naming ``name``."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a numeric array or torch tensor, got {type(value).__name__}") from None
    if arr.ndim == 0 or arr.shape[-1] != d:
        raise ValueError(f"{name} must have shape (..., {d}), got {arr.shape}")
    return arr


def write_checkpoint(path: str | os.PathLike[str], tensors: dict[str, torch.Tensor], config: dict[str, Any]) -> Path:
    """Write ``tensors`` with ``config`` (JSON-serializable) as a safetensors file, atomically."""
    out = Path(path)
    if out.suffix != ".safetensors":
        raise ValueError(f"path must end with .safetensors, got {str(out)!r}")
    data = st_save(
        {k: v.detach().to("cpu").contiguous() for k, v in tensors.items()},
        metadata={"config": json.dumps(config)},
    )
    atomic_write_bytes(out, data)
    return out


def read_checkpoint(path: str | os.PathLike[str], fmt: str) -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
    """Tensors and config of a file written by :func:`write_checkpoint`; its config must carry ``format == fmt``."""
    src = Path(path)
    if not src.is_file():
        raise ValueError(f"no checkpoint file at {str(src)!r}")
    raw = src.read_bytes()
    try:
        n = int.from_bytes(raw[:8], "little")
        header = json.loads(raw[8 : 8 + n])
        config = json.loads(header["__metadata__"]["config"])
    except (ValueError, KeyError, TypeError):
        raise ValueError(f"{src} is not a steer-envs safetensors checkpoint (no config metadata)") from None
    if not isinstance(config, dict) or config.get("format") != fmt:
        found = config.get("format") if isinstance(config, dict) else None
        raise ValueError(f"{src} holds format {found!r}, expected {fmt!r}")
    return st_load(raw), config
