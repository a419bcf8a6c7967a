"""Train any registered trajectory policy (DP, ACT) on any trajectory dataset; check a recorded run.

The command line is :mod:`~steer_envs.baselines.training.cli` (``python -m steer_envs.baselines.training``).

Training is deterministic for a given seed, thread count and device: batches
are drawn by a ``numpy`` generator, diffusion noise / timesteps and the VAE's
reparameterization noise by a ``torch.Generator``, dropout by torch's global
RNG seeded inside ``torch.random.fork_rng`` (the caller's RNG state is left
alone). Optimizer: AdamW with a linear warm-up and cosine decay to 0
(``diffusers.optimization``), gradient-norm clipping. The checkpoint is a
safetensors file; a JSON record beside it (same stem) holds the policy, the
preset, the config, the training settings, the data's provenance, the loss
curve and the wall time. Both are written atomically, each with a sha256 of
its content that loading checks
(:mod:`~steer_envs.baselines.common.checkpoint`).

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

import os
import signal
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any, cast

import numpy as np
import torch

from steer_envs.baselines.common.checkpoint import MAX_PARAMETERS, write_record
from steer_envs.baselines.common.checkpoint import read_record as read_record_file
from steer_envs.baselines.common.configuration import PolicyConfig, TrainSettings
from steer_envs.baselines.common.torch_policy import TorchPolicy
from steer_envs.baselines.factory import (
    get_policy_class,
    make_policy,
    with_dataset_features,
)
from steer_envs.baselines.training.run_state import (
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
from steer_envs.io import CheckpointError
from steer_envs.utils.threads import MAX_THREADS

__all__ = [
    "CROSS_DEVICE_RTOL",
    "TrainingInterrupted",
    "check_record",
    "read_record",
    "require_same_data",
    "save_trained",
    "sidecar_path",
    "train_policy",
]

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
    progress, save_every = _check_training_args(policy, dataset, settings, stop_after, progress, save_every)
    state_file = None if run_dir is None else Path(run_dir) / STATE_FILE
    last = settings.steps if stop_after is None else stop_after
    windows = PlanWindows(dataset, **policy.window_layout)
    if len(windows) == 0:
        raise ValueError(f"dataset of {len(dataset)} steps is too short for windows {policy.window_layout}")
    model = policy.model
    run = _TrainingRun(policy, windows, settings, state_file, save_every)
    with torch.random.fork_rng(devices=[]), _StopSignals(enabled=state_file is not None) as stop:
        torch.manual_seed(settings.seed)
        run.start(last, run_dir)
        bar = progress_bar(total=last, initial=min(run.done.step, last), enabled=progress, unit="step", desc="training")
        autocast = torch.autocast(policy.device.type, dtype=torch.bfloat16, enabled=settings.precision == "bf16")
        if settings.compile_model:
            policy.model = cast(torch.nn.Module, torch.compile(model))
        model.train()
        try:
            run.loop(last, bar, autocast, stop)
        finally:
            policy.model = model
            model.eval()
            bar.close()
    if raw_weights is not None:
        raw_weights.update({k: v.detach().clone() for k, v in model.state_dict().items()})
    if run.parts.ema is not None:
        run.parts.ema.copy_to(model.parameters())
    return _record(policy, dataset, settings, run.done, len(windows))


def _check_training_args(
    policy: TorchPolicy,
    dataset: TrajectoryDataset,
    settings: TrainSettings,
    stop_after: int | None,
    progress: bool | None,
    save_every: float,
) -> tuple[bool | None, float]:
    """:func:`train_policy`'s arguments checked (the dataset's dimensions must be the policy's); the
    progress flag and the save interval."""
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
    return check_progress(progress, owner="train_policy"), real_scalar(save_every, "save_every", low=0.0)


class _TrainingRun:
    """The loop of :func:`train_policy`: optimizer steps, the loss log, and (with a run folder) state saves."""

    def __init__(
        self,
        policy: TorchPolicy,
        windows: PlanWindows,
        settings: TrainSettings,
        state_file: Path | None,
        save_every: float,
    ) -> None:
        self.policy, self.windows, self.settings = policy, windows, settings
        self.model = policy.model
        self.state_file, self.save_every = state_file, save_every
        self.tic = time.perf_counter()

    def start(self, last: int, run_dir: str | os.PathLike[str] | None) -> None:
        """Make the optimizer and RNGs of a fresh run and, where ``state_file`` holds one, load the saved state."""
        self.parts = _training_parts(self.policy, self.settings)
        self.done = RunProgress(threads=torch.get_num_threads(), first_device=self.policy.device.type)
        if self.state_file is not None and self.state_file.exists():
            self.done = load_state(self.state_file, settings=self.settings, parts=self.parts)
            if self.done.step > last:
                raise ValueError(f"stop_after={last}, but the state in {run_dir} is already at step {self.done.step}")
            if self.done.step < last:
                self.done.resumed_at.append(self.done.step)

    def save(self) -> None:
        """Add this segment's time to ``done.wall_s``; write the state (with a run folder)."""
        now = time.perf_counter()
        self.done.wall_s, self.tic = self.done.wall_s + now - self.tic, now
        if self.state_file is not None:
            save_state(self.state_file, settings=self.settings, progress=self.done, parts=self.parts)

    def loop(self, last: int, bar: Any, autocast: Any, stop: _StopSignals) -> None:
        """Train from the step after ``done.step`` through ``last``; save the state as asked and at the end."""
        settings, done, state_file = self.settings, self.done, self.state_file
        losses = done.losses
        last_save = time.monotonic()
        for step in range(done.step + 1, last + 1):
            done.running += self.optimizer_step(step, autocast)
            done.step = step
            if step % settings.log_every == 0 or step == settings.steps or (step == last and state_file is None):
                n = step - (losses[-1][0] if losses else 0)
                losses.append([step, done.running / n])
                done.running = 0.0
                bar.set_postfix(loss=f"{losses[-1][1]:.4f}")
            bar.update(1)
            if stop.requested and state_file is not None:
                self.save()
                raise TrainingInterrupted(step, state_file.parent, stop.requested)
            if state_file is not None and time.monotonic() - last_save >= self.save_every and step < last:
                self.save()
                last_save = time.monotonic()
        self.save()

    def optimizer_step(self, step: int, autocast: Any) -> float:
        """One step on a batch of windows drawn from the run's generator; its loss."""
        settings, parts = self.settings, self.parts
        rng = parts.rng
        obs, plans = self.windows.gather(rng.integers(len(self.windows), size=settings.batch_size))
        if settings.static_history_prob > 0 and obs.shape[1] > 1:
            still = rng.random(len(obs)) < settings.static_history_prob
            obs[still] = obs[still, -1:]
        with autocast:
            loss = self.policy.loss(torch.from_numpy(obs), torch.from_numpy(plans), parts.generator).float()
        if not torch.isfinite(loss):
            raise FloatingPointError(f"training loss became {loss.item()} at step {step}")
        parts.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(self.model.parameters(), settings.grad_clip)
        parts.optimizer.step()
        parts.scheduler.step()
        if parts.ema is not None:
            parts.ema.step(self.model.parameters())
        return float(loss.item())


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
    atomically, with their checksums (:func:`~steer_envs.baselines.common.checkpoint.write_record`). Returns the
    checkpoint path.
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
    write_record(sidecar_path(path), summary)
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
    _check_record_size(path, config, dataset)
    first_device = record["first_device"]
    rerun = _replay(config, dataset, settings, record, steps, progress)
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


