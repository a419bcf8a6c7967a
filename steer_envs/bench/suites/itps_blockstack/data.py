"""BlockStack skill data through the bench: one shard per episode seed, then one merged data set.

A shard is the unit of work of the ``itps-blockstack-data`` suite (one trial =
one episode seed): :func:`~steer_envs.data.blockstack_skills.record_episode`
with ``skills_per_episode`` skills, written atomically as one
:func:`~steer_envs.data.blockstack_skills.save_skills` file under
``cache_dir/shards``. Generation therefore runs through the bench executors
(``--workers``, Ray), resumes where it stopped (a readable shard on disk is
never rebuilt) and shows the runner's progress bar. :func:`skills_dataset`
reads the shards of seeds ``0..n_episodes-1`` (building any missing one here)
and writes the merged file atomically beside them.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path

from steer_envs.core.validation import integer
from steer_envs.data import blockstack_skills as bs
from steer_envs.io import DatasetError

#: bump when shard contents change for the same settings (old shards are then not reused).
SHARD_VERSION = 1


@dataclass(frozen=True)
class ShardSettings:
    """What one shard is built from (its file name hashes these)."""

    seed: int
    skills_per_episode: int

    @property
    def digest(self) -> str:
        """A hash of what the contents depend on besides the seed (versions, skills per episode)."""
        key = {"v": SHARD_VERSION, "format": bs.FORMAT_VERSION, "skills": self.skills_per_episode}
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
    cache_dir: str | Path, n_episodes: int, skills_per_episode: int
) -> tuple[list[bs.SkillRecord], Path]:
    """Every skill of the shards of seeds ``0..n_episodes-1`` (missing shards built here) and the merged file.

    The merged file (``cache_dir/blockstack-skills-...npz``, written atomically)
    is reused when it exists and reads back; convert the records with
    :func:`~steer_envs.data.blockstack_skills.to_trajectory_dataset`.
    """
    n_episodes = integer(n_episodes, "n_episodes", low=1, high=100_000, owner="skills_dataset")
    skills_per_episode = integer(skills_per_episode, "skills_per_episode", low=1, high=10_000, owner="skills_dataset")
    digest = ShardSettings(0, skills_per_episode).digest
    merged = Path(cache_dir) / f"blockstack-skills-{n_episodes}x{skills_per_episode}-{digest}.npz"
    found = _read(merged)
    if found is not None:
        return found, merged
    out: list[bs.SkillRecord] = []
    env = None  # made once, for the first missing shard
    try:
        for seed in range(n_episodes):
            settings = ShardSettings(seed, skills_per_episode)
            path = shard_path(cache_dir, settings)
            records = _read(path)
            if records is None:
                env = env or bs.make_env()
                records = _write_shard(path, settings, env)
            out += records
    finally:
        if env is not None:
            env.close()
    meta = {"n_episodes": n_episodes, "skills_per_episode": skills_per_episode, "shard_version": SHARD_VERSION}
    bs.save_skills(merged, out, meta=meta)
    return out, merged
