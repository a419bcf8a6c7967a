"""GLiDE mode classifier: grounding modes from success-labelled trajectories (thesis §4.2).

The classifier ``phi`` maps a state to a belief over ``K`` modes (an MLP with
one hidden layer of 128 ReLU units and a softmax). It is trained without any
mode labels, only from which trajectories succeeded, through a differentiable
forward model of task success built on the feasibility matrix ``F``
(``F[i, j] = 0`` for feasible moves, negative otherwise):

* transition score ``f_t = phi(s_t)^T F phi(s_{t+1})``;
* ``L_succ = -mean_{tau+} mean_t f_t`` -- successes make only feasible moves;
* ``L_fail = mean_{tau-} max(clip, sum_t f_t)`` -- each failure makes at least
  one infeasible move (clipped at -1: all infeasible moves count the same);
* ``L_init`` / ``L_final``: cross-entropy of the first / last state of every
  trajectory against the first / last mode of the plan;
* ``L_dyn`` (eq. 4.3, underactuated systems): a per-mode forward model
  ``psi`` predicts the next state change from the current one, and
  ``phi(s_t)^T psi(s_t - s_{t-1})`` must match ``s_{t+1} - s_t``.

``L = w_succ L_succ + w_fail L_fail + w_init L_init + w_final L_final + w_dyn L_dyn``
with the public code's weights 1000 / 1 / 10 / 10 as defaults (``w_dyn = 0``
for the fully actuated PolygonNav). Any weight set to 0 ablates its term.

Optimisation (:class:`GlideTrainConfig`,
:func:`~steer_envs.baselines.glide.training.train_mode_classifier`): several
heads train in parallel (loss ``(1 - b) * mean_head + b * best_head``) and the head with the lowest
*training loss* is kept (never one chosen by ground truth); after a fraction
of training only the best few heads train on. The weight of ``L_succ`` is
warmed up geometrically over the first half of training: at full weight from
the start it drives the heads into labellings where one mode fills whole
regions before the failures can act. Training is full batch over *distinct*
states and *distinct* transitions: replays share most of their states and
whole stretches of transitions with their demo, so per-trajectory sums are
taken over runs of consecutive transitions with one cumulative sum (exact,
see :func:`~steer_envs.baselines.glide.packing.pack_trajectories`).

Once trained, the classifier only provides labels:
:func:`~steer_envs.baselines.glide.modes.label_demonstrations` labels every state of the demonstrations, which
:mod:`steer_envs.data.segmentation` (and GLiDE's policies) turn into modes.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from steer_envs.baselines.common.checkpoint import (
    check_parameter_count,
    check_state,
    read_safetensors,
    write_safetensors,
)
from steer_envs.core.progress import check_progress
from steer_envs.core.validation import integer, real_array
from steer_envs.io import CheckpointError

LOSS_TERMS: tuple[str, ...] = ("succ", "fail", "init", "final", "dyn")


# ------------------------------------------------------------------ configuration
@dataclass(frozen=True)
class GlideLossWeights:
    """Weights of the loss terms (0 switches a term off) and the ``L_fail`` clip."""

    succ: float = 1000.0
    fail: float = 1.0
    init: float = 10.0
    final: float = 10.0
    dyn: float = 0.0
    fail_clip: float = -1.0
    #: > 0: a failure may also be explained by ending outside the final mode: ``L_fail`` adds
    #: ``-u (1 - p(s_T in sigma_K))`` to each failure's sum and ``L_final`` holds successes only
    #: (replays on a robot arm fail by running out of time or being cut short, with every
    #: move feasible; the thesis's "every trajectory ends in the final mode" is the polygons').
    #: ``u < 1`` leaves a failure that also makes an infeasible move better explained.
    unfinished_fails: float = 0.0

    def __post_init__(self) -> None:
        for name in LOSS_TERMS:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise ValueError(f"loss weight {name!r} must be a finite float >= 0, got {v!r}")
        if not (isinstance(self.unfinished_fails, (int, float)) and 0 <= self.unfinished_fails <= 1):
            raise ValueError(f"unfinished_fails must be a float in [0, 1], got {self.unfinished_fails!r}")
        if not (np.isfinite(self.fail_clip) and self.fail_clip < 0):
            raise ValueError(f"fail_clip must be a negative float, got {self.fail_clip!r}")

    def without(self, *terms: str) -> GlideLossWeights:
        """These weights with ``terms`` switched off.

        >>> GlideLossWeights().without("succ", "fail").succ
        0.0
        """
        for t in terms:
            if t not in LOSS_TERMS:
                raise ValueError(f"unknown loss term {t!r}; expected one of {LOSS_TERMS}")
        zeros: dict[str, Any] = dict.fromkeys(terms, 0.0)
        return replace(self, **zeros)


@dataclass(frozen=True)
class GlideTrainConfig:
    """Optimisation settings of :func:`~steer_envs.baselines.glide.training.train_mode_classifier`.

    Args:
        epochs: full-batch Adam steps.
        lr: initial learning rate (cosine-decayed to ``lr * lr_final_ratio``).
        hidden: hidden units of the MLP.
        n_heads: classifiers trained in parallel; the best by training loss is kept
            (the GLiDE suites' setting: 5 heads, the best 2 after pruning).
        best_head_weight: ``b`` in ``(1 - b) * mean_head_loss + b * best_head_loss``.
        prune_at, prune_to: after the fraction ``prune_at`` of the steps, only the
            ``prune_to`` heads with the lowest training loss (full weights) train on;
            the others are dropped, so restarts cost compute only while they can still
            win. ``prune_to >= n_heads`` never prunes.
        stride: keep every ``stride``-th state of each trajectory (its last state always).
        init_mode_bias: added to the initial mode's output bias at initialisation,
            so training starts from "every state is in the plan's first mode"
            (0: off).
        succ_warmup: fraction of the steps over which the weight of ``L_succ``
            grows geometrically from ``succ_warmup_start`` times its value to its
            value (0: no warm-up).
        n_batches: the trajectories are split once (seeded) into this many
            minibatches, used in turn; 1 is full-batch training. One epoch is
            one pass over all minibatches.
        psi_hidden: hidden units of the forward model psi (0: one linear map per mode).
        dyn_columns: the state columns ``L_dyn`` models (None: all). On a robot arm the
            quaternions' controller jitter, divided by their tiny spread, would swamp the
            positions whose dynamics tell the modes apart.
        dyn_inputs: the state columns whose change psi reads (None: ``dyn_columns``, the
            thesis's ``psi(s_t - s_{t-1})``). On an underactuated system the robot's own
            motion (e.g. the end effector's position): a linear psi that reads the change
            of the columns it predicts fits every smooth motion with the identity, in
            every mode; one that reads the robot's motion must tell "the object moves
            with the gripper" from "it does not".
        dyn_input_lag: 1: psi reads the previous step's change (``s_t - s_{t-1}``, the
            thesis); 0: the same step's (``s_{t+1} - s_t`` of ``dyn_inputs``, which must
            then be given): the object's motion caused by the robot's, without the
            smoothness assumption.
        seed: seeds the initial weights.
        num_threads: torch intra-op threads during training (None: leave torch's setting); 1 by
            default: the networks are small and extra threads mostly spin on a shared CPU.
        progress: a tqdm bar over epochs: True shown, None shown only when stderr is a terminal, False
            (default) hidden.

    >>> GlideTrainConfig().n_heads, GlideTrainConfig().prune_to, GlideTrainConfig(n_heads=1).epochs
    (5, 2, 2000)
    """

    epochs: int = 2000
    lr: float = 1e-2
    lr_final_ratio: float = 0.05
    hidden: int = 128
    n_heads: int = 5
    best_head_weight: float = 0.9
    prune_at: float = 0.6
    prune_to: int = 2
    stride: int = 1
    n_batches: int = 1
    init_mode_bias: float = 0.0
    succ_warmup: float = 0.5
    succ_warmup_start: float = 1e-3
    psi_hidden: int = 0
    dyn_columns: tuple[int, ...] | None = None
    dyn_inputs: tuple[int, ...] | None = None
    dyn_input_lag: int = 1
    seed: int = 0
    num_threads: int | None = 1
    progress: bool | None = False

    def __post_init__(self) -> None:
        check_progress(self.progress)
        for name in ("epochs", "hidden", "n_heads", "stride", "n_batches"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"{name} must be a positive int, got {v!r}")
        if (
            isinstance(self.psi_hidden, bool)
            or not isinstance(self.psi_hidden, (int, np.integer))
            or self.psi_hidden < 0
        ):
            raise ValueError(f"psi_hidden must be an int >= 0, got {self.psi_hidden!r}")
        if self.dyn_input_lag not in (0, 1) or isinstance(self.dyn_input_lag, bool):
            raise ValueError(f"dyn_input_lag must be 0 or 1, got {self.dyn_input_lag!r}")
        if self.dyn_input_lag == 0 and self.dyn_inputs is None:
            raise ValueError("dyn_input_lag=0 needs dyn_inputs (psi would read the change it predicts)")
        for name in ("dyn_columns", "dyn_inputs"):
            cols = getattr(self, name)
            if cols is not None and (
                not isinstance(cols, tuple)
                or not cols
                or any(isinstance(c, bool) or not isinstance(c, (int, np.integer)) or c < 0 for c in cols)
            ):
                raise ValueError(f"{name} must be None or a non-empty tuple of column indices, got {cols!r}")
        if not (np.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr must be a positive float, got {self.lr!r}")
        if not 0 < self.lr_final_ratio <= 1:
            raise ValueError(f"lr_final_ratio must be in (0, 1], got {self.lr_final_ratio!r}")
        if not 0 <= self.succ_warmup <= 1:
            raise ValueError(f"succ_warmup must be in [0, 1], got {self.succ_warmup!r}")
        if not 0 < self.succ_warmup_start <= 1:
            raise ValueError(f"succ_warmup_start must be in (0, 1], got {self.succ_warmup_start!r}")
        if not np.isfinite(self.init_mode_bias):
            raise ValueError(f"init_mode_bias must be a finite float, got {self.init_mode_bias!r}")
        if not 0 <= self.best_head_weight <= 1:
            raise ValueError(f"best_head_weight must be in [0, 1], got {self.best_head_weight!r}")
        if not 0 <= self.prune_at <= 1:
            raise ValueError(f"prune_at must be in [0, 1], got {self.prune_at!r}")
        if isinstance(self.prune_to, bool) or not isinstance(self.prune_to, (int, np.integer)) or self.prune_to < 1:
            raise ValueError(f"prune_to must be a positive int, got {self.prune_to!r}")
        if self.num_threads is not None and (not isinstance(self.num_threads, int) or self.num_threads < 1):
            raise ValueError(f"num_threads must be None or a positive int, got {self.num_threads!r}")


# -------------------------------------------------------------------------- models
def _uniform(gen: torch.Generator, shape: tuple[int, ...], fan_in: int) -> nn.Parameter:
    bound = 1.0 / np.sqrt(fan_in)
    return nn.Parameter((torch.rand(shape, generator=gen, dtype=torch.float32) * 2 - 1) * bound)


class ModeClassifier(nn.Module):
    """``n_heads`` parallel MLPs ``d -> hidden (ReLU) -> K`` with softmax beliefs.

    Inputs are standardised with the ``mean``/``scale`` buffers (set from the
    training states). ``head`` selects the head :meth:`predict_proba` uses.
    """

    mean: torch.Tensor
    scale: torch.Tensor

    def __init__(self, state_dim: int, num_modes: int, *, hidden: int = 128, n_heads: int = 1, seed: int = 0) -> None:
        super().__init__()
        for name, v, lo in (("state_dim", state_dim, 1), ("num_modes", num_modes, 2), ("hidden", hidden, 1)):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise ValueError(f"{name} must be an int >= {lo}, got {v!r}")
        if isinstance(n_heads, bool) or not isinstance(n_heads, (int, np.integer)) or n_heads < 1:
            raise ValueError(f"n_heads must be a positive int, got {n_heads!r}")
        self.state_dim, self.num_modes, self.hidden, self.n_heads = (
            int(state_dim),
            int(num_modes),
            int(hidden),
            int(n_heads),
        )
        gen = torch.Generator().manual_seed(int(seed))
        h, d, k = self.n_heads, self.state_dim, self.num_modes
        self.w1 = _uniform(gen, (h, d, hidden), d)
        self.b1 = _uniform(gen, (h, 1, hidden), d)
        self.w2 = _uniform(gen, (h, hidden, k), hidden)
        self.b2 = _uniform(gen, (h, 1, k), hidden)
        self.register_buffer("mean", torch.zeros(d))
        self.register_buffer("scale", torch.ones(d))
        self.head = 0

    def set_normalization(self, states: np.ndarray) -> None:
        """Standardise inputs with the mean and std of ``states`` ``(N, d)``."""
        x = torch.as_tensor(np.asarray(states, dtype=np.float32))
        self.mean.copy_(x.mean(0))
        self.scale.copy_(x.std(0).clamp_min(1e-6))

    def forward(self, states: torch.Tensor) -> torch.Tensor:
        """Logits ``(n_heads, N, K)`` of states ``(N, d)``."""
        x = (states - self.mean) / self.scale
        hid = torch.relu(torch.baddbmm(self.b1, x.expand(self.n_heads, *x.shape), self.w1))
        return torch.baddbmm(self.b2, hid, self.w2)

    def _check_states(self, states: Any) -> torch.Tensor:
        arr = real_array(states, "states", owner="ModeClassifier").astype(np.float32)
        if arr.ndim != 2 or arr.shape[1] != self.state_dim:
            raise ValueError(f"ModeClassifier: states must have shape (N, {self.state_dim}), got {arr.shape}")
        return torch.from_numpy(arr)

    @torch.no_grad()
    def predict_proba(self, states: np.ndarray, head: int | None = None) -> np.ndarray:
        """Mode beliefs ``(N, K)`` of the selected (or given) head."""
        h = self.head if head is None else int(head)
        if not 0 <= h < self.n_heads:
            raise ValueError(f"head must be in [0, {self.n_heads}), got {h}")
        x = self._check_states(states)
        out = [torch.softmax(self.forward(x[i : i + 65536])[h], dim=-1) for i in range(0, len(x), 65536)]
        return torch.cat(out).numpy() if out else np.zeros((0, self.num_modes), dtype=np.float32)

    def predict(self, states: np.ndarray) -> np.ndarray:
        """Most likely mode ``(N,)`` of each state."""
        return self.predict_proba(states).argmax(axis=1).astype(np.int64)

    # ----------------------------------------------------------------- files
    def save(self, path: str | os.PathLike[str], extra: dict[str, Any] | None = None) -> Path:
        """Write weights + architecture to a ``.safetensors`` file atomically."""
        meta = {
            "state_dim": self.state_dim,
            "num_modes": self.num_modes,
            "hidden": self.hidden,
            "n_heads": self.n_heads,
            "head": self.head,
            "extra": extra or {},
        }
        tensors = {k: v.detach().contiguous() for k, v in self.state_dict().items()}
        return write_safetensors(path, tensors, _META_KEY, meta, sort_keys=True)

    @staticmethod
    def parameter_count(state_dim: int, num_modes: int, hidden: int, n_heads: int) -> int:
        """Numbers in the state dict of a classifier of that size (weights, biases, input statistics).

        >>> ModeClassifier.parameter_count(2, 3, 128, 1)
        775
        """
        return n_heads * (state_dim * hidden + hidden + hidden * num_modes + num_modes) + 2 * state_dim

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> ModeClassifier:
        """Read a classifier written by :meth:`save` (safetensors: no code execution).

        :class:`~steer_envs.io.CheckpointError` (naming the file) for a file
        that is missing, truncated or foreign, malformed metadata, tensors that
        do not fit the metadata's network (checked before it is built),
        non-finite weights and a non-positive input scale.
        """
        tensors, meta = read_safetensors(path, _META_KEY)
        try:
            sizes = {
                "state_dim": integer(meta["state_dim"], "state_dim", low=1),
                "num_modes": integer(meta["num_modes"], "num_modes", low=2),
                "hidden": integer(meta["hidden"], "hidden", low=1),
                "n_heads": integer(meta["n_heads"], "n_heads", low=1),
            }
            head = integer(meta["head"], "head", low=0, high=sizes["n_heads"] - 1)
        except (KeyError, TypeError, ValueError) as err:
            raise CheckpointError(
                f"{path}: malformed GLiDE classifier metadata ({type(err).__name__}: {err})"
            ) from None
        check_parameter_count(cls.parameter_count(**sizes), tensors, str(path))
        model = cls(sizes["state_dim"], sizes["num_modes"], hidden=sizes["hidden"], n_heads=sizes["n_heads"])
        check_state(model.state_dict(), tensors, str(path))
        if not bool((tensors["scale"] > 0).all()):
            raise CheckpointError(f"{path}: the input scale must be > 0, got {tensors['scale'].tolist()}")
        model.load_state_dict(tensors)
        model.head = head
        model.eval()
        return model


_META_KEY = "glide_classifier"


class ForwardModel(nn.Module):
    """Per-mode forward dynamics psi: a change ``(N, d_in)`` -> predicted next change ``(H, N, K, d)``.

    ``input_dim`` defaults to ``state_dim`` (psi reads the change of the columns it predicts).
    """

    def __init__(
        self,
        state_dim: int,
        num_modes: int,
        *,
        n_heads: int = 1,
        hidden: int = 0,
        seed: int = 0,
        input_dim: int | None = None,
    ) -> None:
        super().__init__()
        gen = torch.Generator().manual_seed(int(seed) + 7919)
        d, k, h = int(state_dim), int(num_modes), int(n_heads)
        d_in = d if input_dim is None else int(input_dim)
        self.state_dim, self.num_modes, self.hidden = d, k, int(hidden)
        if hidden == 0:
            self.w = _uniform(gen, (h, d_in, k * d), d_in)
            self.b = _uniform(gen, (h, 1, k * d), d_in)
        else:
            self.w1 = _uniform(gen, (h, d_in, hidden), d_in)
            self.b1 = _uniform(gen, (h, 1, hidden), d_in)
            self.w = _uniform(gen, (h, hidden, k * d), hidden)
            self.b = _uniform(gen, (h, 1, k * d), hidden)

    def forward(self, delta: torch.Tensor) -> torch.Tensor:
        x = delta
        if self.hidden:
            x = torch.relu(torch.einsum("nd,hdk->hnk", x, self.w1) + self.b1)
            out = torch.bmm(x, self.w) + self.b
        else:
            out = torch.einsum("nd,hdk->hnk", x, self.w) + self.b
        return out.reshape(out.shape[0], out.shape[1], self.num_modes, self.state_dim)


__all__ = [
    "LOSS_TERMS",
    "ForwardModel",
    "GlideLossWeights",
    "GlideTrainConfig",
    "ModeClassifier",
]
