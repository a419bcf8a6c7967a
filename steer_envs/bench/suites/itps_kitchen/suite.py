"""ITPS on Kitchen (thesis §2.3): ``itps-kitchen-data`` (the skill data) and ``itps-kitchen`` (Table 2.3).

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

* ``itps-kitchen``: one trial = one evaluation scene (the seed) x one method:
  a skill-level rollout of the frozen Kitchen skill Diffusion Policy that a
  simulated user steers at each of the first ``max_interactions`` skill
  boundaries by clicking, in the scene camera, the target of a legal skill other
  than the one it watched the policy sample
  (:mod:`~steer_envs.bench.suites.itps_kitchen.protocol`). Methods (thesis
  Table 2.3): RS (unsteered), GD (point, ``gd_ratio`` 5 at every DDIM step), SS
  (point, ``ss_ratio`` 100, 4 MCMC iterations), OP (a physical push of the end
  effector ``op_distance`` m toward the click, then RS). Seeds alternate the
  thesis's two tasks (``tasks``, default microwave / sink: the policy's merged
  training setting). The policy comes from ``loader`` (the committed
  checkpoint, :func:`steer_envs.baselines.pretrained.load_kitchen`) or a
  ``checkpoint`` file; while it is missing the suite runs nothing and says so.
  The ``plot`` hook draws the quadrants beside the thesis's and a rollout strip
  (:mod:`~steer_envs.bench.suites.itps_kitchen.plots`); the guide-ratio sweep of
  Fig. 2.10 is ``python -m steer_envs.bench.suites.itps_kitchen.sweep``.
  Not part of the quick tour: one trial executes whole 32-waypoint skills on the
  arm and builds a rendering env, so even one seed of the four methods takes
  about a minute on one core.

>>> DataParams(max_skills=0)
Traceback (most recent call last):
ValueError: itps-kitchen-data: parameter 'max_skills' must be >= 1, got 0
>>> SteerParams(gd_ratio=-1.0)
Traceback (most recent call last):
ValueError: itps-kitchen: parameter 'gd_ratio' must be >= 0, got -1.0
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import (
    Finding,
    Metric,
    Reference,
    Suite,
    Trial,
    TrialPlan,
    TrialRequest,
    TrialResult,
    register_suite,
)
from steer_envs.utils.threads import limit_threads, single_threaded

__all__ = [
    "DATA_SUITE",
    "ENV_ID",
    "KITCHEN_LOADER",
    "SUITE_NAME",
    "TABLE_2_3",
    "TASKS",
    "DataParams",
    "SteerParams",
    "default_cache_dir",
    "run_data_trial",
    "run_steer_trial",
    "steer_findings",
]

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
    :data:`~steer_envs.envs.robosuite.kitchen.KITCHEN_TASKS`), or with
    ``every_task`` one episode of every task from the same scene (reset seed
    ``s``): then the scene alone cannot tell the policy which task's first
    skill to sample, and the merged data is multimodal at the shared start
    state, as the thesis's real kitchen was. ``perturbed_starts`` also records
    each episode's pushed copy (a second shard: every skill starts after the
    end effector was pushed partway toward its target, the states OP's push
    makes; off by default). ``cache_dir`` "" is the default folder.
    """

    suite_name: ClassVar[str] = DATA_SUITE
    tasks: tuple[str, ...] = ("microwave", "sink")
    max_skills: int = 8
    every_task: bool = False
    perturbed_starts: bool = False
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
        """The task of episode seed ``seed`` (the first of :meth:`tasks_of`)."""
        return self.tasks_of(seed)[0]

    def tasks_of(self, seed: int) -> tuple[str, ...]:
        """The tasks episode seed ``seed`` records: every task with ``every_task``, else ``tasks[seed % len]``."""
        return self.tasks if self.every_task else (self.tasks[seed % len(self.tasks)],)


def run_data_trial(trial: Trial) -> TrialResult:
    """One episode seed: build (or find) its shard."""
    from steer_envs.bench.suites.itps_kitchen.data import ensure_shard, shard_settings
    from steer_envs.envs.robosuite.kitchen import kitchen_task

    if trial.env != ENV_ID:
        raise ValueError(f"{DATA_SUITE}: unknown env {trial.env!r}; expected {ENV_ID!r}")
    params = DataParams.from_json(trial.params)
    tasks = params.tasks_of(trial.seed)
    records, paths, goals, built = [], [], [], False
    with single_threaded():
        for task in tasks:
            for settings in shard_settings(trial.seed, task, params.max_skills, params.perturbed_starts):
                shard, path, made = ensure_shard(params.cache, settings)
                records += shard
                paths.append(str(path))
                goals.append(bool(shard) and shard[-1].mode_after in kitchen_task(task).goal)
                built = built or made
    n = max(len(records), 1)
    metrics = {
        "skills": len(records),
        "skill_success": sum(r.success for r in records) / n,
        "violations": sum(r.violation for r in records) / n,
        "goal": sum(goals) / len(goals),
        "steps": sum(len(r) for r in records) / n,
        "built": built,
    }
    extra: dict[str, Any] = {
        "shard": paths[0],
        "task": tasks[0],
        "skills": [r.name for r in records],
        "steps": [len(r) for r in records],
    }
    if params.every_task or params.perturbed_starts:
        extra.update(shards=paths, tasks=list(tasks))
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


