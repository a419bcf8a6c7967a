"""Train any registered trajectory policy (DP, ACT) on any trajectory dataset; check a recorded run.

``python -m steer_envs.baselines.training --policy dp --dataset FILE --preset cpu --out dp.safetensors``

* ``--preset NAME``: a registered (model config, training settings) pair of
  the policy (:func:`steer_envs.baselines.factory.get_preset`);
* ``--model KEY=VALUE``: override one config field (``down_dims=[32,64,128]``);
  ``--train KEY=VALUE`` or ``--steps``, ``--lr``, ... one training setting;
* ``--dataset``: a :mod:`steer_envs.data.trajectories` file or a Maze2D random walk.

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

Training is deterministic for a given seed, thread count and device: batches
are drawn by a ``numpy`` generator, diffusion noise / timesteps and the VAE's
reparameterization noise by a ``torch.Generator``, dropout by torch's global
RNG seeded inside ``torch.random.fork_rng`` (the caller's RNG state is left
alone). Optimizer: AdamW with a linear warm-up and cosine decay to 0
(``diffusers.optimization``), gradient-norm clipping. The checkpoint is a
safetensors file; a JSON record beside it (same stem) holds the policy, the
preset, the config, the training settings, the data's provenance, the loss
curve and the wall time. Both are written atomically.

>>> import numpy as np
>>> from steer_envs.baselines.factory import make_policy, make_policy_config
>>> from steer_envs.data.trajectories import TrajectoryDataset
>>> data = TrajectoryDataset(np.random.default_rng(0).normal(size=(40, 3)), np.zeros((40, 2)))
>>> policy = make_policy(make_policy_config("act", chunk_size=4, d_model=8, n_heads=1, dim_feedforward=8), dataset=data)
>>> record = train_policy(policy, data, TrainSettings(steps=2, batch_size=4, log_every=1), progress=False)
>>> [step for step, _ in record["losses"]]
[1, 2]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any, cast

import numpy as np
import torch

from steer_envs.baselines.common.checkpoint import MAX_PARAMETERS
from steer_envs.baselines.common.checkpoint import read_record as read_record_file
from steer_envs.baselines.common.configuration import PRECISIONS, PolicyConfig, TrainSettings
from steer_envs.baselines.common.torch_policy import TorchPolicy
from steer_envs.baselines.factory import (
    get_policy_class,
    get_preset,
    make_policy,
    policy_names,
    with_dataset_features,
)
from steer_envs.baselines.training.run_state import (
    RUN_FILE,
    RUN_FORMAT,
    STATE_FILE,
    RunProgress,
    TrainingParts,
    check_device_kind,
    check_losses,
    load_state,
    save_state,
)
from steer_envs.core.progress import check_progress, progress_bar
from steer_envs.core.validation import integer, real_scalar
from steer_envs.data.datasets import load_dataset
from steer_envs.data.trajectories import PlanWindows, TrajectoryDataset
from steer_envs.io import CheckpointError, atomic_write_text
from steer_envs.utils.cli import parse_key_value
from steer_envs.utils.threads import MAX_THREADS

__all__ = [
    "TrainingInterrupted",
    "check_record",
    "main",
    "parse_overrides",
    "read_record",
    "require_same_data",
    "save_trained",
    "sidecar_path",
    "train_policy",
]

PROG = "python -m steer_envs.baselines.training"
#: largest relative loss difference ``--check`` accepts for a run that started on another device (a CUDA run
#: replayed on the CPU draws other diffusion noise: only the loss curve's course can match)
CROSS_DEVICE_RTOL = 0.1


def train_policy(
    policy: TorchPolicy,
    dataset: TrajectoryDataset,
    settings: TrainSettings,
    *,
    progress: bool | None = None,
    stop_after: int | None = None,
    raw_weights: dict[str, torch.Tensor] | None = None,
    run_dir: str | os.PathLike[str] | None = None,
    save_every: float = 300.0,
) -> dict[str, Any]:
    """Train ``policy`` in place on windows of ``dataset``; returns the training record (losses, wall time).

    The record's ``losses`` are ``[step, mean loss over the last log_every steps]`` pairs;
    ``progress`` shows a bar (``None``: only on a terminal, see :mod:`steer_envs.core.progress`).
    ``stop_after`` ends training after that many steps of the *same* run (the
    learning-rate schedule still spans ``settings.steps``): the prefix of a
    long run, to check a recorded loss curve without paying for all of it.
    With ``settings.ema_power > 0`` the policy ends with the exponential moving
    average of its weights (``diffusers.training_utils.EMAModel``, capped at
    0.9999); the logged losses are the raw weights' and do not change. Pass a
    dict as ``raw_weights`` to get the raw (un-averaged) state dict as well.

    With ``run_dir`` the run is resumable: its full state
    (:mod:`~steer_envs.baselines.training.run_state`) is saved there at least
    every ``save_every`` seconds, at ``stop_after`` and at the end, and a state
    already in ``run_dir`` is continued, so a stopped-and-resumed run ends
    with the same weights as an uninterrupted one. In the main thread, SIGINT
    or SIGTERM then saves the state after the current step and raises
    :class:`TrainingInterrupted` (a second SIGINT interrupts at once).
    """
    if not isinstance(policy, TorchPolicy):
        raise TypeError(f"policy must be a TorchPolicy (e.g. DiffusionPolicy, ACTPolicy), got {type(policy).__name__}")
    if not isinstance(dataset, TrajectoryDataset):
        raise TypeError(f"dataset must be a TrajectoryDataset, got {type(dataset).__name__}")
    if not isinstance(settings, TrainSettings):
        raise TypeError(f"settings must be TrainSettings, got {type(settings).__name__}")
    if (dataset.obs_dim, dataset.action_dim) != (policy.obs_dim, policy.action_dim):
        raise ValueError(
            f"dataset has obs_dim={dataset.obs_dim}, action_dim={dataset.action_dim}; "
            f"the policy expects {policy.obs_dim}, {policy.action_dim}"
        )
    if stop_after is not None:
        integer(stop_after, "stop_after", low=1, high=settings.steps)
    progress = check_progress(progress, owner="train_policy")
    save_every = real_scalar(save_every, "save_every", low=0.0)
    state_file = None if run_dir is None else Path(run_dir) / STATE_FILE
    last = settings.steps if stop_after is None else stop_after
    windows = PlanWindows(dataset, **policy.window_layout)
    if len(windows) == 0:
        raise ValueError(f"dataset of {len(dataset)} steps is too short for windows {policy.window_layout}")
    model = policy.model
    tic = time.perf_counter()
    with torch.random.fork_rng(devices=[]), _StopSignals(enabled=state_file is not None) as stop:
        torch.manual_seed(settings.seed)
        parts = _training_parts(policy, settings)
        opt, sched, ema, rng, gen = parts.optimizer, parts.scheduler, parts.ema, parts.rng, parts.generator
        done = RunProgress(threads=torch.get_num_threads(), first_device=policy.device.type)
        if state_file is not None and state_file.exists():
            done = load_state(state_file, settings=settings, parts=parts)
            if done.step > last:
                raise ValueError(f"stop_after={last}, but the state in {run_dir} is already at step {done.step}")
            if done.step < last:
                done.resumed_at.append(done.step)
        losses = done.losses

        def save() -> None:
            """Add this segment's time to ``done.wall_s``; write the state (with a run folder)."""
            nonlocal tic
            now = time.perf_counter()
            done.wall_s, tic = done.wall_s + now - tic, now
            if state_file is not None:
                save_state(state_file, settings=settings, progress=done, parts=parts)

        last_save = time.monotonic()
        bar = progress_bar(total=last, initial=min(done.step, last), enabled=progress, unit="step", desc="training")
        autocast = torch.autocast(policy.device.type, dtype=torch.bfloat16, enabled=settings.precision == "bf16")
        if settings.compile_model:
            policy.model = cast(torch.nn.Module, torch.compile(model))
        model.train()
        try:
            for step in range(done.step + 1, last + 1):
                obs, plans = windows.gather(rng.integers(len(windows), size=settings.batch_size))
                if settings.static_history_prob > 0 and obs.shape[1] > 1:
                    still = rng.random(len(obs)) < settings.static_history_prob
                    obs[still] = obs[still, -1:]
                with autocast:
                    loss = policy.loss(torch.from_numpy(obs), torch.from_numpy(plans), gen).float()
                if not torch.isfinite(loss):
                    raise FloatingPointError(f"training loss became {loss.item()} at step {step}")
                opt.zero_grad(set_to_none=True)
                loss.backward()
                torch.nn.utils.clip_grad_norm_(model.parameters(), settings.grad_clip)
                opt.step()
                sched.step()
                if ema is not None:
                    ema.step(model.parameters())
                done.running += loss.item()
                done.step = step
                if step % settings.log_every == 0 or step == settings.steps or (step == last and state_file is None):
                    n = step - (losses[-1][0] if losses else 0)
                    losses.append([step, done.running / n])
                    done.running = 0.0
                    bar.set_postfix(loss=f"{losses[-1][1]:.4f}")
                bar.update(1)
                if stop.requested and state_file is not None:
                    save()
                    raise TrainingInterrupted(step, state_file.parent, stop.requested)
                if state_file is not None and time.monotonic() - last_save >= save_every and step < last:
                    save()
                    last_save = time.monotonic()
            save()
        finally:
            policy.model = model
            model.eval()
            bar.close()
    if raw_weights is not None:
        raw_weights.update({k: v.detach().clone() for k, v in model.state_dict().items()})
    if ema is not None:
        ema.copy_to(model.parameters())
    return _record(policy, dataset, settings, done, len(windows))


