"""The training CLI: ``python -m steer_envs.baselines.training`` (see :mod:`~steer_envs.baselines.training.trainer`).

``python -m steer_envs.baselines.training --policy dp --dataset FILE --preset cpu --out dp.safetensors``

* ``--preset NAME``: a registered (model config, training settings) pair of
  the policy (:func:`steer_envs.baselines.factory.get_preset`);
* ``--model KEY=VALUE``: override one config field (``down_dims=[32,64,128]``);
  ``--train KEY=VALUE`` or ``--steps``, ``--lr``, ... one training setting;
* ``--dataset``: a :mod:`steer_envs.data.trajectories` file, a Maze2D random walk, or another library's
  dataset: ``lerobot:DIR``, ``robomimic:FILE``, ``minari:ID`` (:func:`~steer_envs.data.datasets.load_dataset`).

``--run-dir DIR`` makes a run resumable (its full state saved in ``DIR`` every
``--save-every`` seconds and on SIGINT / SIGTERM); ``--resume DIR`` continues
it, ending with the weights an uninterrupted run would have; ``--resume DIR
--snapshot`` writes the weights it has reached so far (to evaluate a long run
on the way) without training. ``--precision
bf16``, ``--fused-optimizer`` and ``--compile`` trade exact reproduction of
an fp32 run for speed (they are recorded, so ``--check`` replays them).

``... --policy dp --dataset FILE --check dp.json --check-steps 200`` re-runs
the first steps of the run recorded in ``dp.json`` and compares the logged
losses (a cheap check that a recorded command reproduces a checkpoint).
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from steer_envs.baselines.common.checkpoint import read_record as read_record_file
from steer_envs.baselines.common.checkpoint import write_record
from steer_envs.baselines.common.configuration import PRECISIONS, TrainSettings
from steer_envs.baselines.common.torch_policy import TorchPolicy
from steer_envs.baselines.factory import get_policy_class, get_preset, make_policy, policy_names
from steer_envs.baselines.training.run_state import RUN_FILE, RUN_FORMAT
from steer_envs.baselines.training.trainer import (
    CROSS_DEVICE_RTOL,
    TrainingInterrupted,
    check_record,
    require_same_data,
    save_trained,
    sidecar_path,
    snapshot_run,
    train_policy,
)
from steer_envs.data.datasets import canonical_dataset, load_dataset
from steer_envs.data.trajectories import TrajectoryDataset
from steer_envs.io import CheckpointError
from steer_envs.utils.cli import parse_key_value
from steer_envs.utils.threads import MAX_THREADS

__all__ = ["PROG", "main", "parse_overrides"]

PROG = "python -m steer_envs.baselines.training"


def parse_overrides(items: list[str] | None, fields: set[str], flag: str) -> dict[str, Any]:
    """``["key=value", ...]`` -> overrides; values are JSON (else strings), JSON lists become tuples.

    ``ValueError`` naming ``flag`` and the item when it is not ``key=value`` or
    ``key`` is not in ``fields``.

    >>> parse_overrides(["down_dims=[8,16]", "relative=false"], {"down_dims", "relative"}, "--model")
    {'down_dims': (8, 16), 'relative': False}
    """
    out: dict[str, Any] = {}
    for item in items or []:
        try:
            key, value = parse_key_value(item)
        except ValueError as err:
            raise ValueError(f"{flag} {err}") from None
        if key not in fields:
            raise ValueError(f"{flag} {key}: not a field (one of {', '.join(sorted(fields))})")
        out[key] = tuple(value) if isinstance(value, list) else value
    return out


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Train a trajectory policy (Diffusion Policy, ACT) on a trajectory dataset, "
        "continue a stopped run, or check that a recorded training run reproduces.",
    )
    _add_run_arguments(parser)
    _add_training_arguments(parser)
    _add_check_arguments(parser)
    return parser


def _add_run_arguments(parser: argparse.ArgumentParser) -> None:
    """What to train on, where it goes, and the resumable-run flags."""
    parser.add_argument("--policy", choices=policy_names(), help="policy to train (with --check: optional)")
    parser.add_argument(
        "--dataset",
        metavar="DATA",
        help="training data: a steer_envs.data.trajectories .npz, a maze2d random walk "
        "(python -m steer_envs.data.maze_random_walk), lerobot:DIR (a LeRobotDataset), robomimic:FILE (an HDF5 "
        "file) or minari:ID (a local Minari dataset); with --resume: default the run's own",
    )
    parser.add_argument(
        "--out", help="checkpoint path (.safetensors); a .json record goes beside it (default with --run-dir: in it)"
    )
    parser.add_argument(
        "--run-dir",
        metavar="DIR",
        help="make the run resumable: its full state is saved in DIR every --save-every seconds and on "
        "SIGINT / SIGTERM; continue it with --resume DIR",
    )
    parser.add_argument(
        "--resume",
        metavar="DIR",
        help="continue the run in DIR (started with --run-dir); it ends with the weights an uninterrupted run "
        "would have. Takes only --dataset, --threads, --save-every, --no-progress, --snapshot, and --out and --device "
        "(a run moved to another kind of device restarts its noise generator there, see run_state)",
    )
    parser.add_argument(
        "--snapshot",
        action="store_true",
        help="with --resume: write the weights the run has reached so far (default --out: "
        "DIR/snapshot-step<N>.safetensors) and exit, without training; the run may be going on",
    )
    parser.add_argument(
        "--save-every", type=float, default=300.0, metavar="SECONDS", help="state save interval (default 300)"
    )


def _add_training_arguments(parser: argparse.ArgumentParser) -> None:
    """The preset, its overrides and the run's device, threads and progress bar."""
    parser.add_argument(
        "--preset",
        help="registered (model, training) preset of the policy, e.g. cpu (the shipped checkpoints, default) "
        "or itps (ITPS's full size; a GPU job)",
    )
    parser.add_argument(
        "--model",
        action="append",
        metavar="KEY=VALUE",
        help="override one field of the preset's model config, VALUE as JSON (repeatable), e.g. down_dims=[32,64]",
    )
    parser.add_argument(
        "--train",
        action="append",
        metavar="KEY=VALUE",
        help="override one training setting, VALUE as JSON (repeatable), e.g. static_history_prob=0",
    )
    parser.add_argument("--steps", type=int, help="optimizer steps (default: the preset's)")
    parser.add_argument("--seed", type=int, default=None, help="seed of weights, batches and noise (default 0)")
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="torch CPU threads (default 1: on a machine doing anything else, more threads are often slower)",
    )
    parser.add_argument("--batch-size", type=int, default=None, help="default: the preset's")
    parser.add_argument("--lr", type=float, default=None, help="peak learning rate (default: the preset's)")
    parser.add_argument("--warmup-steps", type=int, default=None, help="linear warm-up steps (default: the preset's)")
    parser.add_argument(
        "--ema-power",
        type=float,
        default=None,
        help="save the EMA of the weights with this warm-up power (Diffusion Policy: 0.75; default 0 = no EMA)",
    )
    parser.add_argument(
        "--precision", choices=PRECISIONS, default=None, help="bf16: bfloat16 autocast forward (default: the preset's)"
    )
    parser.add_argument("--fused-optimizer", action="store_true", default=None, help="torch's fused AdamW kernel")
    parser.add_argument("--compile", action="store_true", default=None, help="train a torch.compile of the network")
    parser.add_argument(
        "--device", default=None, help="torch device, e.g. cuda (default cpu; with --resume: the run's)"
    )
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show a progress bar (default: only when stderr is a terminal)",
    )


