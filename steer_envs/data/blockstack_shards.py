"""BlockStack skill data in shards: one shard per episode seed, then one merged data set.

A shard is one episode seed's :func:`~steer_envs.data.blockstack_skills.record_episode`
(``skills_per_episode`` skills; with ``branches``, :func:`~steer_envs.data.blockstack_skills.record_branches`),
written atomically as one :func:`~steer_envs.data.blockstack_skills.save_skills`
file under ``cache_dir/shards`` by the shared :class:`~steer_envs.data.shards.ShardCache`:
a readable shard on disk is never rebuilt, so generation resumes where it
stopped and runs in parallel processes (the ``itps-blockstack-data`` suite
runs one shard per trial). :func:`skills_dataset` reads the shards of seeds
``0..n_episodes-1`` (building any missing one here) and writes the merged file
atomically beside them. Run as a module, it writes the skill-plan training set
of the BlockStack Diffusion Policy (:func:`~steer_envs.data.blockstack_plans.to_plan_dataset`)::

    python -m steer_envs.data.blockstack_shards --cache-dir DIR --episodes 200 --out plans.npz

The default cache folder is :func:`~steer_envs.io.default_cache_dir` ``("itps-blockstack")``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from steer_envs.core.validation import integer
from steer_envs.data import blockstack_plans as plans
from steer_envs.data import blockstack_skills as bs
from steer_envs.data.shards import LazyEnvs, ShardCache, plan_set_args, plan_set_parser, shard_file
from steer_envs.data.trajectories import save_trajectories

__all__ = ["CACHE_NAME", "SHARD_VERSION", "ShardSettings", "ensure_shard", "main", "shard_path", "skills_dataset"]

#: bump when shard contents change for the same settings (old shards are then not reused).
SHARD_VERSION = 1
#: the folder name of :func:`~steer_envs.io.default_cache_dir` for these shards.
CACHE_NAME = "itps-blockstack"


@dataclass(frozen=True)
class ShardSettings:
    """What one shard is built from (its file name hashes these)."""

    seed: int
    skills_per_episode: int
    branches: int = 0

    @property
    def digest(self) -> str:
        """A hash of what the contents depend on besides the seed (versions, skills per episode, branches)."""
        key: dict[str, int] = {"v": SHARD_VERSION, "format": bs.FORMAT_VERSION, "skills": self.skills_per_episode}
        if self.branches:  # unbranched shards keep the names they had before branches existed
            key["branches"] = self.branches
        return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:10]

    def file_name(self) -> str:
        """``blockstack-ep<seed>-<digest>.npz``."""
        return f"blockstack-ep{self.seed:05d}-{self.digest}.npz"


def _record(env: bs.BlockStackEnv, settings: ShardSettings) -> list[bs.SkillRecord]:
    if settings.branches:
        return bs.record_branches(env, settings.seed, settings.skills_per_episode, settings.branches)
    return bs.record_episode(env, settings.seed, settings.skills_per_episode)


def _save(path: Path, records: Sequence[bs.SkillRecord], meta: Mapping[str, Any]) -> Path:
    return bs.save_skills(path, records, meta=meta)


def _cache(cache_dir: str | Path, envs: LazyEnvs[None, bs.BlockStackEnv]) -> ShardCache[ShardSettings, bs.SkillRecord]:
    return ShardCache(
        Path(cache_dir),
        name=ShardSettings.file_name,
        build=lambda settings: _record(envs.get(None), settings),
        load=lambda path: bs.load_skills(path)[0],
        save=_save,
        meta=lambda settings: {"shard": asdict(settings), "shard_version": SHARD_VERSION},
    )


def shard_path(cache_dir: str | Path, settings: ShardSettings) -> Path:
    """Where the shard of ``settings`` lives (``cache_dir/shards/<file name>``)."""
    return shard_file(cache_dir, settings.file_name())


def ensure_shard(cache_dir: str | Path, settings: ShardSettings) -> tuple[list[bs.SkillRecord], Path, bool]:
    """The shard (records, file, built now), built and written atomically unless a readable file exists."""
    with LazyEnvs[None, bs.BlockStackEnv](lambda _: bs.make_env()) as envs:
        return _cache(cache_dir, envs).ensure(settings)


def skills_dataset(
    cache_dir: str | Path, n_episodes: int, skills_per_episode: int, branches: int = 0
) -> tuple[list[bs.SkillRecord], Path]:
    """Every skill of the shards of seeds ``0..n_episodes-1`` (missing shards built here) and the merged file.

    The merged file (``cache_dir/blockstack-skills-...npz``, written atomically)
    is reused when it exists and reads back; convert the records with
    :func:`~steer_envs.data.blockstack_skills.to_trajectory_dataset` or
    :func:`~steer_envs.data.blockstack_plans.to_plan_dataset`.
    """
    n_episodes = integer(n_episodes, "n_episodes", low=1, high=100_000, owner="skills_dataset")
    skills_per_episode = integer(skills_per_episode, "skills_per_episode", low=1, high=10_000, owner="skills_dataset")
    branches = integer(branches, "branches", low=0, high=100, owner="skills_dataset")
    digest = ShardSettings(0, skills_per_episode, branches).digest
    meta = {
        "n_episodes": n_episodes,
        "skills_per_episode": skills_per_episode,
        "branches": branches,
        "shard_version": SHARD_VERSION,
    }
    shards = [ShardSettings(seed, skills_per_episode, branches) for seed in range(n_episodes)]
    with LazyEnvs[None, bs.BlockStackEnv](lambda _: bs.make_env()) as envs:  # made once, for the first missing shard
        return _cache(cache_dir, envs).merged(
            f"blockstack-skills-{n_episodes}x{skills_per_episode}-{digest}.npz", shards, meta
        )


def _parser() -> argparse.ArgumentParser:
    parser = plan_set_parser("blockstack_shards", "BlockStack", "itps-blockstack-data", episodes=200)
    parser.add_argument("--skills-per-episode", type=int, default=12, help="skills per shard (default 12)")
    parser.add_argument(
        "--branches", type=int, default=0, help="alternative skills per skill start in the shards (default 0)"
    )
    parser.add_argument(
        "--permutations",
        type=int,
        default=7,
        help="extra copies of each skill with the cubes listed in another order (default 7; see to_plan_dataset)",
    )
    parser.add_argument(
        "--shift", type=float, default=0.0, help="the copies' random xy shift of the whole scene, at most this (m)"
    )
    parser.add_argument(
        "--yaw", type=float, default=0.0, help="the copies' random turn of the whole scene, at most this (rad)"
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """CLI: the skill-plan data set of the shards (missing shards are built here); exit 2 on a usage error."""
    parser = _parser()
    args = plan_set_args(parser, argv)
    try:
        records, merged = skills_dataset(args.cache_dir, args.episodes, args.skills_per_episode, args.branches)
        meta = {"episodes": args.episodes, "skills_per_episode": args.skills_per_episode}
        if args.branches:
            meta["branches"] = args.branches
        dataset = plans.to_plan_dataset(
            records, permutations=args.permutations, shift=args.shift, yaw=args.yaw, meta=meta
        )
    except (TypeError, ValueError) as err:
        parser.error(str(err))
    path = save_trajectories(dataset, Path(args.out))
    kept = len(dataset.meta["skills"])
    print(
        f"wrote {path}: {kept} plans ({args.permutations} cube permutations a skill) of {len(records)} skills "
        f"({dataset.meta['dropped_too_long']} too long) from {merged.name}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
