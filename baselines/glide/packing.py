"""GLiDE's training data: success-labelled trajectories flattened into distinct states and transitions.

The mode classifier (:mod:`~steer_envs.baselines.glide.classifier`) trains full
batch on :class:`PackedTrajectories`: every distinct state once, every distinct
transition once, and per trajectory the runs of consecutive distinct
transitions it makes, so the loss sums a trajectory's transition scores with
one cumulative sum (replays share most states and whole stretches of
transitions with their demo).

>>> import numpy as np
>>> still, moving = np.zeros((3, 2)), np.arange(6.0).reshape(3, 2)  # 1 and 3 distinct states
>>> packed = pack_trajectories([still, moving], [True, False])
>>> packed.num_trajectories, len(packed.states), len(packed.pair_a), packed.pairs_per_traj.tolist()
(2, 4, 3, [2.0, 2.0])
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

__all__ = ["PackedTrajectories", "pack_trajectories"]


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
    parts, idx = _subsampled(trajectories, stride)

    # replays share most states with their demo (the tracking controller visits the demo's own
    # waypoints): the classifier runs once per distinct state and pairs index into those
    unique, inverse = np.unique(np.concatenate(parts), axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)

    def cat(xs: list[np.ndarray]) -> torch.Tensor:
        return torch.from_numpy(inverse[np.concatenate(xs).astype(np.int64)])

    pairs = np.stack([cat(idx["a"]).numpy(), cat(idx["b"]).numpy()], axis=1)
    traj_of_pair = np.concatenate(idx["traj"]).astype(np.int64)
    upairs, q, starts, ends = _transition_runs(pairs, traj_of_pair)
    return PackedTrajectories(
        states=torch.from_numpy(np.ascontiguousarray(unique)),
        pair_a=torch.from_numpy(upairs[:, 0].copy()),
        pair_b=torch.from_numpy(upairs[:, 1].copy()),
        run_traj=torch.from_numpy(traj_of_pair[starts]),
        run_start=torch.from_numpy(q[starts]),
        run_end=torch.from_numpy(q[ends - 1] + 1),
        pairs_per_traj=torch.tensor(idx["npairs"], dtype=torch.float32),
        init=torch.from_numpy(inverse[np.array(idx["init"], dtype=np.int64)]),
        final=torch.from_numpy(inverse[np.array(idx["final"], dtype=np.int64)]),
        success=torch.from_numpy(labels.copy()),
        dyn_prev=cat(idx["prev"]),
        dyn_mid=cat(idx["mid"]),
        dyn_next=cat(idx["next"]),
    )


def _subsampled(trajectories: Sequence[np.ndarray], stride: int) -> tuple[list[np.ndarray], dict[str, list[Any]]]:
    """Every trajectory's kept states (float32), and per trajectory the indices of its states in their concatenation.

    The indices: ``a`` / ``b`` of each transition, ``traj`` (the trajectory of each transition),
    ``npairs``, ``init`` / ``final`` (first and last state) and ``prev`` / ``mid`` / ``next`` of
    each interior state (the dynamics loss).
    """
    dim = None
    parts: list[np.ndarray] = []
    idx: dict[str, list[Any]] = {k: [] for k in ("a", "b", "traj", "npairs", "init", "final", "prev", "mid", "next")}
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
        at = np.arange(offset, offset + m)
        parts.append(sub)
        idx["a"].append(at[:-1])
        idx["b"].append(at[1:])
        idx["traj"].append(np.full(m - 1, i))
        idx["npairs"].append(m - 1)
        idx["init"].append(at[0])
        idx["final"].append(at[-1])
        idx["prev"].append(at[:-2])
        idx["mid"].append(at[1:-1])
        idx["next"].append(at[2:])
        offset += m
    return parts, idx


def _transition_runs(
    pairs: np.ndarray, traj_of_pair: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The distinct transitions (in order of first occurrence), each pair's number among them, and the starts and
    ends of the runs of consecutive numbers within one trajectory.

    Whole stretches of transitions recur (a replay repeats its demo before and after the
    perturbation): numbered in order of first occurrence, a stretch shared with an earlier
    trajectory is a run of consecutive numbers, summed per trajectory with one cumulative sum
    over the distinct transitions instead of pair by pair.
    """
    upairs, first, pair_inverse = np.unique(pairs, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    q = rank[pair_inverse.reshape(-1)]
    new_run = np.ones(len(q), dtype=bool)
    new_run[1:] = (q[1:] != q[:-1] + 1) | (traj_of_pair[1:] != traj_of_pair[:-1])
    starts = np.flatnonzero(new_run)
    ends = np.append(starts[1:], len(q))
    return upairs[order], q, starts, ends