def _add_check_arguments(parser: argparse.ArgumentParser) -> None:
    """``--check``: replay the start of a recorded run instead of training."""
    parser.add_argument(
        "--check",
        metavar="RECORD",
        help="instead of training: re-run the first --check-steps steps of the run recorded in RECORD "
        "(a checkpoint's .json) on --dataset and compare the logged losses; exit 1 if they differ",
    )
    parser.add_argument("--check-steps", type=int, default=200, help="steps --check re-runs (default 200)")
    parser.add_argument(
        "--check-rtol", type=float, default=1e-3, help="largest relative loss difference --check accepts (default 1e-3)"
    )


#: the flags that define a run: --resume takes them from the run folder instead
_RUN_FLAGS = (
    "policy",
    "preset",
    "out",
    "run_dir",
    "model",
    "train",
    "steps",
    "seed",
    "batch_size",
    "lr",
    "warmup_steps",
    "ema_power",
    "precision",
    "fused_optimizer",
    "compile",
    "device",
)

#: run flags --resume may change: where the weights go, and the device the rest of the run trains on
_RESUME_OVERRIDES = ("out", "device")


def _check_main(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    if args.dataset is None:
        parser.error("--dataset is required")
    try:
        res = check_record(args.check, args.dataset, args.check_steps, policy=args.policy, progress=args.progress)
    except (OSError, TypeError, ValueError) as err:
        parser.error(str(err))
    for step, recorded, rerun in res["compared"]:
        print(f"step {step:6d}: recorded {recorded:.6f}  re-run {rerun:.6f}")
    rtol = args.check_rtol
    if res["cross_device"] is not None:
        rtol = max(rtol, CROSS_DEVICE_RTOL)
        print(
            f"the recorded run started on {res['cross_device']}: its noise stream cannot be replayed on the CPU, "
            f"so this checks the recipe, not the bits (rtol {rtol:g})"
        )
    ok = res["max_rel_diff"] <= rtol
    verdict = "reproduced" if ok else "DIFFERENT"
    print(f"{res['policy']}: {verdict}: max relative difference {res['max_rel_diff']:.2e} (rtol {rtol:g})")
    return 0 if ok else 1


def _unwritable(out: Path) -> str | None:
    """Why ``out`` cannot be written (checked before training, so a long run is not lost), or ``None``."""
    if out.is_dir():
        return "is a folder"
    folder = out.parent
    while not folder.exists():
        if folder.is_symlink():
            return f"{folder} is a broken link"
        folder = folder.parent
    if not folder.is_dir():
        return f"{folder} is not a folder"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"{folder} is not writable"
    return None


def _new_run(parser: argparse.ArgumentParser, args: argparse.Namespace, argv: list[str]) -> dict[str, Any]:
    """The description of a run from the command line (what --resume reads back from ``run.json``)."""
    if args.policy is None:
        parser.error("--policy is required (unless --check or --resume)")
    if args.dataset is None:
        parser.error("--dataset is required (unless --resume)")
    if args.out is None and args.run_dir is None:
        parser.error("--out is required (unless --check, --resume or --run-dir)")
    if args.run_dir is not None and (Path(args.run_dir) / RUN_FILE).exists():
        parser.error(f"--run-dir {args.run_dir!r} holds a run already: continue it with --resume {args.run_dir}")
    out = Path(args.out) if args.out is not None else Path(args.run_dir) / f"{args.policy}.safetensors"
    preset_name = args.preset or "cpu"
    try:
        preset = get_preset(args.policy, preset_name)
        config = preset.model.replace(**parse_overrides(args.model, preset.model.field_names(), "--model"))
        flags = {
            "steps": args.steps,
            "batch_size": args.batch_size,
            "lr": args.lr,
            "warmup_steps": args.warmup_steps,
            "ema_power": args.ema_power,
            "precision": args.precision,
            "fused_optimizer": args.fused_optimizer,
            "compile_model": args.compile,
            "seed": args.seed if args.seed is not None else 0,
        }
        changes = {
            **parse_overrides(args.train, TrainSettings.field_names(), "--train"),
            **{k: v for k, v in flags.items() if v is not None},
        }
        settings = preset.train.replace(**changes)
    except (TypeError, ValueError) as err:
        parser.error(str(err))
    return {
        "format": RUN_FORMAT,
        "policy": args.policy,
        "preset": preset_name,
        "config": config.to_dict(),
        "settings": settings.to_dict(),
        "dataset": canonical_dataset(args.dataset),
        "out": _stored_out(out, args.run_dir),
        "device": args.device or "cpu",
        "command": f"{PROG} " + " ".join(argv),
    }


def _stored_out(out: Path, run_dir: str | None) -> str:
    """``out`` as ``run.json`` keeps it: relative to the run folder when inside it, else absolute."""
    if run_dir is not None and out.resolve().is_relative_to(Path(run_dir).resolve()):
        return str(out.resolve().relative_to(Path(run_dir).resolve()))
    return str(out.resolve())


def _read_run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> dict[str, Any]:
    """The run folder's ``run.json``, checked; usage errors name the folder."""
    given = [
        f"--{name.replace('_', '-')}"
        for name in _RUN_FLAGS
        if getattr(args, name) is not None and name not in _RESUME_OVERRIDES
    ]
    if given:
        parser.error(f"--resume takes the run's settings from its folder; drop {', '.join(given)}")
    path = Path(args.resume) / RUN_FILE
    try:
        run = read_record_file(path)
        if run.get("format") != RUN_FORMAT:
            raise ValueError(f"format {run.get('format')!r}, expected {RUN_FORMAT!r}")
        for key in ("policy", "preset", "dataset", "out", "device", "command"):
            if not isinstance(run.get(key), str):
                raise ValueError(f"{key!r} must be a string")
        get_policy_class(run["policy"]).config_class.from_dict(run["config"])
        TrainSettings.from_dict(run["settings"])
    except (CheckpointError, TypeError, ValueError) as err:
        parser.error(f"--resume {args.resume!r}: not a run folder ({err})")
    return run


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see the module docstring); exit 0 done, 1 ``--check`` differs, 2 usage error, 130 stopped."""
    parser = _parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    if args.check is not None:
        return _check_main(parser, args)
    _check_usage(parser, args)
    run = _read_run(parser, args) if args.resume is not None else _new_run(parser, args, argv)
    run_dir = args.resume if args.resume is not None else args.run_dir
    out = _out_path(parser, args, run, run_dir)
    torch.set_num_threads(args.threads)
    try:
        config = get_policy_class(run["policy"]).config_class.from_dict(run["config"])
        settings = TrainSettings.from_dict(run["settings"])
        dataset = load_dataset(args.dataset or run["dataset"])
        if args.resume is not None:
            require_same_data(dataset, run.get("data"))
        policy = make_policy(config, dataset=dataset, seed=settings.seed, device=run["device"])
    except (TypeError, ValueError) as err:
        parser.error(str(err))
    if run_dir is not None and args.resume is None:
        run["config"] = policy.config.to_dict()
        run["data"] = dataset.provenance()
        try:
            write_record(Path(run_dir) / RUN_FILE, run)
        except OSError as err:
            parser.error(f"cannot write --run-dir {run_dir!r}: {err}")
    job = _Job(parser, args, run, policy, dataset, settings)
    return _snapshot_main(job, out) if args.snapshot else _train_main(job, out)


def _check_usage(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Usage errors of flags that do not go together or are out of range."""
    if args.resume is not None and args.run_dir is not None:
        parser.error("--resume DIR continues the run in DIR; --run-dir starts a new one: give one of them")
    if args.snapshot and args.resume is None:
        parser.error("--snapshot needs --resume DIR (the run whose weights to write)")
    if not 1 <= args.threads <= MAX_THREADS:
        parser.error(f"--threads must be in [1, {MAX_THREADS}], got {args.threads}")
    if not args.save_every >= 0:
        parser.error(f"--save-every must be a number of seconds >= 0, got {args.save_every}")