def _training_parts(policy: TorchPolicy, settings: TrainSettings) -> TrainingParts:
    """The optimizer (AdamW), LR schedule (warm-up + cosine), optional EMA and seeded RNGs of a fresh run."""
    from diffusers.optimization import get_cosine_schedule_with_warmup

    model = policy.model
    opt = torch.optim.AdamW(
        model.parameters(),
        lr=settings.lr,
        betas=settings.betas,
        weight_decay=settings.weight_decay,
        fused=settings.fused_optimizer or None,
    )
    sched = get_cosine_schedule_with_warmup(opt, min(settings.warmup_steps, settings.steps), settings.steps)
    ema = None
    if settings.ema_power > 0:
        from diffusers.training_utils import EMAModel

        ema = EMAModel(model.parameters(), decay=0.9999, use_ema_warmup=True, power=settings.ema_power)
    rng = np.random.default_rng(settings.seed)
    gen = torch.Generator(device=policy.device).manual_seed(settings.seed)
    return TrainingParts(model, opt, sched, ema, rng, gen)


def _record(
    policy: TorchPolicy, dataset: TrajectoryDataset, settings: TrainSettings, done: RunProgress, windows: int
) -> dict[str, Any]:
    """The training record of a run that stands at ``done`` (see :func:`train_policy`)."""
    losses = done.losses
    record: dict[str, Any] = {
        "settings": settings.to_dict(),
        "losses": losses,
        "final_loss": losses[-1][1] if losses else None,
        "wall_s": round(done.wall_s, 1),
        "threads": done.threads or torch.get_num_threads(),  # the first segment's: what a check replays
        "device": str(policy.device),
        "first_device": done.first_device or policy.device.type,  # where a check's replay can match exactly
        "torch": torch.__version__,
        "windows": windows,
        "data": dataset.provenance(),
    }
    if done.resumed_at:
        record["resumed_at"] = list(done.resumed_at)
    if done.moved_at:
        record["moved_at"] = list(done.moved_at)
    return record


