"""Kitchen skill data in shards: one shard per episode seed and task, then one merged data set.

A shard is one episode seed's :func:`~steer_envs.data.kitchen_skills.record_episode`
on one task, written atomically as one :func:`~steer_envs.data.kitchen_skills.save_skills`
file under ``cache_dir/shards`` by the shared :class:`~steer_envs.data.shards.ShardCache`:
a readable shard on disk is never rebuilt, so generation resumes where it
stopped and runs in parallel processes (the ``itps-kitchen-data`` suite runs
one episode seed per trial). A process keeps one env per task for the shards
it builds (:func:`env_for`; building a Kitchen env takes seconds).
:func:`skills_dataset` reads the shards of seeds ``0..n_episodes-1`` (building
any missing one here) and writes the merged file atomically beside them. Run
as a module, it writes the skill-plan training set of the Kitchen Diffusion
Policy (:func:`~steer_envs.data.kitchen_plans.to_plan_dataset`)::

    python -m steer_envs.data.kitchen_shards --cache-dir DIR --episodes 120 --out plans.npz

With ``perturbed_starts`` (``--perturbed-starts``; off by default) every
episode seed and task has a second shard beside the plain one, recorded with
``record_episode(..., perturbed_starts=True)``: each skill starts after the end
effector was pushed partway toward its target (the states an OP push makes),
and the merged data holds both. The option is part of the shard's and the
merged file's name, so plain and pushed data are never mixed up; plain shards
keep the names they had before the option existed.

The default cache folder is :func:`~steer_envs.io.default_cache_dir` ``("itps-kitchen")``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from steer_envs.core.validation import boolean, integer, one_of
from steer_envs.data import kitchen_plans as plans
from steer_envs.data import kitchen_skills as ks
from steer_envs.data.shards import LazyEnvs, ShardCache, plan_set_args, plan_set_parser, shard_file
from steer_envs.data.trajectories import save_trajectories
from steer_envs.envs.robosuite.kitchen import KITCHEN_TASKS, KitchenEnv

__all__ = [
    "CACHE_NAME",
    "SHARD_VERSION",
    "ShardSettings",
    "close_envs",
    "ensure_shard",
    "env_for",
    "main",
    "record_shard",
    "shard_path",
    "shard_settings",
    "skills_dataset",
]

#: bump when shard contents change for the same settings (old shards are then not reused).
SHARD_VERSION = 1
#: the folder name of :func:`~steer_envs.io.default_cache_dir` for these shards.
CACHE_NAME = "itps-kitchen"

_ENVS: LazyEnvs[str, KitchenEnv] = LazyEnvs(ks.make_env)


@dataclass(frozen=True)
class ShardSettings:
    """What one shard is built from (its file name hashes these)."""

    seed: int
    task: str
    max_skills: int = 8
    #: each skill starts after a push toward its target (``record_episode(..., perturbed_starts=True)``)
    perturbed_starts: bool = False

    def __post_init__(self) -> None:
        integer(self.seed, "seed", low=0, owner="ShardSettings")
        one_of(self.task, "task", KITCHEN_TASKS, owner="ShardSettings")
        integer(self.max_skills, "max_skills", low=1, high=1000, owner="ShardSettings")
        boolean(self.perturbed_starts, "perturbed_starts", owner="ShardSettings")

    @property
    def digest(self) -> str:
        """A hash of what the contents depend on besides the seed and task (versions, most skills, pushes)."""
        key: dict[str, object] = {"v": SHARD_VERSION, "format": ks.FORMAT_VERSION, "max_skills": self.max_skills}
        if self.perturbed_starts:  # only when set: plain shards keep their digest
            key.update(perturbed_starts=True, push=[ks.PUSH_DISTANCE, ks.PUSH_JITTER])
        return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:10]

    def file_name(self) -> str:
        """``kitchen-<task>-ep<seed>[-push]-<digest>.npz``."""
        push = "-push" if self.perturbed_starts else ""
        return f"kitchen-{self.task}-ep{self.seed:05d}{push}-{self.digest}.npz"


def shard_settings(seed: int, task: str, max_skills: int = 8, perturbed_starts: bool = False) -> list[ShardSettings]:
    """The shards of one episode seed and task: the plain one, then with ``perturbed_starts`` the pushed one."""
    plain = ShardSettings(seed, task, max_skills)
    if not boolean(perturbed_starts, "perturbed_starts", owner="shard_settings"):
        return [plain]
    return [plain, ShardSettings(seed, task, max_skills, True)]


def shard_path(cache_dir: str | Path, settings: ShardSettings) -> Path:
    """Where the shard of ``settings`` lives (``cache_dir/shards/<file name>``)."""
    return shard_file(cache_dir, settings.file_name())


def env_for(task: str) -> KitchenEnv:
    """This process's env of ``task`` for building shards (made on first use, kept until :func:`close_envs`)."""
    return _ENVS.get(one_of(task, "task", KITCHEN_TASKS, owner="env_for"))


def close_envs() -> None:
    """Close and forget the envs :func:`env_for` made."""
    _ENVS.close()


def record_shard(settings: ShardSettings) -> list[ks.SkillRecord]:
    """The records of one shard, recorded on this process's env of its task (:func:`env_for`)."""
    records = ks.record_episode(
        env_for(settings.task),
        settings.seed,
        max_skills=settings.max_skills,
        perturbed_starts=settings.perturbed_starts,
    )
    if not records:  # pragma: no cover - every task needs a skill from the reset state
        raise RuntimeError(f"seed {settings.seed}: the {settings.task!r} episode recorded no skill")
    return records