def _out_path(
    parser: argparse.ArgumentParser, args: argparse.Namespace, run: dict[str, Any], run_dir: str | None
) -> Path:
    """Where the checkpoint goes (checked writable before training); ``--resume --device`` moves ``run``."""
    out = Path(run_dir or ".") / run["out"]  # relative: inside the run folder (the folder may move)
    if args.resume is not None and args.out is not None:
        out = Path(args.out)
    elif args.snapshot:
        out = Path(run_dir or ".") / "snapshot.safetensors"  # checked here; named after the step below
    if args.resume is not None and args.device is not None:
        run["device"] = args.device
    if out.suffix != ".safetensors":
        parser.error(f"--out must end with .safetensors, got {str(out)!r}")
    problem = _unwritable(out)
    if problem:
        parser.error(f"--out {str(out)!r}: {problem}")
    return out


@dataclass
class _Job:
    """What the command line made: its parser (for usage errors), arguments, run description, policy and data."""

    parser: argparse.ArgumentParser
    args: argparse.Namespace
    run: dict[str, Any]
    policy: TorchPolicy
    dataset: TrajectoryDataset
    settings: TrainSettings


def _train_main(job: _Job, out: Path) -> int:
    """Train (or continue) the run and write its checkpoint; exit 0 (130: stopped on a signal, state saved)."""
    parser, args, run, policy, dataset, settings = job.parser, job.args, job.run, job.policy, job.dataset, job.settings
    run_dir = args.resume if args.resume is not None else args.run_dir
    print(
        f"{run['policy']} ({run['preset']}): {policy.num_parameters():,} parameters, {len(dataset):,} steps "
        f"(obs {policy.obs_dim}, action {policy.action_dim}), {settings.steps} training steps"
        + (f", resumable in {run_dir}" if run_dir is not None else "")
    )
    try:
        record = train_policy(
            policy, dataset, settings, progress=args.progress, run_dir=run_dir, save_every=args.save_every
        )
    except TrainingInterrupted as stopped:
        print(f"{stopped}; continue with: {PROG} --resume {run_dir}")
        return 130
    except CheckpointError as err:
        parser.error(str(err))
    _write_checkpoint(job, record, out)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB) and {sidecar_path(out).name}: ", end="")
    print(f"final loss {record['final_loss']:.4f}, {record['wall_s']:.0f} s")
    return 0


def _write_checkpoint(job: _Job, record: dict[str, Any], out: Path) -> None:
    """Complete ``record`` with the run's data file, preset and command; write it and the weights to ``out``."""
    run = job.run
    record["data"]["file"] = Path(job.args.dataset or run["dataset"]).name
    record["preset"] = run["preset"]
    record["command"] = run["command"]
    try:
        save_trained(job.policy, out, run["policy"], record)
    except OSError as err:
        job.parser.error(f"cannot write --out {str(out)!r}: {err}")


def _snapshot_main(job: _Job, out: Path) -> int:
    """``--resume DIR --snapshot``: write the run's current weights and record; exit 0 (2: no usable state)."""
    try:
        record = snapshot_run(job.policy, job.dataset, job.settings, job.args.resume)
    except CheckpointError as err:
        job.parser.error(str(err))
    if job.args.out is None:
        out = Path(job.args.resume) / f"snapshot-step{record['snapshot_step']}.safetensors"
    _write_checkpoint(job, record, out)
    print(f"wrote {out}: step {record['snapshot_step']} of {job.settings.steps}, loss {record['final_loss']:.4f}")
    return 0
