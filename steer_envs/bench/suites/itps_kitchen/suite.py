"""ITPS on Kitchen (thesis §2.3): ``itps-kitchen-data`` (the skill data) and ``itps-kitchen`` (Table 2.3).

* ``itps-kitchen-data``: one trial = one episode seed: the scripted expert's
  skills from that reset seed on the seed's task (``tasks[seed % len(tasks)]``:
  by default even seeds ``microwave``, odd seeds ``sink``), written as one
  shard under ``cache_dir`` (:mod:`~steer_envs.data.kitchen_shards`).
  Running it through ``steer-bench run`` gives generation in parallel
  (``--workers``, ``--executor ray``), resumption (a finished shard is never
  rebuilt) and the runner's progress bar;
  :func:`~steer_envs.data.kitchen_shards.skills_dataset` merges the shards.

``cache_dir`` defaults to ``$XDG_CACHE_HOME/steer-envs/itps-kitchen``
(``~/.cache`` when unset). Trials run with one BLAS thread.

* ``itps-kitchen``: one trial = one evaluation scene (the seed) x one method:
  a skill-level rollout of the frozen Kitchen skill Diffusion Policy that a
  simulated user steers at each of the first ``max_interactions`` skill
  boundaries by clicking, in the scene camera, the target of a legal skill other
  than the one it watched the policy sample
  (:func:`~steer_envs.steering.kitchen.kitchen_trial`; ``execution``
  ``open_loop`` or ``closed_loop``: how the plans run on the arm, scored
  apart from the plans' validity by ``valid`` and ``executed_ok``). Methods (thesis
  Table 2.3): RS (unsteered), GD (point, ``gd_ratio`` 5 at every DDIM step), SS
  (point, ``ss_ratio`` 100, 4 MCMC iterations), OP (a physical push of the end
  effector ``op_distance`` m toward the click, then RS). Seeds alternate the
  thesis's two tasks (``tasks``, default microwave / sink: the policy's merged
  training setting). The policy comes from ``loader`` (the committed
  checkpoint, ``load_pretrained("kitchen")`` of :mod:`steer_envs.baselines.pretrained`) or a
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

from dataclasses import dataclass
from typing import Any, ClassVar

from steer_envs.bench.findings import judge
from steer_envs.bench.metrics import (
    BUILT,
    QUADRANT_METRICS,
    SHARE,
    SKILL_OUTCOME_METRICS,
    skill_outcomes,
    table_references,
)
from steer_envs.bench.params import PolicyLoader, SuiteParams
from steer_envs.bench.policies import PRETRAINED_LOADER, SkillPolicyParams, policy_planner
from steer_envs.bench.suite import Finding, Metric, Suite, Trial, TrialResult, register_suite
from steer_envs.bench.trials import check_trial
from steer_envs.control.plans import EXECUTIONS
from steer_envs.io import default_cache_dir
from steer_envs.utils.fields import same_named
from steer_envs.utils.threads import single_threaded

__all__ = [
    "DATA_SUITE",
    "ENV_ID",
    "SUITE_NAME",
    "TABLE_2_3",
    "TASKS",
    "DataParams",
    "SteerParams",
    "run_data_trial",
    "run_steer_trial",
    "steer_findings",
]

DATA_SUITE = "itps-kitchen-data"
ENV_ID = "steer_envs/Kitchen-v0"
#: the env's tasks (``KITCHEN_TASKS``; spelled out so that registering the suite imports no env module).
TASKS = ("clean", "microwave", "sink")


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
        self.require_between(1, 1000, "max_skills")

    @property
    def cache(self) -> str:
        """The cache folder in use."""
        return self.cache_dir or str(default_cache_dir("itps-kitchen"))

    def task_of(self, seed: int) -> str:
        """The task of episode seed ``seed`` (the first of :meth:`tasks_of`)."""
        return self.tasks_of(seed)[0]

    def tasks_of(self, seed: int) -> tuple[str, ...]:
        """The tasks episode seed ``seed`` records: every task with ``every_task``, else ``tasks[seed % len]``."""
        return self.tasks if self.every_task else (self.tasks[seed % len(self.tasks)],)


def run_data_trial(trial: Trial) -> TrialResult:
    """One episode seed: build (or find) its shard."""
    from steer_envs.data.kitchen_shards import ensure_shard, shard_settings
    from steer_envs.envs.robosuite.kitchen import kitchen_task

    check_trial(trial, envs=(ENV_ID,))
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
        **skill_outcomes(records),
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
            *SKILL_OUTCOME_METRICS,
            Metric("goal", "the episode reached its task's goal", fmt=".2f"),
            Metric("steps", "control steps per skill", fmt=".0f"),
            BUILT,
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
#: the columns of Table 2.3 (:data:`steer_envs.steering.kitchen.METHODS`; spelled out so that registering the suite
#: imports no robosuite module)
METHODS = ("DP-RS", "DP-GD", "DP-SS", "DP-OP")

#: thesis Table 2.3 (real toy kitchen, pixel clicks; OP: physical corrections): method -> {metric: share}
TABLE_2_3: dict[str, dict[str, float]] = {
    "DP-RS": {"TA": 0.38, "CS": 0.90, "AS": 0.34, "AF": 0.04, "MS": 0.56, "MF": 0.06},
    "DP-GD": {"TA": 0.37, "CS": 0.82, "AS": 0.32, "AF": 0.05, "MS": 0.50, "MF": 0.13},
    "DP-SS": {"TA": 0.71, "CS": 0.73, "AS": 0.55, "AF": 0.16, "MS": 0.18, "MF": 0.11},
    "DP-OP": {"TA": 0.89, "CS": 0.37, "AS": 0.30, "AF": 0.59, "MS": 0.07, "MF": 0.04},
}


@dataclass(frozen=True)
class SteerParams(SkillPolicyParams):
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
    torch's default); ``loader`` the policy's loader (called with ``"kitchen"``): ``pretrained`` or,
    with ``--allow-import``, any ``module:function``; ``checkpoint`` a checkpoint file that replaces it.
    ``execution`` how the plans run on the arm: ``open_loop`` (the default) or ``closed_loop``
    (waypoints reached within a tolerance, grasps checked and retried, releases settled;
    :func:`~steer_envs.control.kitchen.execute_kitchen_plan`).
    """

    suite_name: ClassVar[str] = SUITE_NAME
    policy_name: ClassVar[str] = "kitchen"
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
    loader: PolicyLoader = PRETRAINED_LOADER
    checkpoint: str = ""
    execution: str = "open_loop"

    def __post_init__(self) -> None:
        ok = 0 < len(self.tasks) <= 100 and all(t in TASKS for t in self.tasks)
        self.require("tasks", ok, f"a non-empty list of {TASKS}")
        self.require_steering()
        self.require_in("execution", EXECUTIONS)
        self.require_between(1, 100, "max_skills")
        self.require("gd_ratio", self.gd_ratio >= 0, ">= 0")
        self.require("ss_ratio", self.ss_ratio >= 0, ">= 0")
        self.require("op_distance", 0 <= self.op_distance <= 1, "in [0, 1] (m)")


