"""A training run's full state in one safetensors file, so a stopped run continues bit-identically.

The state holds everything a training step changes: the network's weights,
AdamW's moments, the learning-rate schedule, the EMA of the weights, the step,
the loss log, and the three random streams (numpy's batch order, the torch
generator of the diffusion noise, torch's global RNG for dropout). It is one
file, replaced atomically, read back only after every tensor has been checked
against the network and optimizer it is loaded into (:class:`CheckpointError`
naming the file otherwise), and after the sha256 of its tensors has been
checked (a state damaged on disk is refused, not trained on). Loading runs
no code: tensors through safetensors, the rest as JSON in its header.

A *run folder* (``--run-dir`` of :mod:`steer_envs.baselines.training`) holds
:data:`RUN_FILE`, what is trained on what, and :data:`STATE_FILE`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from steer_envs.baselines.common.checkpoint import check_state, read_safetensors, write_safetensors
from steer_envs.baselines.common.configuration import TrainSettings
from steer_envs.core.validation import integer
from steer_envs.io import CheckpointError
from steer_envs.utils.threads import MAX_THREADS

__all__ = [
    "RUN_FILE",
    "RUN_FORMAT",
    "STATE_FILE",
    "STATE_FORMAT",
    "RunProgress",
    "TrainingParts",
    "check_device_kind",
    "check_losses",
    "load_state",
    "save_state",
]

#: the run folder's description (policy, config, settings, data, output) and its format tag
RUN_FILE = "run.json"
RUN_FORMAT = "steer_envs.training_run/1"
#: the run folder's latest training state and its format tag (the safetensors metadata key)
STATE_FILE = "state.safetensors"
STATE_FORMAT = "steer_envs.training_state/1"
#: the device kind of a torch generator by the size of its state (for states saved before it was kept)
_GENERATOR_KIND_BY_SIZE = {5056: "cpu", 16: "cuda"}
#: the most logged loss points a training record may hold
MAX_LOSSES = 10**7
#: what to do about a state whose bytes changed after it was saved
_DAMAGED_STATE = (
    "the run cannot continue from it: restore it from a copy, or delete it and `--resume` the run folder to "
    "train again from step 0"
)


@dataclass
class RunProgress:
    """Where a run stands between two steps: the last finished step and what was logged so far.

    ``running`` is the loss sum since the last logged step; ``wall_s`` the
    training time of earlier segments; ``resumed_at`` the steps at which
    earlier segments stopped; ``threads`` the torch threads of the first
    segment (what a check of the run replays; 0 in states saved before it was
    kept); ``moved_at`` the steps after which the run continued on another
    kind of device (a CUDA run resumed on the CPU, say): its diffusion-noise
    generator then restarts from ``(seed, step)``, so from there on the run no
    longer matches an uninterrupted one; ``first_device`` the device kind of
    the first segment (``""`` in states saved before it was kept).
    """

    step: int = 0
    losses: list[list[float]] = field(default_factory=list)
    running: float = 0.0
    wall_s: float = 0.0
    resumed_at: list[int] = field(default_factory=list)
    threads: int = 0
    moved_at: list[int] = field(default_factory=list)
    first_device: str = ""


def check_losses(value: Any) -> list[list[float]]:
    """``value`` as ``[[step, loss], ...]`` with increasing int steps >= 1 and finite losses; else an error."""
    if not isinstance(value, list) or len(value) > MAX_LOSSES:
        raise TypeError(f"'losses' must be a list of [step, loss] pairs, got {type(value).__name__}")
    out: list[list[float]] = []
    for item in value:
        if not (isinstance(item, list) and len(item) == 2):
            raise TypeError(f"'losses' entries must be [step, loss] pairs, got {item!r}")
        step = integer(item[0], "losses step", low=1)
        loss = item[1]
        if isinstance(loss, bool) or not isinstance(loss, (int, float)) or not math.isfinite(loss):
            raise ValueError(f"'losses' values must be finite numbers, got {loss!r} at step {step}")
        if out and step <= out[-1][0]:
            raise ValueError(f"'losses' steps must increase, got {step} after {out[-1][0]}")
        out.append([step, float(loss)])
    return out


def _params(optimizer: torch.optim.Optimizer) -> list[torch.Tensor]:
    return [p for group in optimizer.param_groups for p in group["params"]]


@dataclass
class TrainingParts:
    """The objects a training step changes (besides :class:`RunProgress`): what a state is saved from and loaded into.

    ``ema`` is diffusers' ``EMAModel`` or ``None``; ``rng`` draws the batches,
    ``generator`` the diffusion noise.
    """

    model: torch.nn.Module
    optimizer: torch.optim.Optimizer
    scheduler: torch.optim.lr_scheduler.LRScheduler
    ema: Any | None
    rng: np.random.Generator
    generator: torch.Generator


def save_state(
    path: str | os.PathLike[str], *, settings: TrainSettings, progress: RunProgress, parts: TrainingParts
) -> Path:
    """Write the state after ``progress.step`` atomically (see the module docstring); returns the path."""
    model, optimizer, scheduler, ema = parts.model, parts.optimizer, parts.scheduler, parts.ema
    tensors: dict[str, torch.Tensor] = {f"model.{k}": v.detach().cpu() for k, v in model.state_dict().items()}
    opt_state = optimizer.state_dict()
    for index, entry in opt_state["state"].items():
        for key, value in entry.items():
            tensors[f"optim.{index}.{key}"] = value.detach().cpu()
    ema_meta = None
    if ema is not None:
        ema_state = ema.state_dict()
        for i, shadow in enumerate(ema_state.pop("shadow_params")):
            tensors[f"ema.{i}"] = shadow.detach().cpu()
        ema_meta = ema_state
    tensors["torch_generator"] = parts.generator.get_state()
    tensors["torch_rng"] = torch.get_rng_state()
    meta = {
        "generator_device": parts.generator.device.type,
        "format": STATE_FORMAT,
        "settings": settings.to_dict(),
        "step": progress.step,
        "losses": progress.losses,
        "running": progress.running,
        "wall_s": progress.wall_s,
        "resumed_at": progress.resumed_at,
        "threads": progress.threads,
        "moved_at": progress.moved_at,
        "first_device": progress.first_device,
        "param_groups": opt_state["param_groups"],
        "scheduler": scheduler.state_dict(),
        "ema": ema_meta,
        "numpy_rng": parts.rng.bit_generator.state,
    }
    return write_safetensors(path, {k: v.contiguous() for k, v in tensors.items()}, "training_state", meta)


def _expected_tensors(model: torch.nn.Module, optimizer: torch.optim.Optimizer, ema: Any | None) -> dict[str, Any]:
    """The names, shapes and dtypes the state of this network and optimizer must hold."""
    expected: dict[str, Any] = {f"model.{k}": v for k, v in model.state_dict().items()}
    params = _params(optimizer)
    for i, p in enumerate(params):
        expected[f"optim.{i}.step"] = torch.empty((), dtype=torch.float32)
        expected[f"optim.{i}.exp_avg"] = torch.empty_like(p, device="cpu")
        expected[f"optim.{i}.exp_avg_sq"] = torch.empty_like(p, device="cpu")
    if ema is not None:
        for i, p in enumerate(params):
            expected[f"ema.{i}"] = torch.empty_like(p, device="cpu")
    return expected


def load_state(path: str | os.PathLike[str], *, settings: TrainSettings, parts: TrainingParts) -> RunProgress:
    """Restore the state in ``path`` into ``parts`` (built as for a fresh run); returns the progress.

    :class:`CheckpointError` naming the file when it is not a training state,
    was saved with other settings, or does not fit the network, optimizer or
    RNGs; nothing is changed then except what the error names.
    """
    src = Path(path)
    tensors, meta = read_safetensors(src, "training_state", remedy=_DAMAGED_STATE)
    try:
        progress = _saved_progress(meta, settings, has_ema=parts.ema is not None)
    except (KeyError, TypeError, ValueError) as err:
        what = f"missing {err}" if isinstance(err, KeyError) else str(err)
        raise CheckpointError(f"{src}: not a training state of this run ({what})") from None
    model, optimizer, ema = parts.model, parts.optimizer, parts.ema
    check_state(_expected_tensors(model, optimizer, ema), {k: v for k, v in tensors.items() if "." in k}, str(src))
    try:
        _restore_training(parts, tensors, meta)
        _restore_generators(parts, tensors, meta, settings, progress)
    except (KeyError, TypeError, ValueError, RuntimeError) as err:
        raise CheckpointError(f"{src}: the training state does not fit this run ({err})") from None
    return progress


def _saved_progress(meta: dict[str, Any], settings: TrainSettings, *, has_ema: bool) -> RunProgress:
    """The progress a state's metadata records, checked against this run's ``settings`` (and EMA or not)."""
    if meta.get("format") != STATE_FORMAT:
        raise ValueError(f"format {meta.get('format')!r}, expected {STATE_FORMAT!r}")
    saved = TrainSettings.from_dict(meta["settings"])
    if saved != settings:
        changed = sorted(k for k, v in settings.to_dict().items() if saved.to_dict().get(k) != v)
        raise ValueError(f"it was saved by a run with other training settings (differ: {', '.join(changed)})")
    progress = RunProgress(
        step=integer(meta["step"], "step", low=1, high=settings.steps),
        losses=check_losses(meta["losses"]),
        running=_finite(meta["running"], "running"),
        wall_s=_finite(meta["wall_s"], "wall_s"),
        resumed_at=[integer(s, "resumed_at entry", low=1, high=settings.steps) for s in meta["resumed_at"]],
        threads=integer(meta.get("threads", 0), "threads", low=0, high=MAX_THREADS),
        moved_at=[integer(s, "moved_at entry", low=1, high=settings.steps) for s in meta.get("moved_at", [])],
        first_device=check_device_kind(meta.get("first_device", "")),
    )
    if progress.losses and progress.losses[-1][0] > progress.step:
        raise ValueError(f"losses logged up to step {progress.losses[-1][0]}, after the state's {progress.step}")
    if (meta["ema"] is None) != (not has_ema):
        raise ValueError("the EMA of the weights is " + ("missing" if has_ema else "unexpected"))
    return progress


def _restore_training(parts: TrainingParts, tensors: dict[str, torch.Tensor], meta: dict[str, Any]) -> None:
    """Load the weights, the optimizer's moments and groups, the LR schedule and the EMA into ``parts``."""
    model, optimizer, ema = parts.model, parts.optimizer, parts.ema
    model.load_state_dict({k[len("model.") :]: v for k, v in tensors.items() if k.startswith("model.")})
    groups = meta["param_groups"]
    for group in groups:
        if "betas" in group:
            group["betas"] = tuple(group["betas"])
    state = {
        i: {key: tensors[f"optim.{i}.{key}"] for key in ("step", "exp_avg", "exp_avg_sq")}
        for i in range(len(_params(optimizer)))
    }
    optimizer.load_state_dict({"state": state, "param_groups": groups})
    parts.scheduler.load_state_dict(meta["scheduler"])
    if ema is not None:
        n = len(_params(optimizer))
        ema.load_state_dict({**meta["ema"], "shadow_params": [tensors[f"ema.{i}"] for i in range(n)]})


