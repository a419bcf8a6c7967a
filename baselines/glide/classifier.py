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

Optimisation (:class:`GlideTrainConfig`): several heads train in parallel
(loss ``(1 - b) * mean_head + b * best_head``) and the head with the lowest
*training loss* is kept (never one chosen by ground truth); after a fraction
of training only the best few heads train on. The weight of ``L_succ`` is
warmed up geometrically over the first half of training: at full weight from
the start it drives the heads into labellings where one mode fills whole
regions before the failures can act. Training is full batch over *distinct*
states and *distinct* transitions: replays share most of their states and
whole stretches of transitions with their demo, so per-trajectory sums are
taken over runs of consecutive transitions with one cumulative sum (exact,
see :func:`pack_trajectories`).

Once trained, the classifier only provides labels:
:func:`label_demonstrations` labels every state of the demonstrations, which
:mod:`steer_envs.data.segmentation` (and GLiDE's policies) turn into modes.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch
from torch import nn

from steer_envs.baselines.common.checkpoint import (
    check_parameter_count,
    check_state,
    read_safetensors,
    write_safetensors,
)
from steer_envs.core.progress import check_progress, progress_bar
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
    """Optimisation settings of :func:`train_mode_classifier`.

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


class ModePredictor(Protocol):
    """Anything that labels states with mode indices (classifier, k-means baseline)."""

    def predict(self, states: np.ndarray) -> np.ndarray:
        """The mode index of each state ``(N, d) -> (N,)``."""
        ...


def label_demonstrations(predictor: ModePredictor, demos: Sequence[np.ndarray], num_modes: int) -> list[np.ndarray]:
    """The predicted mode of every state of every demo (``(T_i,)`` int arrays).

    The labels are what :func:`~steer_envs.data.segmentation.segment_demonstrations`
    splits demonstrations by; a mode outside ``[0, num_modes)`` is an error.

    >>> import numpy as np
    >>> class LeftRight:  # mode 1 right of x = 0
    ...     def predict(self, s): return (np.asarray(s)[:, 0] > 0).astype(int)
    >>> label_demonstrations(LeftRight(), [np.array([[-1.0, 0.0], [1.0, 0.0]])], 2)
    [array([0, 1])]
    """
    if len(demos) == 0:
        raise ValueError("demos must not be empty")
    out = []
    for i, d in enumerate(demos):
        arr = np.asarray(d, dtype=np.float64)
        if arr.ndim != 2:
            raise ValueError(f"demos[{i}] must be (T, d), got {arr.shape}")
        modes = np.asarray(predictor.predict(arr), dtype=np.int64)
        if np.any((modes < 0) | (modes >= num_modes)):
            raise ValueError(f"the predictor returned modes outside [0, {num_modes}) for demos[{i}]")
        out.append(modes)
    return out


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


# ---------------------------------------------------------------------- data packing
@dataclass
class PackedTrajectories:
    """Trajectories flattened for full-batch training (built by :func:`pack_trajectories`)."""

    states: torch.Tensor  # (N, d) distinct states
    pair_a: torch.Tensor  # (U,) index of s_t of each distinct transition (s_t, s_{t+1})
    pair_b: torch.Tensor  # (U,) index of s_{t+1}
    run_traj: torch.Tensor  # (R,) trajectory of each run of transitions
    run_start: torch.Tensor  # (R,) a run is the distinct transitions run_start .. run_end - 1
    run_end: torch.Tensor  # (R,)
    pairs_per_traj: torch.Tensor  # (n,) float
    init: torch.Tensor  # (n,) index of each trajectory's first state
    final: torch.Tensor  # (n,) index of each trajectory's last state
    success: torch.Tensor  # (n,) bool
    dyn_prev: torch.Tensor  # (M,) index of s_{t-1} for interior states
    dyn_mid: torch.Tensor  # (M,) index of s_t
    dyn_next: torch.Tensor  # (M,) index of s_{t+1}

    @property
    def num_trajectories(self) -> int:
        return len(self.success)


def pack_trajectories(
    trajectories: Sequence[np.ndarray], success: Sequence[bool] | np.ndarray, stride: int = 1
) -> PackedTrajectories:
    """Flatten ``(T_i, d)`` trajectories (keeping every ``stride``-th state and the last one)."""
    if len(trajectories) == 0:
        raise ValueError("trajectories must not be empty")
    labels = np.asarray(success, dtype=bool)
    if labels.shape != (len(trajectories),):
        raise ValueError(f"success must have one label per trajectory ({len(trajectories)}), got {labels.shape}")
    if isinstance(stride, bool) or not isinstance(stride, (int, np.integer)) or stride < 1:
        raise ValueError(f"stride must be a positive int, got {stride!r}")
    dim = None
    parts, a, b, traj, npairs, init, final, prev, mid, nxt = [], [], [], [], [], [], [], [], [], []
    offset = 0
    for i, tr in enumerate(trajectories):
        arr = np.asarray(tr, dtype=np.float32)
        if arr.ndim != 2 or len(arr) < 1:
            raise ValueError(f"trajectories[{i}] must have shape (T >= 1, d), got {arr.shape}")
        if dim is None:
            dim = arr.shape[1]
        elif arr.shape[1] != dim:
            raise ValueError(f"trajectories[{i}] has dimension {arr.shape[1]}, expected {dim}")
        keep = np.arange(0, len(arr), stride)
        if keep[-1] != len(arr) - 1:
            keep = np.append(keep, len(arr) - 1)
        sub = arr[keep]
        m = len(sub)
        idx = np.arange(offset, offset + m)
        parts.append(sub)
        a.append(idx[:-1])
        b.append(idx[1:])
        traj.append(np.full(m - 1, i))
        npairs.append(m - 1)
        init.append(idx[0])
        final.append(idx[-1])
        prev.append(idx[:-2])
        mid.append(idx[1:-1])
        nxt.append(idx[2:])
        offset += m

    # replays share most states with their demo (the tracking controller visits the demo's own
    # waypoints): the classifier runs once per distinct state and pairs index into those
    unique, inverse = np.unique(np.concatenate(parts), axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)

    def cat(xs: list[np.ndarray]) -> torch.Tensor:
        return torch.from_numpy(inverse[np.concatenate(xs).astype(np.int64)])

    # whole stretches of transitions recur too (a replay repeats its demo before and after the
    # perturbation): number the distinct transitions in order of first occurrence, so a stretch
    # shared with an earlier trajectory is a run of consecutive numbers, summed per trajectory
    # with one cumulative sum over the distinct transitions instead of pair by pair
    pairs = np.stack([cat(a).numpy(), cat(b).numpy()], axis=1)
    upairs, first, pair_inverse = np.unique(pairs, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    q = rank[pair_inverse.reshape(-1)]
    traj_of_pair = np.concatenate(traj).astype(np.int64)
    new_run = np.ones(len(q), dtype=bool)
    new_run[1:] = (q[1:] != q[:-1] + 1) | (traj_of_pair[1:] != traj_of_pair[:-1])
    starts = np.flatnonzero(new_run)
    ends = np.append(starts[1:], len(q))
    upairs = upairs[order]

    return PackedTrajectories(
        states=torch.from_numpy(np.ascontiguousarray(unique)),
        pair_a=torch.from_numpy(upairs[:, 0].copy()),
        pair_b=torch.from_numpy(upairs[:, 1].copy()),
        run_traj=torch.from_numpy(traj_of_pair[starts]),
        run_start=torch.from_numpy(q[starts]),
        run_end=torch.from_numpy(q[ends - 1] + 1),
        pairs_per_traj=torch.tensor(npairs, dtype=torch.float32),
        init=torch.from_numpy(inverse[np.array(init, dtype=np.int64)]),
        final=torch.from_numpy(inverse[np.array(final, dtype=np.int64)]),
        success=torch.from_numpy(labels.copy()),
        dyn_prev=cat(prev),
        dyn_mid=cat(mid),
        dyn_next=cat(nxt),
    )


# ---------------------------------------------------------------------------- losses
def glide_losses(
    logits: torch.Tensor,
    data: PackedTrajectories,
    feasibility: torch.Tensor,
    weights: GlideLossWeights,
    *,
    psi: ForwardModel | None = None,
    init_mode: int = 0,
    final_mode: int | None = None,
    state_scale: torch.Tensor | None = None,
    dyn_columns: torch.Tensor | None = None,
    dyn_inputs: torch.Tensor | None = None,
    dyn_input_lag: int = 1,
) -> dict[str, torch.Tensor]:
    """Every loss term per head, ``(H,)`` tensors, plus their weighted ``"total"``.

    ``logits`` are the classifier outputs ``(H, N, K)`` on ``data.states``.
    The dynamics loss works on state changes divided by ``state_scale``
    (default 1), so its size does not depend on the units of the state.
    """
    h, _, k = logits.shape
    final_mode = k - 1 if final_mode is None else final_mode
    logp = torch.log_softmax(logits, dim=-1)
    probs = logp.exp()
    zero = logits.new_zeros(h)
    out: dict[str, torch.Tensor] = {}
    if weights.succ > 0 or weights.fail > 0:
        pa, pb = probs[:, data.pair_a], probs[:, data.pair_b]
        f = torch.einsum("hpk,kl,hpl->hp", pa, feasibility, pb)
        cum = torch.nn.functional.pad(torch.cumsum(f.double(), dim=1), (1, 0))
        runs = (cum[:, data.run_end] - cum[:, data.run_start]).float()
        per_traj = logits.new_zeros(h, data.num_trajectories).index_add_(1, data.run_traj, runs)
        has_pairs = data.pairs_per_traj > 0
        succ = data.success & has_pairs
        fail = ~data.success & has_pairs
        mean_f = per_traj / data.pairs_per_traj.clamp_min(1.0)
        out["succ"] = -mean_f[:, succ].mean(1) if succ.any() else zero
        if weights.unfinished_fails > 0:
            per_traj = per_traj - weights.unfinished_fails * (1.0 - probs[:, data.final, final_mode])
            fail = ~data.success
        out["fail"] = per_traj[:, fail].clamp_min(weights.fail_clip).mean(1) if fail.any() else zero
    else:
        out["succ"] = out["fail"] = zero
    out["init"] = -logp[:, data.init, init_mode].mean(1)
    final_states = data.final[data.success] if weights.unfinished_fails > 0 else data.final
    out["final"] = -logp[:, final_states, final_mode].mean(1) if len(final_states) else zero
    if weights.dyn > 0:
        if psi is None:
            raise ValueError("the dynamics loss (weights.dyn > 0) needs a forward model psi")
        if len(data.dyn_mid) == 0:
            out["dyn"] = zero
        else:
            s = data.states if state_scale is None else data.states / state_scale
            s_out = s if dyn_columns is None else s[:, dyn_columns]
            s_in = s_out if dyn_inputs is None else s[:, dyn_inputs]
            if dyn_input_lag == 1:
                delta_in = s_in[data.dyn_mid] - s_in[data.dyn_prev]
            else:
                delta_in = s_in[data.dyn_next] - s_in[data.dyn_mid]
            delta_next = s_out[data.dyn_next] - s_out[data.dyn_mid]
            pred_k = psi(delta_in)  # (H, M, K, d)
            pred = torch.einsum("hmk,hmkd->hmd", probs[:, data.dyn_mid], pred_k)
            out["dyn"] = ((pred - delta_next) ** 2).sum(-1).mean(1)
    else:
        out["dyn"] = zero
    out["total"] = sum(getattr(weights, t) * out[t] for t in LOSS_TERMS)
    return out


# -------------------------------------------------------------------------- training
@dataclass
class GlideTrainResult:
    """A trained classifier and its training record."""

    classifier: ModeClassifier
    psi: ForwardModel | None
    seconds: float
    #: per step: each loss term and the total of the head that was best at that step; ``"heads"``:
    #: every head's total (full weights) every 50 steps and at the last step
    history: dict[str, list[Any]] = field(default_factory=dict)
    head_losses: list[float] = field(default_factory=list)
    config: dict[str, Any] = field(default_factory=dict)


def _check_feasibility(feasibility: Any) -> np.ndarray:
    feas = np.asarray(feasibility, dtype=np.float64)
    if feas.ndim != 2 or feas.shape[0] != feas.shape[1] or feas.shape[0] < 2:
        raise ValueError(f"feasibility must be a square (K, K) matrix with K >= 2, got {feas.shape}")
    if not np.all(np.isfinite(feas)) or np.any(feas > 0):
        raise ValueError("feasibility entries must be finite and <= 0 (0 = feasible move)")
    return feas


_OPTIM_READY = False


def _warm_up_torch_optim() -> None:
    """Build a throw-away Adam once: its first construction imports torch._dynamo (seconds), which
    must not count as training time."""
    global _OPTIM_READY
    if not _OPTIM_READY:
        torch.optim.Adam([nn.Parameter(torch.zeros(1))])
        _OPTIM_READY = True


def _succ_ramp(step: int, steps: int, config: GlideTrainConfig) -> float:
    """Multiplier of the ``L_succ`` weight at ``step`` (geometric warm-up, then 1)."""
    span = config.succ_warmup * steps
    if span <= 0 or step >= span:
        return 1.0
    return float(config.succ_warmup_start ** (1.0 - step / span))


def _keep_heads(
    opt: torch.optim.Optimizer, modules: Sequence[nn.Module], keep: torch.Tensor
) -> tuple[torch.optim.Optimizer, list[nn.Parameter]]:
    """Keep only the heads ``keep`` of the head-batched ``modules``: new parameters, and a new Adam
    that carries on with the kept heads' moments (returns it and the new parameter list)."""
    params: list[nn.Parameter] = []
    moved: list[tuple[nn.Parameter, dict[str, Any]]] = []
    for module in modules:
        for name, old in list(module._parameters.items()):
            if old is None:
                continue
            new = nn.Parameter(old.detach()[keep].clone())
            module._parameters[name] = new
            params.append(new)
            state = opt.state.get(old, {})
            moved.append(
                (new, {k: (v[keep].clone() if k in ("exp_avg", "exp_avg_sq") else v) for k, v in state.items()})
            )
        if isinstance(module, ModeClassifier):
            module.n_heads = len(keep)
    new_opt = torch.optim.Adam(params, lr=opt.param_groups[0]["lr"])
    for param, state in moved:
        if state:
            new_opt.state[param] = state
    return new_opt, params


def train_mode_classifier(
    trajectories: Sequence[np.ndarray],
    success: Sequence[bool] | np.ndarray,
    feasibility: np.ndarray,
    *,
    weights: GlideLossWeights | None = None,
    config: GlideTrainConfig | None = None,
    init_mode: int = 0,
    final_mode: int | None = None,
) -> GlideTrainResult:
    """Fit a :class:`ModeClassifier` to success-labelled trajectories (Adam, CPU).

    Args:
        trajectories: ``(T_i, d)`` state sequences (demos and perturbed replays).
        success: one task-success label per trajectory.
        feasibility: the ``(K, K)`` feasibility matrix; ``K`` is the number of modes.
        weights: loss weights (default: the public code's 1000 / 1 / 10 / 10).
        config: optimisation settings.
        init_mode, final_mode: the plan's first and last mode (default ``0`` and ``K - 1``).

    >>> import numpy as np
    >>> line = np.stack([np.linspace(-1, 1, 21), np.zeros(21)], axis=1)
    >>> feasibility = np.array([[0.0, 0.0], [-1.0, 0.0]])  # mode 1 -> 0 is infeasible
    >>> result = train_mode_classifier(  # a success, and a failure that turns back
    ...     [line, line[::-1][:8]], [True, False], feasibility, config=GlideTrainConfig(epochs=50, n_heads=2))
    >>> result.classifier.predict(np.array([[-1.0, 0.0], [1.0, 0.0]])).tolist(), len(result.head_losses)
    ([0, 1], 2)
    """
    weights = weights or GlideLossWeights()
    config = config or GlideTrainConfig()
    feas = _check_feasibility(feasibility)
    k = feas.shape[0]
    final_mode = k - 1 if final_mode is None else int(final_mode)
    if not (0 <= init_mode < k and 0 <= final_mode < k):
        raise ValueError(f"init_mode and final_mode must be in [0, {k}), got {init_mode}, {final_mode}")
    labels = np.asarray(success, dtype=bool)
    if labels.shape != (len(trajectories),):
        raise ValueError(f"success must have one label per trajectory ({len(trajectories)}), got {labels.shape}")
    _warm_up_torch_optim()
    start = time.perf_counter()
    data = pack_trajectories(trajectories, labels, config.stride)
    # fixed, seeded partition of the trajectories into minibatches, each packed once
    order = np.random.default_rng(config.seed).permutation(len(trajectories))
    n_batches = min(config.n_batches, len(trajectories))
    batches = (
        [data]
        if n_batches == 1
        else [
            pack_trajectories([trajectories[i] for i in part], labels[part], config.stride)
            for part in np.array_split(order, n_batches)
        ]
    )
    steps = config.epochs * len(batches)
    old_threads = torch.get_num_threads()
    if config.num_threads is not None:
        torch.set_num_threads(config.num_threads)
    try:
        clf = ModeClassifier(data.states.shape[1], k, hidden=config.hidden, n_heads=config.n_heads, seed=config.seed)
        clf.set_normalization(data.states.numpy())
        with torch.no_grad():
            clf.b2[:, :, init_mode] += float(config.init_mode_bias)
        psi = None
        params = list(clf.parameters())
        if weights.dyn > 0:
            for name in ("dyn_columns", "dyn_inputs"):
                cols = getattr(config, name)
                if cols is not None and max(cols) >= data.states.shape[1]:
                    raise ValueError(f"{name} {cols} index past the {data.states.shape[1]} state columns")
            d_out = data.states.shape[1] if config.dyn_columns is None else len(config.dyn_columns)
            psi = ForwardModel(
                d_out,
                k,
                n_heads=config.n_heads,
                hidden=config.psi_hidden,
                seed=config.seed,
                input_dim=None if config.dyn_inputs is None else len(config.dyn_inputs),
            )
            params += list(psi.parameters())
        feas_t = torch.as_tensor(feas, dtype=torch.float32)
        loss_kwargs: dict[str, Any] = {
            "psi": psi,
            "init_mode": init_mode,
            "final_mode": final_mode,
            "state_scale": clf.scale,
            "dyn_columns": None if config.dyn_columns is None else torch.tensor(config.dyn_columns),
            "dyn_inputs": None if config.dyn_inputs is None else torch.tensor(config.dyn_inputs),
            "dyn_input_lag": config.dyn_input_lag,
        }
        opt: torch.optim.Optimizer = torch.optim.Adam(params, lr=config.lr)
        lr_min = config.lr * config.lr_final_ratio
        prune_step = round(config.prune_at * steps) if config.prune_to < config.n_heads else -1
        history: dict[str, list[Any]] = {t: [] for t in (*LOSS_TERMS, "total", "heads")}
        b = config.best_head_weight
        bar = progress_bar(range(steps), enabled=config.progress, desc="GLiDE classifier", leave=False)
        for step in bar:
            if step == prune_step:
                with torch.no_grad():
                    ranking = glide_losses(clf(data.states), data, feas_t, weights, **loss_kwargs)["total"]
                opt, params = _keep_heads(
                    opt, [clf] if psi is None else [clf, psi], ranking.argsort()[: config.prune_to]
                )
            for group in opt.param_groups:  # cosine decay from lr to lr_min
                group["lr"] = lr_min + (config.lr - lr_min) * 0.5 * (1.0 + np.cos(np.pi * step / steps))
            batch = batches[step % len(batches)]
            losses = glide_losses(clf(batch.states), batch, feas_t, weights, **loss_kwargs)
            total = losses["total"]
            ramp = _succ_ramp(step, steps, config)
            if ramp < 1.0:  # L_succ warm-up: the optimised objective, not the reported loss
                total = total - (1.0 - ramp) * weights.succ * losses["succ"]
            objective = (1 - b) * total.mean() + b * total.min()
            opt.zero_grad(set_to_none=True)
            objective.backward()
            opt.step()
            best = int(total.argmin())
            for t in (*LOSS_TERMS, "total"):
                history[t].append(float(losses[t][best].detach()))
            if step % 50 == 0 or step == steps - 1:
                history["heads"].append([float(v) for v in losses["total"].detach()])
            if not bar.disable:
                bar.set_postfix(loss=f"{float(total.min().detach()):.4g}")
        with torch.no_grad():
            final = glide_losses(clf(data.states), data, feas_t, weights, **loss_kwargs)["total"]
        clf.head = int(final.argmin())
        clf.eval()
    finally:
        torch.set_num_threads(old_threads)
    return GlideTrainResult(
        classifier=clf,
        psi=psi,
        seconds=time.perf_counter() - start,
        history=history,
        head_losses=[float(v) for v in final],
        config={"weights": asdict(weights), "train": asdict(config), "num_modes": k},
    )


# --------------------------------------------------------------------------- metrics
def workspace_grid(low: np.ndarray, high: np.ndarray, resolution: int = 200) -> np.ndarray:
    """``resolution x resolution`` grid points ``(R*R, 2)`` spanning the box ``[low, high]``.

    >>> workspace_grid(np.zeros(2), np.ones(2), 2).tolist()
    [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]
    """
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or resolution < 2:
        raise ValueError(f"resolution must be an int >= 2, got {resolution!r}")
    lo, hi = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    if lo.shape != (2,) or hi.shape != (2,) or np.any(lo >= hi):
        raise ValueError("low and high must be 2-vectors with low < high")
    xs, ys = np.linspace(lo[0], hi[0], resolution), np.linspace(lo[1], hi[1], resolution)
    gx, gy = np.meshgrid(xs, ys)
    return np.stack([gx.ravel(), gy.ravel()], axis=1)


def mode_overlap(predicted: np.ndarray, truth: np.ndarray) -> float:
    """Fraction of points whose predicted mode equals the true mode (the grounding study's overlap).

    >>> mode_overlap(np.array([0, 1, 1, 2]), np.array([0, 1, 2, 2]))
    0.75
    """
    p, t = np.asarray(predicted), np.asarray(truth)
    if p.shape != t.shape or p.ndim != 1 or len(p) == 0:
        raise ValueError(f"predicted and truth must be equal-length 1-D arrays, got {p.shape} and {t.shape}")
    return float(np.mean(p == t))


def mode_iou(predicted: np.ndarray, truth: np.ndarray, num_modes: int) -> np.ndarray:
    """Per-mode intersection over union ``(K,)`` (stricter than overlap where one mode dominates the grid).

    >>> mode_iou(np.array([0, 1, 1, 2]), np.array([0, 1, 2, 2]), 3).round(2).tolist()
    [1.0, 0.5, 0.5]
    """
    p, t = np.asarray(predicted), np.asarray(truth)
    if p.shape != t.shape:
        raise ValueError(f"predicted and truth must have the same shape, got {p.shape} and {t.shape}")
    out = np.zeros(num_modes)
    for m in range(num_modes):
        union = np.sum((p == m) | (t == m))
        out[m] = np.sum((p == m) & (t == m)) / union if union else 1.0
    return out


__all__ = [
    "LOSS_TERMS",
    "ForwardModel",
    "GlideLossWeights",
    "GlideTrainConfig",
    "GlideTrainResult",
    "ModeClassifier",
    "ModePredictor",
    "PackedTrajectories",
    "glide_losses",
    "label_demonstrations",
    "mode_iou",
    "mode_overlap",
    "pack_trajectories",
    "train_mode_classifier",
    "workspace_grid",
]
