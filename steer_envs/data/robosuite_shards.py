"""GLiDE's robosuite data in shards: one shard per demonstration (the demo and its perturbed replays).

Shard ``i`` of a task: the demonstrator's demo from reset seed ``i`` (the
scripted expert, or with ``demos="human_like"`` the human-like one; in the
task's ``variant``, e.g. the public-code Lift); if ``i < replay_demos``,
``replays_per_demo`` perturbed replays of it and their truncated copies
(:func:`~steer_envs.data.robosuite_replay_sets.demo_with_replays`).
Shards live under ``cache_dir/shards`` in the shared
:class:`~steer_envs.data.shards.ShardCache`: a readable shard on disk is never
rebuilt, so generation resumes where it stopped and runs in parallel processes
(the ``glide-robosuite-data`` suite runs one shard per trial).
:func:`task_dataset` reads a task's shards, building any missing one here.
The default cache folder is :func:`~steer_envs.io.default_cache_dir` ``("glide-robosuite")``.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from steer_envs.data import robosuite_replays as rr
from steer_envs.data.robosuite_replay_sets import demo_with_replays
from steer_envs.data.shards import LazyEnvs, ShardCache, shard_file

__all__ = [
    "CACHE_NAME",
    "SHARD_VERSION",
    "ShardSettings",
    "build_shard",
    "ensure_shard",
    "read_shards",
    "shard_path",
    "task_dataset",
]

#: the folder name of :func:`~steer_envs.io.default_cache_dir` for these shards.
CACHE_NAME = "glide-robosuite"
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
    variant: str = "thesis"
    demos: str = "scripted"

    @property
    def has_replays(self) -> bool:
        return self.index < self.replay_demos

    def file_name(self) -> str:
        key: dict[str, object] = {
            "v": SHARD_VERSION,
            "replays": self.replays_per_demo if self.has_replays else 0,
            "truncated": self.truncated_copies and self.has_replays,
            "hold": self.success_hold,
            "extra_gripper": self.extra_gripper and self.has_replays,
        }
        # named only when not the default, so the default shards keep their names (and caches)
        key |= {k: v for k, v in (("variant", self.variant), ("demos", self.demos)) if v != _DEFAULTS[k]}
        digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:10]
        return f"{self.task}-demo{self.index:04d}-{digest}.npz"


_DEFAULTS = {"variant": "thesis", "demos": "scripted"}


def build_shard(settings: ShardSettings, env: rr.RobosuiteEnv) -> list[rr.ArmTrajectory]:
    """The demo of ``settings.index`` and (when it has replays) its perturbed replays and their truncated copies."""
    return demo_with_replays(
        env,
        settings.index,
        settings.replays_per_demo if settings.has_replays else 0,
        truncated_copies=settings.truncated_copies,
        success_hold=settings.success_hold,
        extra_gripper=settings.extra_gripper,
        demos=settings.demos,
    )


def shard_path(cache_dir: str | Path, settings: ShardSettings) -> Path:
    """Where the shard of ``settings`` lives (``cache_dir/shards/<file name>``)."""
    return shard_file(cache_dir, settings.file_name())


_Key = tuple[str, str]  # (task, variant): one env each


def _make(key: _Key) -> rr.RobosuiteEnv:
    return rr.make_arm_env(*key)


def _cache(cache_dir: str | Path, envs: LazyEnvs[_Key, rr.RobosuiteEnv]) -> ShardCache[ShardSettings, rr.ArmTrajectory]:
    return ShardCache(
        Path(cache_dir),
        name=ShardSettings.file_name,
        build=lambda settings: build_shard(settings, envs.get((settings.task, settings.variant))),
        load=lambda path: rr.load_trajectories(path)[0],
        save=lambda path, trajs, meta: rr.save_trajectories(path, trajs, meta=meta),
    )


def ensure_shard(cache_dir: str | Path, settings: ShardSettings) -> tuple[list[rr.ArmTrajectory], Path, bool]:
    """The shard (trajectories, file, built now), built and written atomically unless a readable file exists."""
    with LazyEnvs[_Key, rr.RobosuiteEnv](_make) as envs:
        return _cache(cache_dir, envs).ensure(settings)


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
    """Every trajectory of ``shards`` in their order; a missing shard is built and written here."""
    with LazyEnvs[_Key, rr.RobosuiteEnv](_make) as envs:  # an env per task, made for its first missing shard
        return _cache(cache_dir, envs).gather(shards)
