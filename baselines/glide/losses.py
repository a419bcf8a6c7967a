"""GLiDE's loss (thesis §4.2): every term of the mode classifier's differentiable model of task success.

:func:`glide_losses` scores classifier outputs on
:class:`~steer_envs.baselines.glide.packing.PackedTrajectories` with the
feasibility matrix: ``L_succ``, ``L_fail``, ``L_init``, ``L_final`` and
``L_dyn`` per head and their weighted total (the terms are defined in
:mod:`~steer_envs.baselines.glide.classifier`).
"""

from __future__ import annotations

import torch

from steer_envs.baselines.glide.classifier import LOSS_TERMS, ForwardModel, GlideLossWeights
from steer_envs.baselines.glide.packing import PackedTrajectories

__all__ = ["glide_losses"]


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
        out["succ"], out["fail"] = _feasibility_losses(logits, probs, data, feasibility, weights, final_mode)
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
            out["dyn"] = _dynamics_loss(probs, data, psi, state_scale, dyn_columns, dyn_inputs, dyn_input_lag)
    else:
        out["dyn"] = zero
    out["total"] = sum(getattr(weights, t) * out[t] for t in LOSS_TERMS)
    return out


def _feasibility_losses(
    logits: torch.Tensor,
    probs: torch.Tensor,
    data: PackedTrajectories,
    feasibility: torch.Tensor,
    weights: GlideLossWeights,
    final_mode: int,
) -> tuple[torch.Tensor, torch.Tensor]:
    """``L_succ`` and ``L_fail`` per head: the mean feasibility of the mode transitions of successful
    trajectories (negated) and the clipped summed feasibility of failed ones."""
    h = logits.shape[0]
    zero = logits.new_zeros(h)
    pa, pb = probs[:, data.pair_a], probs[:, data.pair_b]
    f = torch.einsum("hpk,kl,hpl->hp", pa, feasibility, pb)
    cum = torch.nn.functional.pad(torch.cumsum(f.double(), dim=1), (1, 0))
    runs = (cum[:, data.run_end] - cum[:, data.run_start]).float()
    per_traj = logits.new_zeros(h, data.num_trajectories).index_add_(1, data.run_traj, runs)
    has_pairs = data.pairs_per_traj > 0
    succ = data.success & has_pairs
    fail = ~data.success & has_pairs
    mean_f = per_traj / data.pairs_per_traj.clamp_min(1.0)
    succ_loss = -mean_f[:, succ].mean(1) if succ.any() else zero
    if weights.unfinished_fails > 0:
        per_traj = per_traj - weights.unfinished_fails * (1.0 - probs[:, data.final, final_mode])
        fail = ~data.success
    fail_loss = per_traj[:, fail].clamp_min(weights.fail_clip).mean(1) if fail.any() else zero
    return succ_loss, fail_loss


def _dynamics_loss(
    probs: torch.Tensor,
    data: PackedTrajectories,
    psi: ForwardModel,
    state_scale: torch.Tensor | None,
    dyn_columns: torch.Tensor | None,
    dyn_inputs: torch.Tensor | None,
    dyn_input_lag: int,
) -> torch.Tensor:
    """``L_dyn`` per head: the squared error of the mode-weighted forward model's next state change."""
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
    return ((pred - delta_next) ** 2).sum(-1).mean(1)