def run_steer_trial(trial: Trial) -> TrialResult:
    """One evaluation scene x one method: a rollout the clicking user steers."""
    from steer_envs.steering.kitchen import env_for, kitchen_trial

    check_trial(trial, envs=(ENV_ID,))
    params = SteerParams.from_json(trial.params)
    task = params.tasks[trial.seed % len(params.tasks)]
    with params.thread_limits():
        metrics, extra = kitchen_trial(
            trial.seed,
            params.policy(),
            str(trial.method),
            **same_named(kitchen_trial, params, keep_frames=trial.seed < params.plot_seeds, env=env_for(task)),
        )
    return TrialResult(metrics, extra)


def steer_findings(table: Any) -> list[Finding]:
    """Table 2.3's findings, checked on a run's summary table."""
    ta, cs, aligned_success = (table.means(m, list(METHODS)) for m in ("TA", "CS", "AS"))
    return [
        judge(
            "SS raises aligned success over RS (thesis: +21 points)",
            aligned_success,
            lambda v: v["DP-SS"] > v["DP-RS"],
            "AS SS {DP-SS:.2f} vs RS {DP-RS:.2f}",
        ),
        judge(
            "OP aligns most (highest TA) but fails most (lowest CS)",
            {"TA": ta, "CS": cs},
            lambda v: v["TA"]["DP-OP"] >= max(v["TA"].values()) and v["CS"]["DP-OP"] <= min(v["CS"].values()),
            lambda v: ", ".join(f"{m[3:]} TA {v['TA'][m]:.2f} CS {v['CS'][m]:.2f}" for m in METHODS),
        ),
        judge(
            "GD at beta 5 barely changes alignment (TA within 0.1 of RS's)",
            ta,
            lambda v: abs(v["DP-GD"] - v["DP-RS"]) <= 0.1,
            "TA GD {DP-GD:.2f} vs RS {DP-RS:.2f}",
        ),
    ]


register_suite(
    Suite(
        name=SUITE_NAME,
        description=(
            "ITPS kitchen (thesis Table 2.3): a simulated user clicks a pixel on the target of a legal skill other "
            "than the one the skill Diffusion Policy sampled; RS, GD (beta 5), SS (beta 100) and OP (a push) "
            "steer the next skill; TA, CS and the AS/AF/MS/MF quadrants."
        ),
        metrics=(
            Metric("TA", f"aligned: the run plan does the intended skill ({SHARE})", fmt=".2f"),
            Metric("CS", f"success: the skill happened, legally in the task tree, no violation ({SHARE})", fmt=".2f"),
            *QUADRANT_METRICS,
            Metric("valid", f"the run plan is some skill, the intended one or not ({SHARE})", fmt=".2f"),
            Metric("executed_ok", "share of the valid plans whose execution did that skill, legally", fmt=".2f"),
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
        generate=policy_planner("the Kitchen policy", "train it with scripts/train_kitchen_checkpoint.sh"),
        references=table_references(TABLE_2_3, env=ENV_ID, source="thesis Table 2.3"),
        plot="steer_envs.bench.suites.itps_kitchen.plots:plot_kitchen",
        findings=steer_findings,
    )
)
