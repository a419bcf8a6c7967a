"""Training of the GLiDE mode classifier (thesis §4.2): :func:`train_mode_classifier`.

Several heads of :class:`~steer_envs.baselines.glide.classifier.ModeClassifier`
train in parallel on the loss of
:func:`~steer_envs.baselines.glide.losses.glide_losses` (full batch over
the distinct states and transitions of
:func:`~steer_envs.baselines.glide.packing.pack_trajectories`, or a fixed
split into minibatches), with Adam and a cosine-decayed learning rate; the
weight of ``L_succ`` is warmed up geometrically; after a fraction of the
steps only the best few heads train on, and the head with the lowest
*training loss* is kept (see
:class:`~steer_envs.baselines.glide.classifier.GlideTrainConfig`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import torch
from torch import nn

from steer_envs.baselines.glide.classifier import (
    LOSS_TERMS,
    ForwardModel,
    GlideLossWeights,
    GlideTrainConfig,
    ModeClassifier,
)
from steer_envs.baselines.glide.losses import glide_losses
from steer_envs.baselines.glide.packing import PackedTrajectories, pack_trajectories
from steer_envs.core.progress import progress_bar

__all__ = ["GlideTrainResult", "train_mode_classifier"]


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


def _pack_batches(
    trajectories: Sequence[np.ndarray], labels: np.ndarray, config: GlideTrainConfig
) -> tuple[PackedTrajectories, list[PackedTrajectories]]:
    """All trajectories packed, and the minibatches: a fixed, seeded partition, each packed once."""
    data = pack_trajectories(trajectories, labels, config.stride)
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
    return data, batches


def _build_models(
    data: PackedTrajectories, k: int, weights: GlideLossWeights, config: GlideTrainConfig, init_mode: int
) -> tuple[ModeClassifier, ForwardModel | None]:
    """The classifier (inputs standardised on the data, the initial mode's bias raised) and psi when ``L_dyn`` is on."""
    clf = ModeClassifier(data.states.shape[1], k, hidden=config.hidden, n_heads=config.n_heads, seed=config.seed)
    clf.set_normalization(data.states.numpy())
    with torch.no_grad():
        clf.b2[:, :, init_mode] += float(config.init_mode_bias)
    if weights.dyn <= 0:
        return clf, None
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
    return clf, psi


def _optimize(
    clf: ModeClassifier,
    psi: ForwardModel | None,
    data: PackedTrajectories,
    batches: Sequence[PackedTrajectories],
    loss: Any,
    config: GlideTrainConfig,
    weights: GlideLossWeights,
) -> dict[str, list[Any]]:
    """Adam over ``config.epochs`` passes of ``batches`` (``loss(logits, batch)``: the loss terms); the history."""
    params = list(clf.parameters()) + ([] if psi is None else list(psi.parameters()))
    steps = config.epochs * len(batches)
    opt: torch.optim.Optimizer = torch.optim.Adam(params, lr=config.lr)
    lr_min = config.lr * config.lr_final_ratio
    prune_step = round(config.prune_at * steps) if config.prune_to < config.n_heads else -1
    history: dict[str, list[Any]] = {t: [] for t in (*LOSS_TERMS, "total", "heads")}
    b = config.best_head_weight
    bar = progress_bar(range(steps), enabled=config.progress, desc="GLiDE classifier", leave=False)
    for step in bar:
        if step == prune_step:
            with torch.no_grad():
                ranking = loss(clf(data.states), data)["total"]
            opt, params = _keep_heads(opt, [clf] if psi is None else [clf, psi], ranking.argsort()[: config.prune_to])
        for group in opt.param_groups:  # cosine decay from lr to lr_min
            group["lr"] = lr_min + (config.lr - lr_min) * 0.5 * (1.0 + np.cos(np.pi * step / steps))
        batch = batches[step % len(batches)]
        losses = loss(clf(batch.states), batch)
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
    return history


def _checked_inputs(
    trajectories: Sequence[np.ndarray],
    success: Sequence[bool] | np.ndarray,
    feasibility: np.ndarray,
    init_mode: int,
    final_mode: int | None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The feasibility matrix, the success labels and the final mode (default ``K - 1``), checked."""
    feas = _check_feasibility(feasibility)
    k = feas.shape[0]
    final_mode = k - 1 if final_mode is None else int(final_mode)
    if not (0 <= init_mode < k and 0 <= final_mode < k):
        raise ValueError(f"init_mode and final_mode must be in [0, {k}), got {init_mode}, {final_mode}")
    labels = np.asarray(success, dtype=bool)
    if labels.shape != (len(trajectories),):
        raise ValueError(f"success must have one label per trajectory ({len(trajectories)}), got {labels.shape}")
    return feas, labels, final_mode


def _loss_function(
    feas: np.ndarray,
    weights: GlideLossWeights,
    config: GlideTrainConfig,
    clf: ModeClassifier,
    psi: ForwardModel | None,
    modes: tuple[int, int],
) -> Callable[[torch.Tensor, PackedTrajectories], dict[str, torch.Tensor]]:
    """``loss(logits, batch)``: :func:`glide_losses` with the feasibility, weights, models and settings of a run.

    ``modes``: the plan's first and last mode.
    """
    feas_t = torch.as_tensor(feas, dtype=torch.float32)
    loss_kwargs: dict[str, Any] = {
        "psi": psi,
        "init_mode": modes[0],
        "final_mode": modes[1],
        "state_scale": clf.scale,
        "dyn_columns": None if config.dyn_columns is None else torch.tensor(config.dyn_columns),
        "dyn_inputs": None if config.dyn_inputs is None else torch.tensor(config.dyn_inputs),
        "dyn_input_lag": config.dyn_input_lag,
    }

    def loss(logits: torch.Tensor, batch: PackedTrajectories) -> dict[str, torch.Tensor]:
        return glide_losses(logits, batch, feas_t, weights, **loss_kwargs)

    return loss


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
    """Fit a :class:`~steer_envs.baselines.glide.classifier.ModeClassifier` to success-labelled trajectories.

    Adam on the CPU, deterministic given ``config.seed``.

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
    feas, labels, final_mode = _checked_inputs(trajectories, success, feasibility, init_mode, final_mode)
    k = feas.shape[0]
    _warm_up_torch_optim()
    start = time.perf_counter()
    data, batches = _pack_batches(trajectories, labels, config)
    old_threads = torch.get_num_threads()
    if config.num_threads is not None:
        torch.set_num_threads(config.num_threads)
    try:
        clf, psi = _build_models(data, k, weights, config, init_mode)
        loss = _loss_function(feas, weights, config, clf, psi, (init_mode, final_mode))
        history = _optimize(clf, psi, data, batches, loss, config, weights)
        with torch.no_grad():
            final = loss(clf(data.states), data)["total"]
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