def snapshot_run(
    policy: TorchPolicy, dataset: TrajectoryDataset, settings: TrainSettings, run_dir: str | os.PathLike[str]
) -> dict[str, Any]:
    """Load the weights a resumable run in ``run_dir`` has reached into ``policy``; nothing is written.

    For evaluating a long run on the way (the run may be going on: its state
    file is replaced atomically). With an EMA the policy gets the averaged
    weights, as at the end of a run. Returns the record of the run so far,
    with ``snapshot_step``; :class:`CheckpointError` when there is no state
    of this run in ``run_dir``.
    """
    state_file = Path(run_dir) / STATE_FILE
    if not state_file.exists():
        raise CheckpointError(f"{run_dir}: no saved training state yet ({STATE_FILE})")
    with torch.random.fork_rng(devices=[]):
        parts = _training_parts(policy, settings)
        done = load_state(state_file, settings=settings, parts=parts)
    if parts.ema is not None:
        parts.ema.copy_to(policy.model.parameters())
    policy.model.eval()
    windows = len(PlanWindows(dataset, **policy.window_layout))
    return {**_record(policy, dataset, settings, done, windows), "snapshot_step": done.step}


class TrainingInterrupted(KeyboardInterrupt):
    """A resumable run stopped on a signal after saving its state; ``--resume`` the folder to continue.

    A ``KeyboardInterrupt``: code that calls :func:`train_policy` (a benchmark
    trial, a notebook) stops as on Ctrl-C instead of treating it as a failure.
    """

    def __init__(self, step: int, run_dir: Path, signal_name: str) -> None:
        super().__init__(f"{signal_name}: training state saved after step {step} in {run_dir}")
        self.step, self.run_dir, self.signal_name = step, run_dir, signal_name


