"""Train the Maze2D Diffusion Policy or ACT on a random-walk dataset (thesis §2.4.1).

``python -m steer_envs.baselines.train_maze {dp,act} --data walk.npz --out dp.safetensors --steps N --seed S``

Training is deterministic for a given seed, thread count and device: batches
are drawn by a ``numpy`` generator, diffusion noise / timesteps and the VAE's
reparameterization noise by a ``torch.Generator``, dropout by torch's global
RNG seeded inside ``torch.random.fork_rng`` (the caller's RNG state is left
alone). Optimizer: AdamW with a linear warm-up and cosine decay to 0
(``diffusers.optimization``), gradient-norm clipping. The checkpoint is a
safetensors file; a JSON file beside it (same stem) records the model config,
the training settings, the data's provenance, the loss curve and the wall time.
Both are written atomically.

Data layout (``PlanWindows``): DP conditions on 2 positions and predicts the
64 positions starting at the current one (LeRobot / ITPS); ACT conditions on
the current position and predicts the next 64. With ``static_history_prob`` a
fraction of DP's histories are replaced by the current position repeated, the
history a policy sees right after a reset (the steering suite starts at rest).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from steer_envs.data.maze_random_walk import PlanWindows, RandomWalkDataset, load_random_walk
from steer_envs.io import atomic_write_text

from .act import ACTConfig, ACTPolicy
from .diffusion import DiffusionConfig, DiffusionPolicy

__all__ = ["KINDS", "TrainSettings", "build_policy", "main", "train_policy"]

KINDS = ("dp", "act")


@dataclass(frozen=True)
class TrainSettings:
    """Optimization settings; :meth:`defaults` gives each policy's."""

    steps: int = 1000
    batch_size: int = 64
    lr: float = 1e-3
    weight_decay: float = 1e-6
    betas: tuple[float, float] = (0.95, 0.999)
    warmup_steps: int = 200
    grad_clip: float = 10.0
    static_history_prob: float = 0.0
    seed: int = 0
    log_every: int = 50

    def __post_init__(self) -> None:
        for name in ("steps", "batch_size", "warmup_steps", "seed", "log_every"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise TypeError(f"{name} must be an int, got {type(value).__name__}")
        if self.steps < 1 or self.batch_size < 1 or self.log_every < 1:
            raise ValueError("steps, batch_size and log_every must be >= 1")
        if self.warmup_steps < 0 or self.seed < 0:
            raise ValueError("warmup_steps and seed must be >= 0")
        for name in ("lr", "grad_clip"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite float, got {value!r}")
        if not (math.isfinite(self.weight_decay) and self.weight_decay >= 0):
            raise ValueError(f"weight_decay must be a finite float >= 0, got {self.weight_decay!r}")
        if not 0 <= self.static_history_prob <= 1:
            raise ValueError(f"static_history_prob must be in [0, 1], got {self.static_history_prob!r}")

    @staticmethod
    def defaults(kind: str, **overrides: Any) -> TrainSettings:
        """Per-policy defaults: DP AdamW 2e-3 (betas 0.95/0.999, wd 1e-6: ITPS but the lr); ACT AdamW 3e-4, wd 1e-4."""
        _check_kind(kind)
        base: dict[str, Any] = (
            {"lr": 2e-3, "weight_decay": 1e-6, "betas": (0.95, 0.999), "static_history_prob": 0.2}
            if kind == "dp"
            else {"lr": 3e-4, "weight_decay": 1e-4, "betas": (0.9, 0.999), "static_history_prob": 0.0}
        )
        base.update({k: v for k, v in overrides.items() if v is not None})
        return TrainSettings(**base)


def _check_kind(kind: str) -> None:
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")


def build_policy(
    kind: str, dataset: RandomWalkDataset, *, seed: int = 0, device: str = "cpu", **config: Any
) -> DiffusionPolicy | ACTPolicy:
    """A fresh policy whose normalization is fitted to ``dataset`` (DP: min-max; ACT: mean/std of positions)."""
    _check_kind(kind)
    if not isinstance(dataset, RandomWalkDataset):
        raise TypeError(f"dataset must be a RandomWalkDataset, got {type(dataset).__name__}")
    pts = np.concatenate([dataset.xy, dataset.actions]).astype(np.float64)
    if kind == "dp":
        low, high = dataset.xy_bounds()
        return DiffusionPolicy(DiffusionConfig(**config), low, high, seed=seed, device=device)
    return ACTPolicy(ACTConfig(**config), pts.mean(axis=0), pts.std(axis=0), seed=seed, device=device)


def train_policy(
    policy: DiffusionPolicy | ACTPolicy,
    dataset: RandomWalkDataset,
    settings: TrainSettings,
    *,
    progress: bool = True,
) -> dict[str, Any]:
    """Train ``policy`` in place on windows of ``dataset``; returns the training record (losses, wall time).

    The record's ``losses`` are ``[step, mean loss over the last log_every steps]`` pairs.
    """
    if not isinstance(policy, (DiffusionPolicy, ACTPolicy)):
        raise TypeError(f"policy must be a DiffusionPolicy or ACTPolicy, got {type(policy).__name__}")
    if not isinstance(settings, TrainSettings):
        raise TypeError(f"settings must be TrainSettings, got {type(settings).__name__}")
    windows = PlanWindows(dataset, **policy.window_layout)
    if len(windows) == 0:
        raise ValueError(f"dataset of {len(dataset)} samples is too short for {policy.window_layout}")
    from diffusers.optimization import get_cosine_schedule_with_warmup

    model = policy.model
    rng = np.random.default_rng(settings.seed)
    gen = torch.Generator(device=policy.device).manual_seed(settings.seed)
    bar = _progress(settings.steps, progress)
    losses: list[list[float]] = []
    tic = time.perf_counter()
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(settings.seed)
        opt = torch.optim.AdamW(
            model.parameters(), lr=settings.lr, betas=settings.betas, weight_decay=settings.weight_decay
        )
        sched = get_cosine_schedule_with_warmup(opt, min(settings.warmup_steps, settings.steps), settings.steps)
        model.train()
        try:
            running = 0.0
            for step in range(1, settings.steps + 1):
                obs, plans = windows.gather(rng.integers(len(windows), size=settings.batch_size))
                if settings.static_history_prob > 0 and obs.shape[1] > 1:
                    still = rng.random(len(obs)) < settings.static_history_prob
                    obs[still] = obs[still, -1:]
                loss = policy.loss(torch.from_numpy(obs), torch.from_numpy(plans), gen)
                if not torch.isfinite(loss):
                    raise FloatingPointError(f"training loss became {loss.item()} at step {step}")
                opt.zero_grad(set_to_none=True)
                loss.backward()
                torch.nn.utils.clip_grad_norm_(model.parameters(), settings.grad_clip)
                opt.step()
                sched.step()
                running += loss.item()
                if step % settings.log_every == 0 or step == settings.steps:
                    n = step - (losses[-1][0] if losses else 0)
                    losses.append([step, running / n])
                    running = 0.0
                    if bar is not None:
                        bar.set_postfix(loss=f"{losses[-1][1]:.4f}")
                if bar is not None:
                    bar.update(1)
        finally:
            model.eval()
            if bar is not None:
                bar.close()
    return {
        "settings": {**asdict(settings), "betas": list(settings.betas)},
        "losses": losses,
        "final_loss": losses[-1][1],
        "wall_s": round(time.perf_counter() - tic, 1),
        "threads": torch.get_num_threads(),
        "device": str(policy.device),
        "torch": torch.__version__,
        "windows": len(windows),
        "data": {k: dataset.meta.get(k) for k in ("format", "maze", "seed", "raw_steps", "subsample")},
    }


def _progress(total: int, enabled: bool) -> Any:
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="step", desc="training", mininterval=2.0)


def sidecar_path(checkpoint: str | os.PathLike[str]) -> Path:
    """The JSON record beside a checkpoint: ``x.safetensors`` -> ``x.json``."""
    return Path(checkpoint).with_suffix(".json")


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(
        prog="python -m steer_envs.baselines.train_maze",
        description="Train the Maze2D Diffusion Policy (dp) or ACT (act) on a random-walk .npz dataset.",
    )
    parser.add_argument("kind", choices=KINDS)
    parser.add_argument("--data", required=True, help="dataset written by python -m steer_envs.data.maze_random_walk")
    parser.add_argument("--out", required=True, help="checkpoint path (.safetensors); a .json record goes beside it")
    parser.add_argument("--steps", type=int, required=True, help="optimizer steps")
    parser.add_argument("--seed", type=int, default=0, help="seed of weights, batches and noise (default 0)")
    parser.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    parser.add_argument("--batch-size", type=int, default=None, help="default 64")
    parser.add_argument("--lr", type=float, default=None, help="peak learning rate (default: dp 2e-3, act 3e-4)")
    parser.add_argument("--warmup-steps", type=int, default=None, help="linear warm-up steps (default 200)")
    parser.add_argument("--device", default="cpu", help="torch device, e.g. cuda (default cpu)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    args = parser.parse_args(argv)

    out = Path(args.out)
    if out.suffix != ".safetensors":
        parser.error(f"--out must end with .safetensors, got {args.out!r}")
    if args.threads is not None:
        if args.threads < 1:
            parser.error(f"--threads must be >= 1, got {args.threads}")
        torch.set_num_threads(args.threads)
    try:
        dataset = load_random_walk(args.data)
        settings = TrainSettings.defaults(
            args.kind,
            steps=args.steps,
            seed=args.seed,
            batch_size=args.batch_size,
            lr=args.lr,
            warmup_steps=args.warmup_steps,
        )
        policy = build_policy(args.kind, dataset, seed=args.seed, device=args.device)
    except (TypeError, ValueError) as err:
        parser.error(str(err))
    print(f"{args.kind}: {policy.num_parameters():,} parameters, {len(dataset):,} samples, {settings.steps} steps")
    record = train_policy(policy, dataset, settings, progress=not args.no_progress)
    record["data"]["file"] = Path(args.data).name
    record["command"] = "python -m steer_envs.baselines.train_maze " + " ".join(
        argv if argv is not None else sys.argv[1:]
    )
    policy.save(out, extra={"final_loss": record["final_loss"], "steps": settings.steps, "seed": settings.seed})
    summary = {"kind": args.kind, "model": policy.config.to_dict(), "training": record}
    atomic_write_text(sidecar_path(out), json.dumps(summary, indent=1) + "\n")
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB) and {sidecar_path(out).name}: ", end="")
    print(f"final loss {record['final_loss']:.4f}, {record['wall_s']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
