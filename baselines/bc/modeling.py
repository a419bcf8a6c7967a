"""Behaviour cloning: an MLP from state to action (a velocity), fitted by mean squared error.

One policy class, :class:`BCPolicy`, configured by :class:`BCConfig`. The
defaults are the thesis's BC velocity policy of the TLI single-mode study
(appendix "BC Policy Architecture"): ``d -> 100 -> 100 -> d`` with ReLU hidden
layers and a ``tanh`` output scaled to ``[-50, 50]``, trained with Adam
(lr 1e-3, batch 512) on i.i.d. (state, velocity) pairs. Unlike an LPV-DS it
has no stability guarantee, which is what the single-mode study contrasts.

The other settings cover GLiDE's BC baselines (see
:class:`~steer_envs.baselines.glide.mode_policies.GlideBCConfig`): inputs
standardised with the training statistics, a linear output in units of a
speed limit whose norm is clipped to it (``output="clip"``), and a fixed
number of minibatches drawn with replacement (``steps``) instead of epochs.

Training runs on the CPU and is deterministic given ``seed``: the initial
weights (PyTorch's default ``nn.Linear`` initialisation) come from a
``torch.Generator`` of the policy's own, so the global torch RNG is never
touched. With ``epochs`` the shuffles continue that generator; with
``steps`` the minibatch indices come from a second generator seeded with
``seed``. Checkpoints are safetensors files, written atomically.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import os
from collections.abc import Iterator
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any, Literal, Self, cast

import numpy as np
import torch
from numpy.typing import ArrayLike
from torch import nn

from steer_envs.baselines.common.checkpoint import check_parameter_count, check_state
from steer_envs.baselines.common.configuration import int_tuple
from steer_envs.baselines.common.torch_policy import read_checkpoint, write_checkpoint
from steer_envs.core.validation import boolean, describe, integer, one_of, real_array, real_scalar
from steer_envs.io import CheckpointError

__all__ = ["BC_OUTPUTS", "BCConfig", "BCOutput", "BCPolicy", "clip_speed"]

BCOutput = Literal["tanh", "clip"]
#: how :class:`BCPolicy` bounds its output (see :attr:`BCConfig.output`)
BC_OUTPUTS: tuple[str, ...] = ("tanh", "clip")
_FORMAT = "steer_envs.baselines.bc/2"
#: the most hidden layers of a BC MLP
_MAX_LAYERS = 256


@dataclass(frozen=True)
class BCConfig:
    """Architecture and training of a :class:`BCPolicy` (defaults: the thesis's TLI velocity MLP).

    Args:
        state_dim: input features ``d``.
        action_dim: output features (2 for a planar velocity).
        hidden: hidden layer widths (ReLU).
        output: ``"tanh"``: ``output_scale * tanh(MLP(x))``, each component bounded,
            trained on the action error itself (targets must lie inside
            ``(-output_scale, output_scale)``); ``"clip"``: the MLP predicts
            ``action / output_scale`` (trained in those units) and the action's
            norm is clipped to ``output_scale`` (a speed limit).
        output_scale: the bound of the outputs (see ``output``).
        standardize: standardise inputs with the mean and std of the first
            :meth:`BCPolicy.fit`'s states.
        lr: Adam learning rate.
        batch_size: minibatch size.
        epochs: passes over the data, each in a fresh random order.
        steps: instead of ``epochs``: this many minibatches drawn with replacement
            (set exactly one of ``epochs`` and ``steps``).
        num_threads: torch intra-op threads while training (small networks: extra threads only contend).

    >>> BCConfig().hidden, BCConfig(hidden=[32]).hidden
    ((100, 100), (32,))
    """

    state_dim: int = 2
    action_dim: int = 2
    hidden: tuple[int, ...] = (100, 100)
    output: BCOutput = "tanh"
    output_scale: float = 50.0
    standardize: bool = False
    lr: float = 1e-3
    batch_size: int = 512
    epochs: int | None = 4000
    steps: int | None = None
    num_threads: int = 1

    def __post_init__(self) -> None:
        object.__setattr__(self, "state_dim", integer(self.state_dim, "state_dim", low=1))
        object.__setattr__(self, "action_dim", integer(self.action_dim, "action_dim", low=1))
        hidden = int_tuple(self.hidden, "hidden", 1)
        if not hidden or len(hidden) > _MAX_LAYERS:
            raise ValueError(f"hidden must hold 1 to {_MAX_LAYERS} positive ints, got {describe(self.hidden)}")
        object.__setattr__(self, "hidden", hidden)
        one_of(self.output, "output", BC_OUTPUTS)
        for name in ("output_scale", "lr"):
            object.__setattr__(self, name, real_scalar(getattr(self, name), name, low=0.0, low_inclusive=False))
        object.__setattr__(self, "standardize", boolean(self.standardize, "standardize"))
        object.__setattr__(self, "batch_size", integer(self.batch_size, "batch_size", low=1))
        if (self.epochs is None) == (self.steps is None):
            raise ValueError(f"set exactly one of epochs and steps, got epochs={self.epochs!r}, steps={self.steps!r}")
        if self.epochs is not None:
            object.__setattr__(self, "epochs", integer(self.epochs, "epochs", low=0))
        if self.steps is not None:
            object.__setattr__(self, "steps", integer(self.steps, "steps", low=0))
        object.__setattr__(self, "num_threads", integer(self.num_threads, "num_threads", low=1))

    def parameter_count(self) -> int:
        """Weights and biases of the MLP, from the config alone.

        >>> BCConfig().parameter_count()
        10602
        """
        widths = (self.state_dim, *self.hidden, self.action_dim)
        return sum(a * b + b for a, b in itertools.pairwise(widths))


def clip_speed(v: np.ndarray, max_speed: float) -> np.ndarray:
    """Rows of ``v`` ``(N, d)`` scaled down to norm at most ``max_speed`` (shorter rows unchanged).

    >>> clip_speed(np.array([[3.0, 4.0], [0.3, 0.4]]), 1.0)
    array([[0.6, 0.8],
           [0.3, 0.4]])
    """
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return cast(np.ndarray, v * np.minimum(1.0, max_speed / np.maximum(norm, 1e-12)))


def _build_mlp(config: BCConfig, generator: torch.Generator) -> nn.Sequential:
    """``Linear, ReLU, ..., Linear[, Tanh]`` with PyTorch's default init drawn from ``generator``, layer by layer."""
    layers: list[nn.Module] = []
    widths = (config.state_dim, *config.hidden)
    for a, b in itertools.pairwise(widths):
        layers += [nn.Linear(a, b, device="meta"), nn.ReLU()]  # meta: no draw from the global RNG
    layers.append(nn.Linear(widths[-1], config.action_dim, device="meta"))
    if config.output == "tanh":
        layers.append(nn.Tanh())
    net = nn.Sequential(*layers).to_empty(device="cpu")
    with torch.no_grad():
        for m in net:
            if isinstance(m, nn.Linear):  # nn.Linear.reset_parameters, with our generator
                nn.init.kaiming_uniform_(m.weight, a=math.sqrt(5), generator=generator)
                bound = 1.0 / math.sqrt(m.in_features)
                nn.init.uniform_(m.bias, -bound, bound, generator=generator)
    return net


class BCPolicy:
    """An MLP policy ``state -> action`` trained by behaviour cloning (see :class:`BCConfig`).

    Batched: ``policy(states (N, d)) -> (N, a)`` (a ``VelocityPolicy``; a single
    ``(d,)`` state gives ``(a,)``). :meth:`act` and :meth:`reset` are the same
    policy in the interface of GLiDE's batched mode policies.

    Args:
        config: architecture and training settings (default: the thesis's TLI MLP).
        seed: seeds the initial weights and the minibatches.

    >>> import numpy as np
    >>> x = np.random.default_rng(0).uniform(-1, 1, (64, 2))
    >>> policy = BCPolicy(BCConfig(hidden=(16,), epochs=3), seed=0)
    >>> losses = policy.fit(x, -x)
    >>> len(losses), policy(x).shape, policy(x[0]).shape
    (3, (64, 2), (2,))
    """

    def __init__(self, config: BCConfig | None = None, *, seed: int = 0) -> None:
        if config is not None and not isinstance(config, BCConfig):
            raise TypeError(f"config must be a BCConfig or None, got {type(config).__name__}")
        integer(seed, "seed", owner="BCPolicy")
        self.config = config if config is not None else BCConfig()
        self.seed = int(seed)
        self._generator = torch.Generator().manual_seed(self.seed)
        self.net = _build_mlp(self.config, self._generator)
        self.net.eval()
        self._batch_generator = (
            self._generator if self.config.steps is None else torch.Generator().manual_seed(self.seed)
        )
        #: input standardisation (set by the first :meth:`fit` when ``config.standardize``)
        self.input_mean: np.ndarray | None = None
        self.input_scale: np.ndarray | None = None
        #: epochs (or, with ``config.steps``, minibatch steps) trained so far
        self.trained_for = 0

    # ------------------------------------------------------------------ training
    def fit(self, states: ArrayLike, actions: ArrayLike) -> list[float]:
        """Train on pairs ``(N, d)`` / ``(N, a)``; returns the loss per epoch (or per step with ``steps``).

        Both are finite real arrays (or tensors) with ``N >= 1`` rows. Each call
        trains ``config.epochs`` (or ``config.steps``) more from the current
        weights, with a fresh Adam optimiser (:class:`~steer_envs.baselines.bc.runs.BCRun`
        keeps one optimiser across calls, and its state in a file).
        """
        cfg = self.config
        x, y = self.training_tensors(states, actions)
        opt = self.new_optimizer()
        losses: list[float] = []
        with self.training():
            if cfg.epochs is not None:
                for _ in range(cfg.epochs):
                    order = torch.randperm(len(x), generator=self._batch_generator)
                    total = 0.0
                    for start in range(0, len(x), cfg.batch_size):
                        idx = order[start : start + cfg.batch_size]
                        total += self._step(opt, x[idx], y[idx]) * len(idx)
                    losses.append(total / len(x))
                self.trained_for += cfg.epochs
            else:
                assert cfg.steps is not None
                for _ in range(cfg.steps):
                    losses.append(self.minibatch_step(opt, x, y))
                self.trained_for += cfg.steps
        return losses

    def training_tensors(self, states: ArrayLike, actions: ArrayLike) -> tuple[torch.Tensor, torch.Tensor]:
        """The inputs and targets :meth:`fit` trains on: checked, float32, the inputs standardised (the first
        call sets the statistics with ``config.standardize``), the targets in the loss's units."""
        cfg = self.config
        s = _as_batch(states, "states", cfg.state_dim)
        a = _as_batch(actions, "actions", cfg.action_dim)
        if len(s) != len(a):
            raise ValueError(f"states and actions must have the same length, got {len(s)} and {len(a)}")
        if cfg.output == "tanh" and np.any(np.abs(a) >= cfg.output_scale):
            raise ValueError(
                f"actions must lie strictly inside (-{cfg.output_scale}, {cfg.output_scale}) for a tanh output, "
                f"got max |a| = {float(np.abs(a).max())}"
            )
        s32 = s.astype(np.float32)
        if cfg.standardize and self.input_mean is None:
            self.input_mean = s32.mean(0)
            self.input_scale = np.maximum(s32.std(0), 1e-6)
        x = torch.from_numpy(self._standardized(s32))
        a32 = a.astype(np.float32)
        y = torch.from_numpy(a32 if cfg.output == "tanh" else a32 / cfg.output_scale)
        return x, y

    def new_optimizer(self) -> torch.optim.Adam:
        """A fresh Adam optimiser over the network's weights at ``config.lr`` (what :meth:`fit` trains with)."""
        return torch.optim.Adam(self.net.parameters(), lr=self.config.lr)

    @property
    def batch_generator(self) -> torch.Generator:
        """The generator the minibatches are drawn from (its state is part of a resumable run's)."""
        return self._batch_generator

    @contextlib.contextmanager
    def training(self) -> Iterator[None]:
        """Training mode with ``config.num_threads`` torch threads; evaluation mode and the caller's threads after."""
        threads = torch.get_num_threads()
        torch.set_num_threads(self.config.num_threads)
        try:
            self.net.train()
            yield
        finally:
            torch.set_num_threads(threads)
            self.net.eval()

    def minibatch_step(self, optimizer: torch.optim.Optimizer, x: torch.Tensor, y: torch.Tensor) -> float:
        """One step on ``min(batch_size, N)`` rows of ``(x, y)`` drawn with replacement from :attr:`batch_generator`
        (one step of :meth:`fit` with ``steps``); returns its loss. Call it inside :meth:`training`."""
        n = min(self.config.batch_size, len(x))
        idx = torch.randint(0, len(x), (n,), generator=self._batch_generator)
        return self._step(optimizer, x[idx], y[idx])

    def _step(self, opt: torch.optim.Optimizer, x: torch.Tensor, y: torch.Tensor) -> float:
        """One Adam step on the squared error of a minibatch; returns its loss."""
        loss = ((self._train_output(x) - y) ** 2).mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        return float(loss.item())

    def _train_output(self, x: torch.Tensor) -> torch.Tensor:
        """The network's output in the units the loss is taken in (actions, or actions / scale for ``clip``)."""
        out = self.net(x)
        return self.config.output_scale * out if self.config.output == "tanh" else out

    def _standardized(self, s32: np.ndarray) -> np.ndarray:
        if self.input_mean is None or self.input_scale is None:
            return s32
        return cast(np.ndarray, (s32 - self.input_mean) / self.input_scale)

    # ----------------------------------------------------------------- inference
    def __call__(self, states: ArrayLike) -> np.ndarray:
        """Actions for states ``(N, d) -> (N, a)`` (a single ``(d,)`` state gives ``(a,)``), float64.

        ``states``: finite real numbers (a sequence, numpy array or torch tensor);
        strings, complex numbers and bools are a ``TypeError``, NaN/inf,
        other shapes and states so large that the actions overflow a ``ValueError``.
        """
        arr = real_array(states, "states", owner="BCPolicy")
        single = arr.ndim == 1
        s = _as_batch(arr[None] if single else arr, "states", self.config.state_dim)
        x = torch.from_numpy(self._standardized(s.astype(np.float32)))
        with torch.no_grad():
            if self.config.output == "tanh":
                out = self._train_output(x).numpy().astype(np.float64)
            else:
                out = clip_speed(
                    self.net(x).numpy().astype(np.float64) * self.config.output_scale, self.config.output_scale
                )
        if not np.all(np.isfinite(out)):  # finite states so large that the network overflows (e.g. 3e38)
            raise ValueError(
                f"BCPolicy: states must be within the network's range, got values up to {np.max(np.abs(s)):.3g} "
                "whose actions overflow to NaN/inf"
            )
        return out[0] if single else out

    def act(self, states: ArrayLike) -> np.ndarray:
        """Same as calling the policy: actions ``(N, a)`` for states ``(N, d)``."""
        return self(states)

    def reset(self, mask: np.ndarray | None = None) -> None:
        """Stateless: nothing to forget (the batched-policy interface of the GLiDE evaluation)."""

    # --------------------------------------------------------------- persistence
    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write weights, input statistics and config to a ``.safetensors`` file atomically."""
        tensors = {k: v.detach() for k, v in self.net.state_dict().items()}
        if self.input_mean is not None and self.input_scale is not None:
            tensors["input_mean"] = torch.from_numpy(self.input_mean)
            tensors["input_scale"] = torch.from_numpy(self.input_scale)
        meta = {"format": _FORMAT, "config": asdict(self.config), "seed": self.seed, "trained_for": self.trained_for}
        return write_checkpoint(path, tensors, meta)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Self:
        """A policy from a file written by :meth:`save` (safetensors: no code is executed).

        :class:`~steer_envs.io.CheckpointError` (naming the file) for a file
        that is missing, truncated or foreign, a malformed config, tensors that
        do not fit the config's MLP (checked before it is built), non-finite
        weights and invalid input statistics.
        """
        tensors, meta = read_checkpoint(path)
        if meta.get("format") != _FORMAT:
            raise CheckpointError(f"{path} holds format {meta.get('format')!r}, expected a BCPolicy file ({_FORMAT!r})")
        try:
            values = meta["config"]
            if not isinstance(values, dict):
                raise TypeError(f"config must be a JSON object, got {describe(values)}")
            known = {f.name for f in fields(BCConfig)}
            kwargs: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
            kwargs = {k: v for k, v in kwargs.items() if k in known}
            config = BCConfig(**kwargs)
            seed = integer(meta["seed"], "seed")
            trained_for = integer(meta["trained_for"], "trained_for", low=0)
        except (KeyError, TypeError, ValueError) as err:
            raise CheckpointError(f"{path}: malformed BCPolicy header ({type(err).__name__}: {err})") from None
        mean, scale = tensors.pop("input_mean", None), tensors.pop("input_scale", None)
        check_parameter_count(config.parameter_count(), tensors, str(path))
        if (mean is None) != (scale is None):
            raise CheckpointError(f"{path}: holds only one of input_mean and input_scale")
        for name, t in (("input_mean", mean), ("input_scale", scale)):
            if t is not None and (tuple(t.shape) != (config.state_dim,) or t.dtype != torch.float32):
                raise CheckpointError(
                    f"{path}: {name} must be float32 of shape ({config.state_dim},), got {t.dtype} {tuple(t.shape)}"
                )
        if scale is not None and not bool((scale > 0).all()):
            raise CheckpointError(f"{path}: input_scale must be > 0, got {scale.tolist()}")
        policy = cls(config, seed=seed)
        check_state(policy.net.state_dict(), tensors, str(path))
        policy.net.load_state_dict(tensors)
        policy.net.eval()
        if mean is not None and scale is not None:
            policy.input_mean, policy.input_scale = mean.numpy(), scale.numpy()
        policy.trained_for = trained_for
        return policy


def _as_batch(value: ArrayLike, name: str, d: int) -> np.ndarray:
    arr = real_array(value, name, owner="BCPolicy")
    if arr.ndim != 2 or arr.shape[1] != d or len(arr) == 0:
        raise ValueError(f"BCPolicy: {name} must have shape (N>=1, {d}), got {arr.shape}")
    return np.ascontiguousarray(arr)
