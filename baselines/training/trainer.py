"""Train the Maze2D Diffusion Policy or ACT on a random-walk dataset (thesis §2.4.1).

``python -m steer_envs.baselines.training {dp,act} --data walk.npz --out dp.safetensors --steps N --seed S``

``... dp --preset itps --device cuda --data walk.npz --out dp.safetensors`` trains
ITPS's full-size network and optimizer settings (a GPU job: ~16M parameters,
100k steps at batch 256); ``--model KEY=VALUE`` overrides one architecture
field (``--model down_dims=[32,64,128]``), ``--steps`` etc. the preset's training.

``... {dp,act} --data walk.npz --check dp.json --check-steps 200`` re-runs the
first steps of a recorded run and compares the logged losses (a cheap check
that the committed command reproduces a shipped checkpoint's training).

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

from steer_envs.baselines.act.modeling import ACTConfig, ACTPolicy
from steer_envs.baselines.diffusion.modeling import DiffusionConfig, DiffusionPolicy
from steer_envs.data.maze_random_walk import PlanWindows, RandomWalkDataset, load_random_walk
from steer_envs.io import atomic_write_text
from steer_envs.utils.cli import parse_key_value

__all__ = [
    "KINDS",
    "PRESETS",
    "TrainSettings",
    "build_policy",
    "check_record",
    "main",
    "parse_model_overrides",
    "train_policy",
]

KINDS = ("dp", "act")

#: named (architecture, training) settings per policy kind. ``cpu``: the shipped checkpoints (the
#: config defaults); ``itps``: the public ITPS maze configs (shared/reference/itps.md), sized for a GPU.
#: ``static_history_prob`` stays 0.2 for DP: our suites start the agent at rest.
PRESETS: dict[str, dict[str, dict[str, dict[str, Any]]]] = {
    "cpu": {
        "dp": {"model": {}, "train": {"steps": 30_000}},
        "act": {"model": {}, "train": {"steps": 3_000}},
    },
    "itps": {
        "dp": {
            "model": {
                "down_dims": (128, 256, 512),
                "step_embed_dim": 128,
                "prediction": "epsilon",
                "relative": False,
                "time_channel": False,
                "obs_embed_dim": 0,
            },
            "train": {"steps": 100_000, "batch_size": 256, "lr": 1e-4, "warmup_steps": 500},
        },
        "act": {
            "model": {
                "d_model": 512,
                "n_heads": 8,
                "dim_feedforward": 3200,
                "n_encoder_layers": 4,
                "n_decoder_layers": 1,
                "n_vae_encoder_layers": 4,
            },
            "train": {"steps": 100_000, "batch_size": 256, "lr": 1e-5},
        },
    },
}


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
    ema_power: float = 0.0
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
        if not (math.isfinite(self.ema_power) and 0 <= self.ema_power <= 1):
            raise ValueError(f"ema_power must be in [0, 1] (0 = no EMA), got {self.ema_power!r}")

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
    stop_after: int | None = None,
    raw_weights: dict[str, torch.Tensor] | None = None,
) -> dict[str, Any]:
    """Train ``policy`` in place on windows of ``dataset``; returns the training record (losses, wall time).

    The record's ``losses`` are ``[step, mean loss over the last log_every steps]`` pairs.
    ``stop_after`` ends training after that many steps of the *same* run (the
    learning-rate schedule still spans ``settings.steps``): the prefix of a
    long run, to check a recorded loss curve without paying for all of it.
    With ``settings.ema_power > 0`` the policy ends with the exponential moving
    average of its weights (``diffusers.training_utils.EMAModel``, warm-up
    decay ``1 - (1 + step) ** -power`` capped at 0.9999, as in Diffusion
    Policy); the logged losses are the raw weights' and do not change. Pass a
    dict as ``raw_weights`` to get the raw (un-averaged) state dict as well.
    """
    if not isinstance(policy, (DiffusionPolicy, ACTPolicy)):
        raise TypeError(f"policy must be a DiffusionPolicy or ACTPolicy, got {type(policy).__name__}")
    if not isinstance(settings, TrainSettings):
        raise TypeError(f"settings must be TrainSettings, got {type(settings).__name__}")
    if stop_after is not None and not (isinstance(stop_after, int) and 1 <= stop_after <= settings.steps):
        raise ValueError(
            f"stop_after must be None or an int in [1, settings.steps={settings.steps}], got {stop_after!r}"
        )
    last = settings.steps if stop_after is None else stop_after
    windows = PlanWindows(dataset, **policy.window_layout)
    if len(windows) == 0:
        raise ValueError(f"dataset of {len(dataset)} samples is too short for {policy.window_layout}")
    from diffusers.optimization import get_cosine_schedule_with_warmup

    model = policy.model
    rng = np.random.default_rng(settings.seed)
    gen = torch.Generator(device=policy.device).manual_seed(settings.seed)
    bar = _progress(last, progress)
    losses: list[list[float]] = []
    tic = time.perf_counter()
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(settings.seed)
        opt = torch.optim.AdamW(
            model.parameters(), lr=settings.lr, betas=settings.betas, weight_decay=settings.weight_decay
        )
        sched = get_cosine_schedule_with_warmup(opt, min(settings.warmup_steps, settings.steps), settings.steps)
        ema = None
        if settings.ema_power > 0:
            from diffusers.training_utils import EMAModel

            ema = EMAModel(model.parameters(), decay=0.9999, use_ema_warmup=True, power=settings.ema_power)
        model.train()
        try:
            running = 0.0
            for step in range(1, last + 1):
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
                if ema is not None:
                    ema.step(model.parameters())
                running += loss.item()
                if step % settings.log_every == 0 or step == last:
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
    if raw_weights is not None:
        raw_weights.update({k: v.detach().clone() for k, v in model.state_dict().items()})
    if ema is not None:
        ema.copy_to(model.parameters())
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


def check_record(
    record_path: str | os.PathLike[str], data: str | os.PathLike[str], steps: int = 200, *, progress: bool = False
) -> dict[str, Any]:
    """Re-run the first ``steps`` steps of a recorded training run and compare its logged losses.

    ``record_path`` is a checkpoint's JSON record (:func:`sidecar_path`); the
    model config, settings, seed and thread count come from it. Returns
    ``{"compared": [[step, recorded, rerun], ...], "max_rel_diff": float}``.
    Bit-identical on the same torch version, thread count and CPU kind;
    another CPU's kernels give rounding-level differences that grow slowly.
    """
    summary = json.loads(Path(record_path).read_text())
    try:
        kind, config, record = summary["kind"], summary["model"], summary["training"]
        raw = dict(record["settings"])
    except (KeyError, TypeError) as err:
        raise ValueError(f"{record_path} is not a train_maze record (missing {err})") from None
    raw["betas"] = tuple(raw["betas"])
    settings = TrainSettings(**raw)
    if not isinstance(steps, int) or not 1 <= steps <= settings.steps:
        raise ValueError(f"steps must be an int in [1, {settings.steps}], got {steps!r}")
    dataset = load_random_walk(data)
    for key in ("maze", "seed", "raw_steps", "subsample"):
        if dataset.meta.get(key) != record["data"].get(key):
            raise ValueError(
                f"data {data} has {key}={dataset.meta.get(key)!r}; the record was trained on "
                f"{record['data'].get(key)!r}"
                " (regenerate it with python -m steer_envs.data.maze_random_walk)"
            )
    threads = torch.get_num_threads()
    torch.set_num_threads(int(record.get("threads", threads)))
    try:
        config = {k: tuple(v) if isinstance(v, list) else v for k, v in config.items()}
        policy = build_policy(kind, dataset, seed=settings.seed, **config)
        rerun = train_policy(policy, dataset, settings, progress=progress, stop_after=steps)
    finally:
        torch.set_num_threads(threads)
    recorded = {int(s): float(v) for s, v in record["losses"]}
    compared = [[s, recorded[s], v] for s, v in rerun["losses"] if s in recorded]
    if not compared:
        raise ValueError(f"no logged step <= {steps} to compare (the record logs every {settings.log_every})")
    rel = max(abs(b - a) / max(abs(a), 1e-12) for _, a, b in compared)
    return {"kind": kind, "compared": compared, "max_rel_diff": rel, "wall_s": rerun["wall_s"]}


def _progress(total: int, enabled: bool) -> Any:
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="step", desc="training", mininterval=2.0)


def sidecar_path(checkpoint: str | os.PathLike[str]) -> Path:
    """The JSON record beside a checkpoint: ``x.safetensors`` -> ``x.json``."""
    return Path(checkpoint).with_suffix(".json")


def parse_model_overrides(kind: str, items: list[str] | None) -> dict[str, Any]:
    """``["key=value", ...]`` -> config overrides for ``kind``'s config; values are JSON (else strings).

    Raises ``ValueError`` naming the item when it is not ``key=value`` or the key is not a config field.
    """
    _check_kind(kind)
    fields = set((DiffusionConfig if kind == "dp" else ACTConfig).__dataclass_fields__)
    out: dict[str, Any] = {}
    for item in items or []:
        try:
            key, value = parse_key_value(item)
        except ValueError as err:
            raise ValueError(f"--model {err}") from None
        if key not in fields:
            raise ValueError(f"--model {key}: not a {kind} config field (one of {', '.join(sorted(fields))})")
        out[key] = tuple(value) if isinstance(value, list) else value
    return out


def _check_main(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    try:
        res = check_record(args.check, args.data, args.check_steps, progress=not args.no_progress)
    except (OSError, TypeError, ValueError) as err:
        parser.error(str(err))
    for step, recorded, rerun in res["compared"]:
        print(f"step {step:6d}: recorded {recorded:.6f}  re-run {rerun:.6f}")
    ok = res["max_rel_diff"] <= args.check_rtol
    verdict = "reproduced" if ok else "DIFFERENT"
    print(f"{res['kind']}: {verdict}: max relative difference {res['max_rel_diff']:.2e} (rtol {args.check_rtol:g})")
    return 0 if ok else 1


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(
        prog="python -m steer_envs.baselines.training",
        description="Train the Maze2D Diffusion Policy (dp) or ACT (act) on a random-walk .npz dataset.",
    )
    parser.add_argument("kind", choices=KINDS)
    parser.add_argument("--data", required=True, help="dataset written by python -m steer_envs.data.maze_random_walk")
    parser.add_argument("--out", help="checkpoint path (.safetensors); a .json record goes beside it")
    parser.add_argument(
        "--preset",
        choices=sorted(PRESETS),
        default="cpu",
        help="architecture + training: cpu (the shipped checkpoints, default) or itps (ITPS's full size; a GPU job)",
    )
    parser.add_argument(
        "--model",
        action="append",
        metavar="KEY=VALUE",
        help="override one architecture field of the preset, VALUE as JSON (repeatable), e.g. down_dims=[32,64,128]",
    )
    parser.add_argument("--steps", type=int, help="optimizer steps (default: the preset's)")
    parser.add_argument("--seed", type=int, default=0, help="seed of weights, batches and noise (default 0)")
    parser.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    parser.add_argument("--batch-size", type=int, default=None, help="default 64")
    parser.add_argument("--lr", type=float, default=None, help="peak learning rate (default: dp 2e-3, act 3e-4)")
    parser.add_argument("--warmup-steps", type=int, default=None, help="linear warm-up steps (default 200)")
    parser.add_argument(
        "--ema-power",
        type=float,
        default=None,
        help="save the EMA of the weights with this warm-up power (Diffusion Policy: 0.75; default 0 = no EMA)",
    )
    parser.add_argument("--device", default="cpu", help="torch device, e.g. cuda (default cpu)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument(
        "--check",
        metavar="RECORD",
        help="instead of training: re-run the first --check-steps steps of the run recorded in RECORD "
        "(a checkpoint's .json) on --data and compare the logged losses; exit 1 if they differ",
    )
    parser.add_argument("--check-steps", type=int, default=200, help="steps --check re-runs (default 200)")
    parser.add_argument(
        "--check-rtol", type=float, default=1e-3, help="largest relative loss difference --check accepts (default 1e-3)"
    )
    args = parser.parse_args(argv)
    if args.check is not None:
        return _check_main(parser, args)
    if args.out is None:
        parser.error("--out is required (unless --check)")

    out = Path(args.out)
    if out.suffix != ".safetensors":
        parser.error(f"--out must end with .safetensors, got {args.out!r}")
    if args.threads is not None:
        if args.threads < 1:
            parser.error(f"--threads must be >= 1, got {args.threads}")
        torch.set_num_threads(args.threads)
    try:
        preset = PRESETS[args.preset][args.kind]
        model_config = {**preset["model"], **parse_model_overrides(args.kind, args.model)}
        dataset = load_random_walk(args.data)
        cli = {
            "steps": args.steps,
            "batch_size": args.batch_size,
            "lr": args.lr,
            "warmup_steps": args.warmup_steps,
            "ema_power": args.ema_power,
        }
        settings = TrainSettings.defaults(
            args.kind, **{**preset["train"], **{k: v for k, v in cli.items() if v is not None}}, seed=args.seed
        )
        policy = build_policy(args.kind, dataset, seed=args.seed, device=args.device, **model_config)
    except (TypeError, ValueError) as err:
        parser.error(str(err))
    print(f"{args.kind}: {policy.num_parameters():,} parameters, {len(dataset):,} samples, {settings.steps} steps")
    record = train_policy(policy, dataset, settings, progress=not args.no_progress)
    record["data"]["file"] = Path(args.data).name
    record["preset"] = args.preset
    record["command"] = "python -m steer_envs.baselines.training " + " ".join(
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