def _check_record_size(path: Path, config: PolicyConfig, dataset: TrajectoryDataset) -> None:
    """``ValueError`` unless the record's config fits ``dataset``; ``CheckpointError`` beyond ``MAX_PARAMETERS``."""
    try:
        size = with_dataset_features(config, dataset).parameter_count()
    except ValueError as err:
        raise ValueError(f"{path}: the record's config does not fit the dataset ({err})") from None
    if size is not None and size > MAX_PARAMETERS:
        raise CheckpointError(
            f"{path}: its config implies {size:,} parameters, more than the {MAX_PARAMETERS:,} allowed"
        )


def _replay(
    config: PolicyConfig,
    dataset: TrajectoryDataset,
    settings: TrainSettings,
    record: Mapping[str, Any],
    steps: int,
    progress: bool,
) -> dict[str, Any]:
    """The record of the first ``steps`` steps of a fresh run (with the recorded thread count on a CPU-started run)."""
    threads = torch.get_num_threads()
    if record["first_device"] == "cpu":  # the same kernels: replay with the recorded thread count
        torch.set_num_threads(int(record.get("threads", threads)))
    try:
        fresh = make_policy(config, dataset=dataset, seed=settings.seed)
        return train_policy(fresh, dataset, settings, progress=progress, stop_after=steps)
    finally:
        torch.set_num_threads(threads)


def require_same_data(dataset: TrajectoryDataset, recorded: Mapping[str, Any] | None) -> None:
    """``ValueError`` unless ``dataset``'s provenance matches a record's ``data`` entry (its file name aside)."""
    for key, value in dict(recorded or {}).items():
        if key != "file" and dataset.meta.get(key) != value:
            raise ValueError(
                f"the dataset has {key}={dataset.meta.get(key)!r}; the record was trained on {value!r} "
                "(regenerate the data with the recorded command)"
            )