def _restore_generators(
    parts: TrainingParts,
    tensors: dict[str, torch.Tensor],
    meta: dict[str, Any],
    settings: TrainSettings,
    progress: RunProgress,
) -> None:
    """Restore the batch RNG, the noise generator (reseeded when saved on another device kind) and torch's RNG."""
    parts.rng.bit_generator.state = meta["numpy_rng"]
    saved_kind = meta.get("generator_device") or _GENERATOR_KIND_BY_SIZE.get(tensors["torch_generator"].numel())
    if saved_kind is not None and not isinstance(saved_kind, str):
        raise TypeError(f"'generator_device' must be a device name, got {saved_kind!r}")
    if saved_kind in (None, parts.generator.device.type):
        parts.generator.set_state(tensors["torch_generator"])
    else:  # saved by a generator of another device kind: its state cannot carry over
        seed = np.random.SeedSequence([settings.seed, progress.step]).generate_state(1)[0]
        parts.generator.manual_seed(int(seed))
        progress.moved_at.append(progress.step)
    torch.set_rng_state(tensors["torch_rng"])


def check_device_kind(value: Any) -> str:
    """A device kind (``"cpu"``, ``"cuda"``, ...) or ``""`` (not kept); ``TypeError`` naming ``first_device``."""
    if not isinstance(value, str) or not (value == "" or value.isidentifier()):
        raise TypeError(f"'first_device' must be a device kind such as 'cpu', got {value!r}")
    return value


def _finite(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{name!r} must be a finite number, got {value!r}")
    return float(value)
