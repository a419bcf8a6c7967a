"""ITPS on Kitchen (thesis §2.3): ``itps-kitchen-data``, the skill data of the microwave and sink tasks.

* ``itps-kitchen-data``: one trial = one episode seed: the scripted expert's
  skills from that reset seed on the seed's task (``tasks[seed % len(tasks)]``:
  by default even seeds ``microwave``, odd seeds ``sink``), written as one
  shard under ``cache_dir`` (:mod:`~steer_envs.bench.suites.itps_kitchen.data`).
  Running it through ``steer-bench run`` gives generation in parallel
  (``--workers``, ``--executor ray``), resumption (a finished shard is never
  rebuilt) and the runner's progress bar;
  :func:`~steer_envs.bench.suites.itps_kitchen.data.skills_dataset` merges the shards.

``cache_dir`` defaults to ``$XDG_CACHE_HOME/steer-envs/itps-kitchen``
(``~/.cache`` when unset). Trials run with one BLAS thread.

>>> DataParams(max_skills=0)
Traceback (most recent call last):
ValueError: itps-kitchen-data: parameter 'max_skills' must be >= 1, got 0
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Metric, Suite, Trial, TrialResult, register_suite
from steer_envs.utils.threads import single_threaded

__all__ = ["DATA_SUITE", "ENV_ID", "TASKS", "DataParams", "default_cache_dir", "run_data_trial"]

DATA_SUITE = "itps-kitchen-data"
ENV_ID = "steer_envs/Kitchen-v0"
#: the env's tasks (``KITCHEN_TASKS``; spelled out so that registering the suite imports no env module).
TASKS = ("clean", "microwave", "sink")


def default_cache_dir() -> str:
    """``$XDG_CACHE_HOME/steer-envs/itps-kitchen`` (``~/.cache`` when unset)."""
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return str(Path(root) / "steer-envs" / "itps-kitchen")


@dataclass(frozen=True)
class DataParams(SuiteParams):
    """What a shard is built from: the tasks the seeds cycle through, the most skills an episode, the cache folder.

    Seed ``s`` records an episode of ``tasks[s % len(tasks)]`` (one of
    :data:`~steer_envs.envs.robosuite.kitchen.KITCHEN_TASKS`); ``cache_dir`` "" is the default folder.
    """

    suite_name: ClassVar[str] = DATA_SUITE
    tasks: tuple[str, ...] = ("microwave", "sink")
    max_skills: int = 8
    cache_dir: str = ""

    def __post_init__(self) -> None:
        ok = 0 < len(self.tasks) <= 100 and all(t in TASKS for t in self.tasks)
        self.require("tasks", ok, f"a non-empty list of {TASKS}")
        self.require_at_least(1, "max_skills")
        self.require_at_most(1000, "max_skills")

    @property
    def cache(self) -> str:
        """The cache folder in use."""
        return self.cache_dir or default_cache_dir()

    def task_of(self, seed: int) -> str:
        """The task of episode seed ``seed``."""
        return self.tasks[seed % len(self.tasks)]


def run_data_trial(trial: Trial) -> TrialResult:
    """One episode seed: build (or find) its shard."""
    from steer_envs.bench.suites.itps_kitchen.data import ShardSettings, ensure_shard
    from steer_envs.envs.robosuite.kitchen import kitchen_task

    if trial.env != ENV_ID:
        raise ValueError(f"{DATA_SUITE}: unknown env {trial.env!r}; expected {ENV_ID!r}")
    params = DataParams.from_json(trial.params)
    task = params.task_of(trial.seed)
    with single_threaded():
        records, path, built = ensure_shard(params.cache, ShardSettings(trial.seed, task, params.max_skills))
    n = max(len(records), 1)
    metrics = {
        "skills": len(records),
        "skill_success": sum(r.success for r in records) / n,
        "violations": sum(r.violation for r in records) / n,
        "goal": bool(records) and records[-1].mode_after in kitchen_task(task).goal,
        "steps": sum(len(r) for r in records) / n,
        "built": built,
    }
    extra = {"shard": str(path), "task": task, "skills": [r.name for r in records], "steps": [len(r) for r in records]}
    return TrialResult(metrics, extra)


register_suite(
    Suite(
        name=DATA_SUITE,
        description=(
            "Kitchen skill data: per episode seed, the scripted expert's door and bowl skills on the seed's task "
            "(tasks alternate microwave / sink) recorded as one shard under cache_dir (resumable; --workers "
            "runs shards in parallel)."
        ),
        metrics=(
            Metric("skills", "skills in the shard", fmt=".1f"),
            Metric("skill_success", "skills whose outcome the world shows at their end", fmt=".2f"),
            Metric("violations", "skills that reported a constraint violation", higher_is_better=False, fmt=".2f"),
            Metric("goal", "the episode reached its task's goal", fmt=".2f"),
            Metric("steps", "control steps per skill", fmt=".0f"),
            Metric("built", "the shard was built by this trial (0: found on disk)", kind="timing", fmt=".0f"),
        ),
        run_trial=run_data_trial,
        envs=(ENV_ID,),
        params=DataParams(),
        default_seeds=120,
        quick={"tasks": ["sink"]},
        quick_seeds=1,
    )
)
