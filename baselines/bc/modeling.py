"""The thesis's behaviour-cloning velocity policy (TLI appendix "BC Policy Architecture").

An MLP ``d -> 100 -> 100 -> d`` with ReLU hidden layers and a ``tanh`` output
scaled to ``[-50, 50]``, trained on i.i.d. (state, velocity) pairs with Adam
(lr 1e-3, batch 512) on the mean squared error. Unlike :class:`LPVDS` it has
no stability guarantee: that contrast is the point of the single-mode study.

Training runs on the CPU and is deterministic for a given ``seed`` (its own
``torch.Generator`` for the initial weights and the batch order; no global
RNG is touched). Checkpoints are safetensors files, written atomically.
"""

from __future__ import annotations

import itertools
import json
import os
import tempfile
from pathlib import Path

import numpy as np
import torch
from numpy.typing import ArrayLike
from safetensors.torch import load as st_load
from safetensors.torch import save as st_save
from torch import nn

__all__ = ["BCPolicy"]

_FORMAT = "steer_envs.baselines.bc/1"


class BCPolicy:
    """MLP velocity policy ``x -> x_dot`` (a batched ``VelocityPolicy``).

    Args:
        state_dim: dimension ``d`` of states and velocities.
        hidden: hidden layer widths (thesis: ``(100, 100)``).
        output_scale: the tanh output is multiplied by this (thesis: 50).
        lr: Adam learning rate (thesis: 1e-3).
        batch_size: minibatch size (tli.md: 512).
        seed: seed of the weight initialisation and of the batch order.
    """

    def __init__(
        self,
        state_dim: int = 2,
        *,
        hidden: tuple[int, ...] = (100, 100),
        output_scale: float = 50.0,
        lr: float = 1e-3,
        batch_size: int = 512,
        seed: int = 0,
    ) -> None:
        if not isinstance(state_dim, (int, np.integer)) or state_dim < 1:
            raise ValueError(f"state_dim must be a positive int, got {state_dim!r}")
        hidden = tuple(int(h) for h in hidden)
        if len(hidden) == 0 or any(h < 1 for h in hidden):
            raise ValueError(f"hidden must be a non-empty tuple of positive ints, got {hidden!r}")
        for name, value in (("output_scale", output_scale), ("lr", lr)):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite float, got {value!r}")
        if not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
            raise ValueError(f"batch_size must be a positive int, got {batch_size!r}")
        self.state_dim = int(state_dim)
        self.hidden = hidden
        self.output_scale = float(output_scale)
        self.lr = float(lr)
        self.batch_size = int(batch_size)
        self.seed = int(seed)
        self._generator = torch.Generator().manual_seed(self.seed)
        self.net = self._build()
        self.epochs_trained = 0

    def _build(self) -> nn.Sequential:
        layers: list[nn.Module] = []
        widths = (self.state_dim, *self.hidden)
        for a, b in itertools.pairwise(widths):
            layers += [nn.Linear(a, b), nn.ReLU()]
        layers += [nn.Linear(widths[-1], self.state_dim), nn.Tanh()]
        net = nn.Sequential(*layers)
        with torch.no_grad():  # PyTorch's default init, drawn from our own generator
            for m in net:
                if isinstance(m, nn.Linear):
                    bound = 1.0 / np.sqrt(m.in_features)
                    m.weight.uniform_(-bound, bound, generator=self._generator)
                    m.bias.uniform_(-bound, bound, generator=self._generator)
        return net

    def fit(self, states: ArrayLike, velocities: ArrayLike, epochs: int = 4000) -> list[float]:
        """Train on pairs ``(N, d)``/``(N, d)`` for ``epochs`` passes; returns the per-epoch mean loss."""
        x = _as_batch(states, "states", self.state_dim)
        v = _as_batch(velocities, "velocities", self.state_dim)
        if len(x) != len(v):
            raise ValueError(f"states and velocities must have the same length, got {len(x)} and {len(v)}")
        if np.any(np.abs(v) >= self.output_scale):
            raise ValueError(f"velocities must lie strictly inside (-{self.output_scale}, {self.output_scale})")
        if not isinstance(epochs, (int, np.integer)) or epochs < 0:
            raise ValueError(f"epochs must be a non-negative int, got {epochs!r}")
        xt, vt = torch.from_numpy(x).float(), torch.from_numpy(v).float()
        opt = torch.optim.Adam(self.net.parameters(), lr=self.lr)
        losses: list[float] = []
        threads = torch.get_num_threads()
        torch.set_num_threads(1)  # a 100-wide MLP: extra intra-op threads only add contention (restored below)
        try:
            self.net.train()
            for _ in range(int(epochs)):
                order = torch.randperm(len(xt), generator=self._generator)
                total = 0.0
                for start in range(0, len(xt), self.batch_size):
                    idx = order[start : start + self.batch_size]
                    loss = torch.mean((self._forward(xt[idx]) - vt[idx]) ** 2)
                    opt.zero_grad()
                    loss.backward()
                    opt.step()
                    total += loss.item() * len(idx)
                losses.append(total / len(xt))
        finally:
            torch.set_num_threads(threads)
            self.net.eval()
        self.epochs_trained += int(epochs)
        return losses

    def _forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.output_scale * self.net(x)

    def __call__(self, x: ArrayLike) -> np.ndarray:
        """Velocities for states ``(N, d) -> (N, d)`` (a single ``(d,)`` state gives ``(d,)``)."""
        arr = np.asarray(x, dtype=np.float64)
        single = arr.ndim == 1
        xb = _as_batch(arr[None] if single else arr, "x", self.state_dim)
        with torch.no_grad():
            out = self._forward(torch.from_numpy(xb).float()).numpy().astype(np.float64)
        return out[0] if single else out

    # ------------------------------------------------------------ persistence
    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write weights + config to a safetensors file atomically (temp file + ``os.replace``)."""
        path = Path(path)
        config = {
            "format": _FORMAT,
            "state_dim": self.state_dim,
            "hidden": list(self.hidden),
            "output_scale": self.output_scale,
            "lr": self.lr,
            "batch_size": self.batch_size,
            "seed": self.seed,
            "epochs_trained": self.epochs_trained,
        }
        tensors = {k: v.detach().contiguous() for k, v in self.net.state_dict().items()}
        data = st_save(tensors, metadata={"config": json.dumps(config)})
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> BCPolicy:
        """A policy from a file written by :meth:`save` (safetensors: no code is executed)."""
        raw = Path(path).read_bytes()
        config = _read_config(raw, path)
        policy = cls(
            config["state_dim"],
            hidden=tuple(config["hidden"]),
            output_scale=config["output_scale"],
            lr=config["lr"],
            batch_size=config["batch_size"],
            seed=config["seed"],
        )
        policy.net.load_state_dict(st_load(raw))
        policy.net.eval()
        policy.epochs_trained = int(config["epochs_trained"])
        return policy


def _read_config(raw: bytes, path: str | os.PathLike[str]) -> dict:
    """The JSON config from a safetensors header (8-byte length + JSON with ``__metadata__``)."""
    try:
        n = int.from_bytes(raw[:8], "little")
        header = json.loads(raw[8 : 8 + n])
        config = json.loads(header["__metadata__"]["config"])
    except (ValueError, KeyError, TypeError):
        raise ValueError(f"{path} is not a BCPolicy safetensors file") from None
    if config.get("format") != _FORMAT:
        raise ValueError(f"{path} holds format {config.get('format')!r}, expected {_FORMAT!r}")
    return config


def _as_batch(value: ArrayLike, name: str, d: int) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a float array of shape (N, {d}), got {type(value).__name__}") from None
    if arr.ndim != 2 or arr.shape[1] != d or len(arr) == 0:
        raise ValueError(f"{name} must have shape (N>=1, {d}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (got NaN or inf)")
    return np.ascontiguousarray(arr)