# ------------------------------------------------------------------ itps-kitchen
SUITE_NAME = "itps-kitchen"
#: the loader of the committed Kitchen checkpoint
KITCHEN_LOADER = "steer_envs.baselines.pretrained:load_kitchen"
METHODS = ("DP-RS", "DP-GD", "DP-SS", "DP-OP")

#: thesis Table 2.3 (real toy kitchen, pixel clicks; OP: physical corrections): method -> {metric: share}
TABLE_2_3: dict[str, dict[str, float]] = {
    "DP-RS": {"TA": 0.38, "CS": 0.90, "AS": 0.34, "AF": 0.04, "MS": 0.56, "MF": 0.06},
    "DP-GD": {"TA": 0.37, "CS": 0.82, "AS": 0.32, "AF": 0.05, "MS": 0.50, "MF": 0.13},
    "DP-SS": {"TA": 0.71, "CS": 0.73, "AS": 0.55, "AF": 0.16, "MS": 0.18, "MF": 0.11},
    "DP-OP": {"TA": 0.89, "CS": 0.37, "AS": 0.30, "AF": 0.59, "MS": 0.07, "MF": 0.04},
}


@dataclass(frozen=True)
class SteerParams(SuiteParams):
    """Parameters of ``itps-kitchen``.

    ``tasks`` the seeds cycle through; ``batch`` plans per sampling call (1,
    the default: the robot runs the one steered sample, as in the thesis's
    real-time rollouts, where GD at beta 5 aligns no better than RS; with a
    larger batch GD and SS run their best-aligned plan, which adds PR-style
    ranking);
    ``max_interactions`` steered skill boundaries per rollout and ``max_skills``
    skills at most; ``gd_ratio`` / ``ss_ratio`` GD's and SS's beta (thesis: 5 and
    100); ``op_distance`` OP's push (m); ``plot_seeds`` seeds that keep camera
    frames for the rollout strip; ``torch_threads`` per trial process (0:
    torch's default); ``loader`` a ``module:function`` returning the policy,
    ``checkpoint`` a checkpoint file that replaces it.
    """

    suite_name: ClassVar[str] = SUITE_NAME
    tasks: tuple[str, ...] = ("microwave", "sink")
    batch: int = 1
    max_interactions: int = 4
    max_skills: int = 6
    gd_ratio: float = 5.0
    ss_ratio: float = 100.0
    op_distance: float = 0.15
    plot_seeds: int = 1
    torch_threads: int = 1
    #: the denoiser's inference mode (``DiffusionPolicy.accelerate``; auto: ONNX Runtime where installed)
    accelerate: str = "auto"
    loader: str = KITCHEN_LOADER
    checkpoint: str = ""

    def __post_init__(self) -> None:
        ok = 0 < len(self.tasks) <= 100 and all(t in TASKS for t in self.tasks)
        self.require("tasks", ok, f"a non-empty list of {TASKS}")
        self.require_at_least(1, "batch")
        self.require_at_most(4096, "batch")
        self.require_at_least(1, "max_interactions")
        self.require_at_most(100, "max_interactions")
        self.require_at_least(1, "max_skills")
        self.require_at_most(100, "max_skills")
        self.require("gd_ratio", self.gd_ratio >= 0, ">= 0")
        self.require("ss_ratio", self.ss_ratio >= 0, ">= 0")
        self.require("op_distance", 0 <= self.op_distance <= 1, "in [0, 1] (m)")
        self.require_at_least(0, "plot_seeds")
        self.require("torch_threads", self.torch_threads >= 0, ">= 0 (0: torch's default)")
        from steer_envs.baselines.diffusion.acceleration import ACCELERATIONS  # here: it imports torch

        self.require_in("accelerate", ACCELERATIONS)

    def policy(self) -> Any:
        """The frozen skill policy (cached per process)."""
        from steer_envs.baselines.diffusion.acceleration import accelerated
        from steer_envs.bench.suites.itps_kitchen.protocol import load_kitchen_policy

        return accelerated(load_kitchen_policy(self.loader, self.checkpoint), self.accelerate, owner="accelerate")


def _plan_steer(suite: Suite, request: TrialRequest) -> TrialPlan:
    from steer_envs.bench.suites.itps_kitchen.protocol import POLICY_UNAVAILABLE

    params: SteerParams = suite.resolve_params(request.params, request.trials, base=request.base)
    try:
        params.policy()
    except POLICY_UNAVAILABLE as exc:
        note = (
            f"skipped every method: the Kitchen policy is not available ({type(exc).__name__}: {exc}); "
            "train it with scripts/train_kitchen_checkpoint.sh or set --param loader=module:function"
        )
        return TrialPlan((), (note,))
    trials = [
        suite.trial(env, method, seed, params)
        for env in request.envs
        for method in request.methods
        for seed in suite.seed_list(request)
    ]
    return TrialPlan(tuple(trials), ())