class _StopSignals:
    """While active (main thread only), the first SIGINT / SIGTERM sets :attr:`requested` instead of killing."""

    def __init__(self, *, enabled: bool) -> None:
        self.enabled = enabled and threading.current_thread() is threading.main_thread()
        self.requested = ""
        self._previous: dict[int, Any] = {}

    def _handle(self, signum: int, frame: Any) -> None:
        if self.requested and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.requested = signal.Signals(signum).name

    def __enter__(self) -> _StopSignals:
        if self.enabled:
            for signum in (signal.SIGINT, signal.SIGTERM):
                self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)


def save_trained(policy: TorchPolicy, out: str | os.PathLike[str], name: str, record: Mapping[str, Any]) -> Path:
    """Write a trained policy's checkpoint and, beside it, its JSON record (policy ``name``, config, stats, training).

    ``record`` is :func:`train_policy`'s (plus anything the caller adds, e.g. the command); both files are written
    atomically. Returns the checkpoint path.
    """
    settings = record["settings"]
    extra = {"final_loss": record["final_loss"], "steps": settings["steps"], "seed": settings["seed"]}
    path = policy.save(out, extra=extra)
    summary = {
        "policy": name,
        "config": policy.config.to_dict(),
        "stats": {k: v.to_dict() for k, v in policy.stats.items()},
        "training": dict(record),
    }
    atomic_write_text(sidecar_path(path), json.dumps(summary, indent=1) + "\n")
    return path


def sidecar_path(checkpoint: str | os.PathLike[str]) -> Path:
    """The JSON record beside a checkpoint: ``x.safetensors`` -> ``x.json``.

    >>> sidecar_path("runs/dp.safetensors").name
    'dp.json'
    """
    return Path(checkpoint).with_suffix(".json")


def read_record(summary: Mapping[str, Any]) -> tuple[str, PolicyConfig, TrainSettings, dict[str, Any]]:
    """``(policy name, config, settings, training record)`` of a training record's JSON.

    Reads the records of this CLI (``policy``/``config``) and those written
    before the policy factory (``kind``/``model``, upgraded by the policy class).
    ``ValueError`` when a field is missing or malformed: the policy must be a
    registered one, the config and settings valid, ``losses`` a list of
    ``[step, finite loss]`` pairs with increasing steps, ``threads`` (if
    present) an int in ``[1, MAX_THREADS]``, ``data`` (if present) an object.
    """
    if not isinstance(summary, Mapping):
        raise ValueError(f"not a training record (a JSON object), got {type(summary).__name__}")
    try:
        record = summary["training"]
        if not isinstance(record, Mapping):
            raise TypeError(f"'training' must be an object, got {type(record).__name__}")
        record = dict(record)
        settings = TrainSettings.from_dict(record["settings"])
        if "policy" in summary:
            name = summary["policy"]
            if not isinstance(name, str):
                raise TypeError(f"'policy' must be a string, got {type(name).__name__}")
            config = get_policy_class(name).config_class.from_dict(summary["config"])
        else:
            name = summary["kind"]
            if not isinstance(name, str):
                raise TypeError(f"'kind' must be a string, got {type(name).__name__}")
            config = get_policy_class(name).upgrade_legacy_config(summary["model"])
        record["losses"] = check_losses(record["losses"])
        if "threads" in record:
            record["threads"] = integer(record["threads"], "threads", low=1, high=MAX_THREADS)
        record["first_device"] = check_device_kind(record.get("first_device", "")) or "cpu"
        if record.get("data") is not None and not isinstance(record["data"], Mapping):
            raise TypeError(f"'data' must be an object, got {type(record['data']).__name__}")
    except (KeyError, TypeError, ValueError) as err:
        what = f"missing {err}" if isinstance(err, KeyError) else f"malformed: {err}"
        raise ValueError(f"not a training record ({what})") from None
    return name, config, settings, record


