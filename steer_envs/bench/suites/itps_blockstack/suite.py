"""ITPS on BlockStack (thesis §2.3): ``itps-blockstack-data``, the random planner's skill data set.

* ``itps-blockstack-data``: one trial = one episode seed: ``skills_per_episode``
  skills of the random planner recorded from that reset seed and written as one
  shard under ``cache_dir`` (:mod:`~steer_envs.bench.suites.itps_blockstack.data`).
  Running it through ``steer-bench run`` gives generation in parallel
  (``--workers``, ``--executor ray``), resumption (a finished shard is never
  rebuilt) and the runner's progress bar;
  :func:`~steer_envs.bench.suites.itps_blockstack.data.skills_dataset` merges the shards.

``cache_dir`` defaults to ``$XDG_CACHE_HOME/steer-envs/itps-blockstack``
(``~/.cache`` when unset). Trials run with one BLAS thread.

>>> DataParams(skills_per_episode=0)
Traceback (most recent call last):
ValueError: itps-blockstack-data: parameter 'skills_per_episode' must be >= 1, got 0
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Metric, Suite, Trial, TrialResult, register_suite
from steer_envs.utils.threads import single_threaded

DATA_SUITE = "itps-blockstack-data"
ENV_ID = "steer_envs/BlockStack-v0"


def default_cache_dir() -> str:
    """``$XDG_CACHE_HOME/steer-envs/itps-blockstack`` (``~/.cache`` when unset)."""
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return str(Path(root) / "steer-envs" / "itps-blockstack")


@dataclass(frozen=True)
class DataParams(SuiteParams):
    """What a shard is built from: skills per episode, the cache folder ("": the default)."""

    suite_name: ClassVar[str] = DATA_SUITE
    skills_per_episode: int = 12
    cache_dir: str = ""

    def __post_init__(self) -> None:
        self.require_at_least(1, "skills_per_episode")
        self.require_at_most(10_000, "skills_per_episode")

    @property
    def cache(self) -> str:
        """The cache folder in use."""
        return self.cache_dir or default_cache_dir()


def run_data_trial(trial: Trial) -> TrialResult:
    """One episode seed: build (or find) its shard."""
    from steer_envs.bench.suites.itps_blockstack.data import ShardSettings, ensure_shard

    if trial.env != ENV_ID:
        raise ValueError(f"{DATA_SUITE}: unknown env {trial.env!r}; expected {ENV_ID!r}")
    params = DataParams.from_json(trial.params)
    with single_threaded():
        records, path, built = ensure_shard(params.cache, ShardSettings(trial.seed, params.skills_per_episode))
    metrics = {
        "skills": len(records),
        "skill_success": sum(r.success for r in records) / len(records),
        "violations": sum(r.violation for r in records) / len(records),
        "built": built,
    }
    extra = {"shard": str(path), "skills": [r.name for r in records], "steps": [len(r) for r in records]}
    return TrialResult(metrics, extra)


register_suite(
    Suite(
        name=DATA_SUITE,
        description=(
            "BlockStack skill data: per episode seed, skills_per_episode random-planner pick/place skills "
            "recorded as one shard under cache_dir (resumable; --workers runs shards in parallel)."
        ),
        metrics=(
            Metric("skills", "skills in the shard", fmt=".0f"),
            Metric("skill_success", "skills whose outcome the world shows at their end", fmt=".2f"),
            Metric("violations", "skills that reported a constraint violation", higher_is_better=False, fmt=".2f"),
            Metric("built", "the shard was built by this trial (0: found on disk)", kind="timing", fmt=".0f"),
        ),
        run_trial=run_data_trial,
        envs=(ENV_ID,),
        params=DataParams(),
        default_seeds=50,
        quick={"skills_per_episode": 3},
        quick_seeds=1,
    )
)
