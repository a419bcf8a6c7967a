"""BlockStack skill data through the bench: one shard per episode seed, then one merged data set.

A shard is the unit of work of the ``itps-blockstack-data`` suite (one trial =
one episode seed): :func:`~steer_envs.data.blockstack_skills.record_episode`
with ``skills_per_episode`` skills, written atomically as one
:func:`~steer_envs.data.blockstack_skills.save_skills` file under
``cache_dir/shards``. Generation therefore runs through the bench executors
(``--workers``, Ray), resumes where it stopped (a readable shard on disk is
never rebuilt) and shows the runner's progress bar. :func:`skills_dataset`
reads the shards of seeds ``0..n_episodes-1`` (building any missing one here)
and writes the merged file atomically beside them. Run as a module, it writes
the skill-plan training set of the BlockStack Diffusion Policy
(:func:`~steer_envs.data.blockstack_plans.to_plan_dataset`)::

    python -m steer_envs.bench.suites.itps_blockstack.data --cache-dir DIR --episodes 200 --out plans.npz
"""

from __future__ import annotations

import argparse
import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path

from steer_envs.core.validation import integer
from steer_envs.data import blockstack_plans as plans
from steer_envs.data import blockstack_skills as bs
from steer_envs.data.trajectories import save_trajectories
from steer_envs.io import DatasetError

#: bump when shard contents change for the same settings (old shards are then not reused).
SHARD_VERSION = 1


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
        return f"blockstack-ep{self.seed:05d}-{self.digest}.npz"


def shard_path(cache_dir: str | Path, settings: ShardSettings) -> Path:
    """Where the shard of ``settings`` lives."""
    return Path(cache_dir) / "shards" / settings.file_name()


def _read(path: Path) -> list[bs.SkillRecord] | None:
    """The file's records, or None when there is no readable file (missing, torn by hand, an older format)."""
    if not path.exists():
        return None
    try:
        return bs.load_skills(path)[0]
    except DatasetError:
        return None


def _write_shard(path: Path, settings: ShardSettings, env: bs.BlockStackEnv) -> list[bs.SkillRecord]:
    if settings.branches:
        records = bs.record_branches(env, settings.seed, settings.skills_per_episode, settings.branches)
    else:
        records = bs.record_episode(env, settings.seed, settings.skills_per_episode)
    bs.save_skills(path, records, meta={"shard": asdict(settings), "shard_version": SHARD_VERSION})
    return records


def ensure_shard(cache_dir: str | Path, settings: ShardSettings) -> tuple[list[bs.SkillRecord], Path, bool]:
    """The shard (records, file, built now), built and written atomically unless a readable file exists."""
    path = shard_path(cache_dir, settings)
    records = _read(path)
    if records is not None:
        return records, path, False
    env = bs.make_env()
    try:
        return _write_shard(path, settings, env), path, True
    finally:
        env.close()


def skills_dataset(
    cache_dir: str | Path, n_episodes: int, skills_per_episode: int, branches: int = 0
) -> tuple[list[bs.SkillRecord], Path]:
    """Every skill of the shards of seeds ``0..n_episodes-1`` (missing shards built here) and the merged file.

    The merged file (``cache_dir/blockstack-skills-...npz``, written atomically)
    is reused when it exists and reads back; convert the records with
    :func:`~steer_envs.data.blockstack_skills.to_trajectory_dataset`.
    """
    n_episodes = integer(n_episodes, "n_episodes", low=1, high=100_000, owner="skills_dataset")
    skills_per_episode = integer(skills_per_episode, "skills_per_episode", low=1, high=10_000, owner="skills_dataset")
    branches = integer(branches, "branches", low=0, high=100, owner="skills_dataset")
    digest = ShardSettings(0, skills_per_episode, branches).digest
    merged = Path(cache_dir) / f"blockstack-skills-{n_episodes}x{skills_per_episode}-{digest}.npz"
    found = _read(merged)
    if found is not None:
        return found, merged
    out: list[bs.SkillRecord] = []
    env = None  # made once, for the first missing shard
    try:
        for seed in range(n_episodes):
            settings = ShardSettings(seed, skills_per_episode, branches)
            path = shard_path(cache_dir, settings)
            records = _read(path)
            if records is None:
                env = env or bs.make_env()
                records = _write_shard(path, settings, env)
            out += records
    finally:
        if env is not None:
            env.close()
    meta = {
        "n_episodes": n_episodes,
        "skills_per_episode": skills_per_episode,
        "branches": branches,
        "shard_version": SHARD_VERSION,
    }
    bs.save_skills(merged, out, meta=meta)
    return out, merged


def main(argv: list[str] | None = None) -> int:
    """CLI: the skill-plan data set of the shards (missing shards are built here); exit 2 on a usage error."""
    from steer_envs.bench.suites.itps_blockstack.suite import DataParams

    parser = argparse.ArgumentParser(
        prog="python -m steer_envs.bench.suites.itps_blockstack.data",
        description="Write the BlockStack skill-plan data set (one plan per successful skill) "
        "from the itps-blockstack-data shards; build the shards first in parallel with "
        "`steer-bench run itps-blockstack-data --seeds N --workers 2 --param cache_dir=DIR`.",
    )
    parser.add_argument("--cache-dir", required=True, help="the shards' cache folder (the suite's cache_dir)")
    parser.add_argument("--episodes", type=int, default=200, help="episode seeds 0..N-1 (default 200)")
    parser.add_argument(
        "--skills-per-episode",
        type=int,
        default=DataParams.skills_per_episode,
        help=f"skills per shard (default {DataParams.skills_per_episode}, the suite's)",
    )
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
        "--shift",
        type=float,
        default=0.0,
        help="the copies' random xy shift of the whole scene, at most this (m; default 0)",
    )
    parser.add_argument(
        "--yaw",
        type=float,
        default=0.0,
        help="the copies' random turn of the whole scene, at most this (rad; default 0)",
    )
    parser.add_argument("--out", required=True, help="output .npz (a steer_envs.data.trajectories file)")
    args = parser.parse_args(argv)
    if not str(args.out).endswith(".npz"):
        parser.error(f"--out must end with .npz, got {args.out!r}")
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