def check_record(
    record_path: str | os.PathLike[str],
    data: str | os.PathLike[str] | TrajectoryDataset,
    steps: int = 200,
    *,
    policy: str | None = None,
    progress: bool = False,
) -> dict[str, Any]:
    """Re-run the first ``steps`` steps of a recorded training run and compare its logged losses.

    ``record_path`` is a checkpoint's JSON record (:func:`sidecar_path`); the
    config, settings, seed and thread count come from it, the data from
    ``data`` (its provenance must match the record's). ``policy`` (optional)
    must be the record's policy. Returns ``{"policy", "compared": [[step,
    recorded, rerun], ...], "max_rel_diff", "wall_s", "cross_device"}``.
    Bit-identical on the same torch version, thread count and CPU kind; another
    CPU's kernels give rounding-level differences that grow slowly. The replay
    runs on the CPU: a run whose first segment ran on another device
    (``first_device``, e.g. ``"cuda"``; ``cross_device`` names it) drew other
    diffusion noise, so only the loss curve's course can match (the CLI then
    accepts :data:`CROSS_DEVICE_RTOL`) and the replay keeps the current thread count.

    A record that is missing, not JSON or malformed (see :func:`read_record`),
    or whose network would exceed
    :data:`~steer_envs.baselines.common.checkpoint.MAX_PARAMETERS`, is a
    :class:`~steer_envs.io.CheckpointError` naming the file; a dataset that
    cannot be read is a :class:`~steer_envs.io.DatasetError`.
    """
    path = Path(record_path)
    summary = read_record_file(path)
    try:
        name, config, settings, record = read_record(summary)
    except ValueError as err:
        raise CheckpointError(f"{path}: {err}") from None
    if policy is not None and policy != name:
        raise ValueError(f"--policy is {policy!r} but {path} records a {name!r} run")
    steps = integer(steps, "steps", low=1, high=settings.steps)
    dataset = data if isinstance(data, TrajectoryDataset) else load_dataset(data)
    require_same_data(dataset, record.get("data"))
    try:
        size = with_dataset_features(config, dataset).parameter_count()
    except ValueError as err:
        raise ValueError(f"{path}: the record's config does not fit the dataset ({err})") from None
    if size is not None and size > MAX_PARAMETERS:
        raise CheckpointError(
            f"{path}: its config implies {size:,} parameters, more than the {MAX_PARAMETERS:,} allowed"
        )
    first_device = record["first_device"]
    threads = torch.get_num_threads()
    if first_device == "cpu":  # the same kernels: replay with the recorded thread count
        torch.set_num_threads(int(record.get("threads", threads)))
    try:
        fresh = make_policy(config, dataset=dataset, seed=settings.seed)
        rerun = train_policy(fresh, dataset, settings, progress=progress, stop_after=steps)
    finally:
        torch.set_num_threads(threads)
    recorded = {int(s): float(v) for s, v in record["losses"]}
    compared = [[s, recorded[s], v] for s, v in rerun["losses"] if s in recorded]
    if not compared:
        raise ValueError(f"no logged step <= {steps} to compare (the record logs every {settings.log_every})")
    rel = max(abs(b - a) / max(abs(a), 1e-12) for _, a, b in compared)
    return {
        "policy": name,
        "compared": compared,
        "max_rel_diff": rel,
        "wall_s": rerun["wall_s"],
        "cross_device": None if first_device == "cpu" else first_device,
    }