def run_steer_trial(trial: Trial) -> TrialResult:
    """One evaluation scene x one method: a rollout the clicking user steers."""
    from steer_envs.bench.suites.itps_kitchen.protocol import env_for, kitchen_trial

    if trial.env != ENV_ID:
        raise ValueError(f"{SUITE_NAME}: unknown env {trial.env!r}; expected {ENV_ID!r}")
    params = SteerParams.from_json(trial.params)
    task = params.tasks[trial.seed % len(params.tasks)]
    with limit_threads(blas_threads=1, torch_threads=params.torch_threads or None):
        return kitchen_trial(
            trial.seed,
            params.policy(),
            str(trial.method),
            tasks=params.tasks,
            batch=params.batch,
            max_interactions=params.max_interactions,
            max_skills=params.max_skills,
            gd_ratio=params.gd_ratio,
            ss_ratio=params.ss_ratio,
            op_distance=params.op_distance,
            keep_frames=trial.seed < params.plot_seeds,
            env=env_for(task),
        )


def steer_findings(table: Any) -> list[Finding]:
    """Table 2.3's findings, checked on a run's summary table."""
    ta, cs, aligned_success = (table.means(m, list(METHODS)) for m in ("TA", "CS", "AS"))
    findings = []
    claim = "SS raises aligned success over RS (thesis: +21 points)"
    holds = None if aligned_success is None else aligned_success["DP-SS"] > aligned_success["DP-RS"]
    detail = (
        "" if aligned_success is None else f"AS SS {aligned_success['DP-SS']:.2f} vs RS {aligned_success['DP-RS']:.2f}"
    )
    findings.append(Finding(claim, holds, detail))
    claim = "OP aligns most (highest TA) but fails most (lowest CS)"
    if ta is None or cs is None:
        findings.append(Finding(claim, None))
    else:
        holds = ta["DP-OP"] >= max(ta.values()) and cs["DP-OP"] <= min(cs.values())
        detail = ", ".join(f"{m[3:]} TA {ta[m]:.2f} CS {cs[m]:.2f}" for m in METHODS)
        findings.append(Finding(claim, holds, detail))
    claim = "GD at beta 5 barely changes alignment (TA within 0.1 of RS's)"
    holds = None if ta is None else abs(ta["DP-GD"] - ta["DP-RS"]) <= 0.1
    detail = "" if ta is None else f"TA GD {ta['DP-GD']:.2f} vs RS {ta['DP-RS']:.2f}"
    findings.append(Finding(claim, holds, detail))
    return findings


def _steer_references() -> tuple[Reference, ...]:
    return tuple(
        Reference(metric, value, env=ENV_ID, method=method, source="thesis Table 2.3")
        for method, values in TABLE_2_3.items()
        for metric, value in values.items()
    )


def _plot_steer(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    from steer_envs.bench.suites.itps_kitchen.plots import plot_kitchen

    return plot_kitchen(suite, records, out_dir)


_SHARE = "share of the trial's interactions"
register_suite(
    Suite(
        name=SUITE_NAME,
        description=(
            "ITPS kitchen (thesis Table 2.3): a simulated user clicks a pixel on the target of a legal skill other "
            "than the one the skill Diffusion Policy sampled; RS, GD (beta 5), SS (beta 100) and OP (a push) "
            "steer the next skill; TA, CS and the AS/AF/MS/MF quadrants."
        ),
        metrics=(
            Metric("TA", f"aligned: the run plan does the intended skill ({_SHARE})", fmt=".2f"),
            Metric("CS", f"success: the skill happened, legally in the task tree, no violation ({_SHARE})", fmt=".2f"),
            Metric("AS", "aligned success", fmt=".2f"),
            Metric("AF", "aligned failure", higher_is_better=False, fmt=".2f"),
            Metric("MS", "misaligned success", higher_is_better=False, fmt=".2f"),
            Metric("MF", "misaligned failure", higher_is_better=False, fmt=".2f"),
            Metric("goal", "the rollout reached its task's goal", fmt=".2f"),
            Metric("skills", "skills run in the rollout", fmt=".1f"),
            Metric("interactions", "steered skill boundaries of the rollout", fmt=".1f"),
            Metric(
                "latency_ms",
                "ms per steering call (OP: push + sampling)",
                kind="timing",
                higher_is_better=False,
                fmt=".0f",
            ),
        ),
        run_trial=run_steer_trial,
        envs=(ENV_ID,),
        methods=METHODS,
        params=SteerParams(),
        default_seeds=20,
        generate=_plan_steer,
        references=_steer_references(),
        plot=_plot_steer,
        findings=steer_findings,
    )
)