def _save(path: Path, records: Sequence[ks.SkillRecord], meta: Mapping[str, Any]) -> Path:
    return ks.save_skills(path, records, meta=meta)


def _cache(cache_dir: str | Path) -> ShardCache[ShardSettings, ks.SkillRecord]:
    return ShardCache(
        Path(cache_dir),
        name=ShardSettings.file_name,
        build=record_shard,
        load=lambda path: ks.load_skills(path)[0],
        save=_save,
        meta=lambda settings: {"shard": asdict(settings), "shard_version": SHARD_VERSION},
    )


def ensure_shard(cache_dir: str | Path, settings: ShardSettings) -> tuple[list[ks.SkillRecord], Path, bool]:
    """The shard (records, file, built now), built and written atomically unless a readable file exists."""
    if not isinstance(settings, ShardSettings):
        raise TypeError(f"ensure_shard: `settings` must be a ShardSettings, got {type(settings).__name__}")
    return _cache(cache_dir).ensure(settings)


def skills_dataset(
    cache_dir: str | Path,
    n_episodes: int,
    tasks: Sequence[str] = ks.DATA_TASKS,
    max_skills: int = 8,
    every_task: bool = False,
    perturbed_starts: bool = False,
) -> tuple[list[ks.SkillRecord], Path]:
    """Every skill of the shards of seeds ``0..n_episodes-1`` (missing shards built here) and the merged file.

    Seed ``s`` is an episode of ``tasks[s % len(tasks)]``, or with
    ``every_task`` one episode of each task from the same scene (the suite's
    rules); with ``perturbed_starts`` each episode's plain shard is followed by
    its pushed one. The merged file (``cache_dir/kitchen-skills-...npz``, written
    atomically) is reused when it exists and reads back.
    """
    owner = "skills_dataset"
    n_episodes = integer(n_episodes, "n_episodes", low=1, high=100_000, owner=owner)
    max_skills = integer(max_skills, "max_skills", low=1, high=1000, owner=owner)
    if isinstance(tasks, str) or not isinstance(tasks, Sequence) or not tasks:
        raise TypeError(f"{owner}: `tasks` must be a non-empty sequence of task names, got {tasks!r}")
    tasks = tuple(one_of(t, "tasks", KITCHEN_TASKS, owner=owner) for t in tasks)
    every_task = boolean(every_task, "every_task", owner=owner)
    perturbed_starts = boolean(perturbed_starts, "perturbed_starts", owner=owner)
    digest = ShardSettings(0, tasks[0], max_skills, perturbed_starts).digest
    rule = "all" if every_task else "x"
    push = "-push" if perturbed_starts else ""
    shards = [
        settings
        for seed in range(n_episodes)
        for task in (tasks if every_task else (tasks[seed % len(tasks)],))
        for settings in shard_settings(seed, task, max_skills, perturbed_starts)
    ]
    meta: dict[str, Any] = {
        "n_episodes": n_episodes,
        "tasks": list(tasks),
        "every_task": every_task,
        "max_skills": max_skills,
        "shard_version": SHARD_VERSION,
    }
    if perturbed_starts:
        meta.update(perturbed_starts=True, push_distance=ks.PUSH_DISTANCE, push_jitter=ks.PUSH_JITTER)
    name = f"kitchen-skills-{n_episodes}{rule}{'-'.join(tasks)}{push}-{digest}.npz"
    return _cache(cache_dir).merged(name, shards, meta)


def _parser() -> argparse.ArgumentParser:
    parser = plan_set_parser("kitchen_shards", "Kitchen", "itps-kitchen-data", episodes=120)
    parser.add_argument(
        "--tasks",
        default=",".join(ks.DATA_TASKS),
        help=f"comma-separated tasks the seeds cycle through (default {','.join(ks.DATA_TASKS)})",
    )
    parser.add_argument("--max-skills", type=int, default=8, help="most skills an episode (default 8)")
    parser.add_argument(
        "--every-task",
        action="store_true",
        help="each seed is one episode of every task from the same scene (the suite's every_task)",
    )
    parser.add_argument(
        "--perturbed-starts",
        action="store_true",
        help="also each episode's pushed copy: every skill starts after the end effector was pushed partway "
        "toward its target (the suite's perturbed_starts)",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """CLI: the skill-plan data set of the shards (missing shards are built here); exit 2 on a usage error."""
    parser = _parser()
    args = plan_set_args(parser, argv)
    tasks = [t.strip() for t in str(args.tasks).split(",") if t.strip()]
    try:
        records, merged = skills_dataset(
            args.cache_dir, args.episodes, tasks, args.max_skills, args.every_task, args.perturbed_starts
        )
        meta = {"episodes": args.episodes, "tasks": tasks, "max_skills": args.max_skills, "every_task": args.every_task}
        if args.perturbed_starts:
            meta["perturbed_starts"] = True
        dataset = plans.to_plan_dataset(records, meta=meta)
    except (TypeError, ValueError) as err:
        parser.error(str(err))
    finally:
        close_envs()
    path = save_trajectories(dataset, Path(args.out))
    kept = Counter(dataset.meta["skills"])
    print(
        f"wrote {path}: {sum(kept.values())} plans of {len(records)} skills "
        f"({dataset.meta['dropped_too_long']} too long) from {merged.name}: "
        + ", ".join(f"{name} {kept[name]}" for name in sorted(kept))
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