def require_same_data(dataset: TrajectoryDataset, recorded: Mapping[str, Any] | None) -> None:
    """``ValueError`` unless ``dataset``'s provenance matches a record's ``data`` entry (its file name aside)."""
    for key, value in dict(recorded or {}).items():
        if key != "file" and dataset.meta.get(key) != value:
            raise ValueError(
                f"the dataset has {key}={dataset.meta.get(key)!r}; the record was trained on {value!r} "
                "(regenerate the data with the recorded command)"
            )


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
    parser.add_argument("--policy", choices=policy_names(), help="policy to train (with --check: optional)")
    parser.add_argument(
        "--dataset",
        metavar="FILE",
        help="training data: a steer_envs.data.trajectories .npz or a maze2d random walk "
        "(python -m steer_envs.data.maze_random_walk); with --resume: default the run's own",
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
    return parser


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
        "dataset": str(Path(args.dataset).resolve()),
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
    if args.resume is not None and args.run_dir is not None:
        parser.error("--resume DIR continues the run in DIR; --run-dir starts a new one: give one of them")
    if args.snapshot and args.resume is None:
        parser.error("--snapshot needs --resume DIR (the run whose weights to write)")
    if not 1 <= args.threads <= MAX_THREADS:
        parser.error(f"--threads must be in [1, {MAX_THREADS}], got {args.threads}")
    if not args.save_every >= 0:
        parser.error(f"--save-every must be a number of seconds >= 0, got {args.save_every}")
    run = _read_run(parser, args) if args.resume is not None else _new_run(parser, args, argv)
    run_dir = args.resume if args.resume is not None else args.run_dir
    out = Path(run_dir or ".") / run["out"]  # relative: inside the run folder (the folder may move)
    if args.resume is not None and args.out is not None:
        out = Path(args.out)
    elif args.snapshot:
        out = Path(run_dir) / "snapshot.safetensors"  # checked here; named after the step below
    if args.resume is not None and args.device is not None:
        run["device"] = args.device
    if out.suffix != ".safetensors":
        parser.error(f"--out must end with .safetensors, got {str(out)!r}")
    problem = _unwritable(out)
    if problem:
        parser.error(f"--out {str(out)!r}: {problem}")
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
            atomic_write_text(Path(run_dir) / RUN_FILE, json.dumps(run, indent=1) + "\n")
        except OSError as err:
            parser.error(f"cannot write --run-dir {run_dir!r}: {err}")
    if args.snapshot:
        return _snapshot_main(parser, args, run, policy, dataset, settings, out)
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
    _write_checkpoint(parser, args, run, policy, record, out)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB) and {sidecar_path(out).name}: ", end="")
    print(f"final loss {record['final_loss']:.4f}, {record['wall_s']:.0f} s")
    return 0


def _write_checkpoint(
    parser: argparse.ArgumentParser,
    args: argparse.Namespace,
    run: dict[str, Any],
    policy: TorchPolicy,
    record: dict[str, Any],
    out: Path,
) -> None:
    """Complete ``record`` with the run's data file, preset and command; write it and the weights to ``out``."""
    record["data"]["file"] = Path(args.dataset or run["dataset"]).name
    record["preset"] = run["preset"]
    record["command"] = run["command"]
    try:
        save_trained(policy, out, run["policy"], record)
    except OSError as err:
        parser.error(f"cannot write --out {str(out)!r}: {err}")


def _snapshot_main(
    parser: argparse.ArgumentParser,
    args: argparse.Namespace,
    run: dict[str, Any],
    policy: TorchPolicy,
    dataset: TrajectoryDataset,
    settings: TrainSettings,
    out: Path,
) -> int:
    """``--resume DIR --snapshot``: write the run's current weights and record; exit 0 (2: no usable state)."""
    try:
        record = snapshot_run(policy, dataset, settings, args.resume)
    except CheckpointError as err:
        parser.error(str(err))
    if args.out is None:
        out = Path(args.resume) / f"snapshot-step{record['snapshot_step']}.safetensors"
    _write_checkpoint(parser, args, run, policy, record, out)
    print(f"wrote {out}: step {record['snapshot_step']} of {settings.steps}, loss {record['final_loss']:.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
