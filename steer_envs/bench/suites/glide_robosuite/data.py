"""GLiDE's robosuite data: one shard per demonstration (the demo and its perturbed replays), then one data set.

A shard is the unit of work of the ``glide-robosuite-data`` suite (one trial =
one task x one demo index), so generation runs through the bench executors
(local processes or Ray), resumes where it stopped (a shard on disk is never
rebuilt) and shows the runner's progress bar. :func:`task_dataset` reads a
task's shards (building any missing one in-process) and writes the merged data
set atomically beside them.

Shard ``i`` of a task: the scripted expert from reset seed ``i``; if ``i <
replay_demos``, ``replays_per_demo`` perturbed replays of it (drawn from
``default_rng([i, 7])`` by :func:`~steer_envs.data.robosuite_replays.sample_perturbation`)
and an early-terminated copy of every successful one; with ``extra_gripper``
(the public GLiDE robosuite code's "extra gripper perturbation", off by
default) also a replay of every successful replay with the gripper forced open
(drawn from its own stream, ``default_rng([i, 11])``, so the others do not change).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from steer_envs.data import robosuite_replays as rr
from steer_envs.io import DatasetError

#: bump when shard contents change for the same settings (old shards are then not reused).
SHARD_VERSION = 4


@dataclass(frozen=True)
class ShardSettings:
    """What one shard is built from (its file name hashes these)."""

    task: str
    index: int
    replay_demos: int
    replays_per_demo: int
    truncated_copies: bool = True
    success_hold: int = rr.SUCCESS_HOLD_STEPS
    extra_gripper: bool = False

    @property
    def has_replays(self) -> bool:
        return self.index < self.replay_demos

    def file_name(self) -> str:
        key = {
            "v": SHARD_VERSION,
            "replays": self.replays_per_demo if self.has_replays else 0,
            "truncated": self.truncated_copies and self.has_replays,
            "hold": self.success_hold,
            "extra_gripper": self.extra_gripper and self.has_replays,
        }
        digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:10]
        return f"{self.task}-demo{self.index:04d}-{digest}.npz"


def build_shard(settings: ShardSettings, env: rr.RobosuiteEnv) -> list[rr.ArmTrajectory]:
    """The demo of ``settings.index`` and (when it has replays) its perturbed replays and their truncated copies."""
    demo = rr.record_demo(env, settings.index, success_hold=settings.success_hold)
    out = [demo]
    if not (settings.has_replays and demo.success):
        return out
    rng = np.random.default_rng([settings.index, 7])
    extra_rng = np.random.default_rng([settings.index, 11])  # its own stream: the other replays stay as they were
    for _ in range(settings.replays_per_demo):
        r = rr.replay(
            env, demo, rr.sample_perturbation(demo, rng), source=settings.index, success_hold=settings.success_hold
        )
        out.append(r)
        if settings.truncated_copies and r.success:
            out.append(rr.early_terminated(r, rng))
        if settings.extra_gripper and r.success:
            g = rr.sample_perturbation(r, extra_rng, kernel_fraction=0.0)
            out.append(rr.replay(env, r, g, source=settings.index, success_hold=settings.success_hold))
    return out


def shard_path(cache_dir: str | Path, settings: ShardSettings) -> Path:
    return Path(cache_dir) / "shards" / settings.file_name()


def _read_shard(path: Path) -> list[rr.ArmTrajectory] | None:
    """The shard's trajectories, or None when there is no readable file (missing, or an older format)."""
    if not path.exists():
        return None
    try:
        return rr.load_trajectories(path)[0]
    except DatasetError:
        return None


def _write_shard(path: Path, settings: ShardSettings, env: rr.RobosuiteEnv) -> list[rr.ArmTrajectory]:
    trajs = build_shard(settings, env)
    rr.save_trajectories(path, trajs, meta={"shard": asdict(settings)})
    return trajs


def ensure_shard(cache_dir: str | Path, settings: ShardSettings) -> tuple[list[rr.ArmTrajectory], Path, bool]:
    """The shard (trajectories, file, built now), built and written atomically unless a readable file exists."""
    path = shard_path(cache_dir, settings)
    trajs = _read_shard(path)
    if trajs is not None:
        return trajs, path, False
    env = rr.make_arm_env(settings.task)
    try:
        return _write_shard(path, settings, env), path, True
    finally:
        env.close()


def task_dataset(
    cache_dir: str | Path,
    task: str,
    n_demos: int,
    replay_demos: int,
    replays_per_demo: int,
    success_hold: int = rr.SUCCESS_HOLD_STEPS,
    extra_gripper: bool = False,
) -> list[rr.ArmTrajectory]:
    """Every trajectory of ``task``'s shards ``0 .. n_demos - 1`` in shard order (missing shards built here)."""
    shards = [
        ShardSettings(task, i, replay_demos, replays_per_demo, success_hold=success_hold, extra_gripper=extra_gripper)
        for i in range(n_demos)
    ]
    return read_shards(cache_dir, shards)


def read_shards(cache_dir: str | Path, shards: Sequence[ShardSettings]) -> list[rr.ArmTrajectory]:
    """Every trajectory of ``shards`` (one task) in their order; a missing shard is built and written here."""
    out: list[rr.ArmTrajectory] = []
    env = None  # made once, for the first missing shard
    try:
        for settings in shards:
            path = shard_path(cache_dir, settings)
            trajs = _read_shard(path)
            if trajs is None:
                env = env or rr.make_arm_env(settings.task)
                trajs = _write_shard(path, settings, env)
            out += trajs
    finally:
        if env is not None:
            env.close()
    return out


def split(trajectories: Sequence[rr.ArmTrajectory]) -> tuple[list[rr.ArmTrajectory], list[rr.ArmTrajectory]]:
    """(successful demos, replays incl. truncated copies)."""
    demos = [t for t in trajectories if t.perturbation.kind == "demo" and t.source < 0 and t.success]
    replays = [t for t in trajectories if t.source >= 0]
    return demos, replays
