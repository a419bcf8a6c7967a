"""ITPS on BlockStack (thesis §2.3): ``itps-blockstack-data`` (the skill data) and ``itps-blockstack`` (Table 2.2).

* ``itps-blockstack-data``: one trial = one episode seed: ``skills_per_episode``
  skills of the random planner recorded from that reset seed and written as one
  shard under ``cache_dir`` (:mod:`~steer_envs.data.blockstack_shards`).
  Running it through ``steer-bench run`` gives generation in parallel
  (``--workers``, ``--executor ray``), resumption (a finished shard is never
  rebuilt) and the runner's progress bar;
  :func:`~steer_envs.data.blockstack_shards.skills_dataset` merges the shards.

``cache_dir`` defaults to ``$XDG_CACHE_HOME/steer-envs/itps-blockstack``
(``~/.cache`` when unset). Trials run with one BLAS thread.

* ``itps-blockstack``: one trial = one evaluation scene (the seed) x one
  method: a simulated user builds a tower of a seeded order by 3D sketches that
  steer the frozen skill Diffusion Policy
  (:func:`~steer_envs.steering.blockstack.tower_trial`). Methods: RS
  (unsteered), PR, GD with ``guide_ratio`` at every step (``DP-GD``), GD with
  guidance off for the last 50 of the 100 DDIM steps (``DP-GD-I50``, the
  thesis's "beta_{i<50} = 0"), GD at beta 25 every step (``DP-GD-B25``: the
  thesis's text gives beta 25 for Table 2.2, its header beta 100), SS; GD's and SS's DDIM steps re-derive the noise
  from the clipped plan estimate (``use_clipped_model_output``). The policy comes from ``loader`` (the
  committed checkpoint, ``load_pretrained("blockstack")`` of :mod:`steer_envs.baselines.pretrained`)
  or a ``checkpoint`` file; while it is missing the suite runs nothing and says
  so. Each steered method also runs with BlockStack's safety cost (``+safe``:
  :func:`~steer_envs.steering.blockstack.tower_safety_cost`, weight ``safety_weight``: the gripper closes
  only at a free cube and opens only where the held cube can rest). The ``plot`` hook draws steered plans
  like thesis Fig. 2.6 (:mod:`~steer_envs.bench.suites.itps_blockstack.plots`). ``FLOW-*`` runs
  Table 2.2's methods on the flow-matching policy of the same preset, network and data
  (``load_pretrained("blockstack-flow")`` or ``flow_checkpoint``; ``flow_steps`` Euler steps, 0: its own):
  flow vs DP at matched parameters and training samples. While it is missing, only ``FLOW-*`` is skipped.

>>> DataParams(skills_per_episode=0)
Traceback (most recent call last):
ValueError: itps-blockstack-data: parameter 'skills_per_episode' must be >= 1, got 0
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

from steer_envs.bench.findings import judge, listing, on_other_policy
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
from steer_envs.utils.threads import single_threaded

DATA_SUITE = "itps-blockstack-data"
#: Table 2.2's methods, then each steered one with the safety cost (``+safe``)
TABLE_METHODS = ("DP-RS", "DP-PR", "DP-GD", "DP-GD-I50", "DP-GD-B25", "DP-SS")
SAFE_METHODS = tuple(f"{m}+safe" for m in TABLE_METHODS if m != "DP-RS")
#: Table 2.2's methods on the flow-matching policy of the same preset and data (``FLOW-*``)
FLOW_METHODS = tuple(m.replace("DP-", "FLOW-", 1) for m in TABLE_METHODS)
METHODS = TABLE_METHODS + SAFE_METHODS + FLOW_METHODS
#: the shipped flow-matching skill policy (``load_pretrained``'s name)
FLOW_POLICY = "blockstack-flow"
ENV_ID = "steer_envs/BlockStack-v0"


@dataclass(frozen=True)
class DataParams(SuiteParams):
    """What a shard is built from: skills per episode, alternative skills per skill start, the cache folder.

    ``branches`` > 0 records that many other skills from each skill's start
    (:func:`~steer_envs.data.blockstack_skills.record_branches`: the multimodal
    data a skill policy needs); ``cache_dir`` "" is the default folder.
    """

    suite_name: ClassVar[str] = DATA_SUITE
    skills_per_episode: int = 12
    branches: int = 0
    cache_dir: str = ""

    def __post_init__(self) -> None:
        self.require_between(1, 10_000, "skills_per_episode")
        self.require_between(0, 100, "branches")

    @property
    def cache(self) -> str:
        """The cache folder in use."""
        return self.cache_dir or str(default_cache_dir("itps-blockstack"))


def run_data_trial(trial: Trial) -> TrialResult:
    """One episode seed: build (or find) its shard."""
    from steer_envs.data.blockstack_shards import ShardSettings, ensure_shard

    check_trial(trial, envs=(ENV_ID,))
    params = DataParams.from_json(trial.params)
    with single_threaded():
        settings = ShardSettings(trial.seed, params.skills_per_episode, params.branches)
        records, path, built = ensure_shard(params.cache, settings)
    metrics = {"skills": len(records), **skill_outcomes(records), "built": built}
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
            *SKILL_OUTCOME_METRICS,
            BUILT,
        ),
        run_trial=run_data_trial,
        envs=(ENV_ID,),
        params=DataParams(),
        default_seeds=50,
        quick={"skills_per_episode": 3},
        quick_seeds=1,
    )
)


# ------------------------------------------------------------------ itps-blockstack
SUITE_NAME = "itps-blockstack"

#: thesis Table 2.2 (Isaac Sim, VR sketches): method -> {metric: share}
TABLE_2_2: dict[str, dict[str, float]] = {
    "DP-PR": {"TA": 0.33, "CS": 1.00, "AS": 0.33, "AF": 0.00, "MS": 0.67, "MF": 0.00},
    "DP-GD-I50": {"TA": 0.83, "CS": 0.84, "AS": 0.67, "AF": 0.16, "MS": 0.17, "MF": 0.00},
    "DP-GD": {"TA": 0.86, "CS": 0.15, "AS": 0.15, "AF": 0.71, "MS": 0.00, "MF": 0.14},
}


@dataclass(frozen=True)
class SteerParams(SkillPolicyParams):
    """Parameters of ``itps-blockstack``.

    ``batch`` plans per steering call; ``max_interactions`` skills per trial
    (a tower needs 6); ``guide_ratio`` GD's beta (thesis table: 100);
    ``use_clipped_model_output`` GD's and SS's DDIM step re-derives the noise
    from the clipped clean plan (default on here: over 100 DDIM steps the
    guidance push clips the clean-plan estimate from the first step on, and
    ITPS's step then drives the plans away from the sketch; see
    :class:`~steer_envs.steering.GuidedDiffusion`);
    ``safety_weight`` the weight of the safety cost in the ``+safe`` methods;
    ``plot_seeds`` seeds that keep their plans for the figure; ``torch_threads``
    per trial process (0: torch's default); ``loader`` the policy's loader (called with ``"blockstack"``, or
    ``"blockstack-flow"`` for ``FLOW-*``):
    ``pretrained`` or, with ``--allow-import``, any ``module:function``; ``checkpoint`` a checkpoint file that
    replaces it. ``flow_checkpoint`` a flow policy file in place of the shipped one (``FLOW-*``), sampled
    with ``flow_steps`` Euler steps (0: the checkpoint's own, the DP's 100 DDIM steps).
    ``execution`` how the picked plans run on the arm: ``open_loop`` (the default) or ``closed_loop``
    (waypoints reached within a tolerance, grasps checked by contact and retried, releases settled;
    :func:`~steer_envs.control.blockstack.execute_plan`).
    """

    suite_name: ClassVar[str] = SUITE_NAME
    policy_name: ClassVar[str] = "blockstack"
    batch: int = 32
    max_interactions: int = 8
    guide_ratio: float = 100.0
    use_clipped_model_output: bool = True
    safety_weight: float = 5.0
    plot_seeds: int = 2
    torch_threads: int = 1
    #: the denoiser's inference mode (``DiffusionPolicy.accelerate``; auto: ONNX Runtime where installed)
    accelerate: str = "auto"
    loader: PolicyLoader = PRETRAINED_LOADER
    checkpoint: str = ""
    flow_checkpoint: str = ""
    flow_steps: int = 0
    execution: str = "open_loop"

    def __post_init__(self) -> None:
        self.require_steering()
        self.require_in("execution", EXECUTIONS)
        self.require("guide_ratio", self.guide_ratio >= 0, ">= 0")
        self.require("safety_weight", self.safety_weight > 0, "> 0")
        self.require_between(0, 1000, "flow_steps")

    def policy_key(self, method: str | None) -> str:
        """``"blockstack-flow"`` for the ``FLOW-*`` methods, ``"blockstack"`` for the others."""
        return FLOW_POLICY if str(method).startswith("FLOW-") else self.policy_name

    def policy_for(self, method: str | None) -> Any:
        """The flow policy for ``FLOW-*`` methods, the DP (:meth:`policy`) for the others."""
        if self.policy_key(method) != FLOW_POLICY:
            return self.policy()
        from steer_envs.baselines.pretrained import shared_policy

        return shared_policy(
            FLOW_POLICY, self.flow_checkpoint, self.accelerate, loader=self.loader, steps=self.flow_steps
        )


def run_steer_trial(trial: Trial) -> TrialResult:
    """One evaluation scene x one method: build the user's tower by sketching."""
    from steer_envs.steering.blockstack import tower_trial

    check_trial(trial, envs=(ENV_ID,))
    params = SteerParams.from_json(trial.params)
    with params.thread_limits():
        metrics, extra = tower_trial(
            trial.seed,
            params.policy_for(trial.method),
            str(trial.method),
            batch=params.batch,
            max_interactions=params.max_interactions,
            guide_ratio=params.guide_ratio,
            keep_plans=trial.seed < params.plot_seeds,
            use_clipped_model_output=params.use_clipped_model_output,
            safety_weight=params.safety_weight,
            execution=params.execution,
        )
    return TrialResult(metrics, extra)


def safety_findings(table: Any) -> list[Finding]:
    """GD and SS with the safety cost keep more plans within the task's constraints (CS) than without."""

    def raises_cs(method: str) -> Finding:
        safe = f"{method}+safe"
        return judge(
            f"{safe} succeeds more often (CS) than {method}",
            table.means("CS", [method, safe]),
            lambda v: v[safe] > v[method],
            lambda v: f"CS {v[safe]:.2f} vs {v[method]:.2f}",
        )

    return [raises_cs(method) for method in ("DP-GD", "DP-GD-B25", "DP-SS")]


def steer_findings(table: Any) -> list[Finding]:
    """Table 2.2's trade-off, checked on a run's summary table."""
    need = ["DP-PR", "DP-GD", "DP-GD-I50"]
    ta, cs, aligned_success = (table.means(m, need) for m in ("TA", "CS", "AS"))
    ss = {m: table.means(m, ["DP-SS"]) for m in ("TA", "CS")}

    def shown(*methods: str) -> Callable[[dict[str, float]], str]:
        return lambda values: listing(values, ".2f", strip="DP-", names=methods)

    # relative, not absolute for CS: the thesis's GD keeps 0.15 of PR's 1.00; ours must show the drop from a lower PR
    return [
        judge(
            "guided sampling (GD, GD off after step 50) raises TA above PR",
            ta,
            lambda v: v["DP-GD"] > v["DP-PR"] and v["DP-GD-I50"] > v["DP-PR"],
            shown("DP-PR", "DP-GD", "DP-GD-I50"),
        ),
        judge(
            "GD at full strength drops CS far below PR (to at most half of PR's)",
            cs,
            lambda v: v["DP-GD"] <= 0.5 * v["DP-PR"],
            shown("DP-PR", "DP-GD"),
        ),
        judge(
            "GD with guidance off after step 50 keeps CS high (within 0.2 of PR's)",
            cs,
            lambda v: v["DP-GD-I50"] >= v["DP-PR"] - 0.2,
            shown("DP-PR", "DP-GD-I50"),
        ),
        judge(
            "GD off after step 50 has the highest aligned success (AS above PR's and full GD's)",
            aligned_success,
            lambda v: v["DP-GD-I50"] > max(v["DP-PR"], v["DP-GD"]),
            shown("DP-GD-I50", "DP-PR", "DP-GD"),
        ),
        judge(
            "GD at the thesis text's beta 25 raises TA above PR",
            table.means("TA", ["DP-PR", "DP-GD-B25"]),
            lambda v: v["DP-GD-B25"] > v["DP-PR"],
            shown("DP-PR", "DP-GD-B25"),
        ),
        judge(
            "SS keeps CS high (within 0.2 of PR's) while raising TA above PR",
            {"CS": cs, "TA": ta, "SS CS": ss["CS"], "SS TA": ss["TA"]},
            lambda v: v["SS CS"]["DP-SS"] >= v["CS"]["DP-PR"] - 0.2 and v["SS TA"]["DP-SS"] > v["TA"]["DP-PR"],
            lambda v: (
                f"TA SS {v['SS TA']['DP-SS']:.2f} vs PR {v['TA']['DP-PR']:.2f}; "
                f"CS SS {v['SS CS']['DP-SS']:.2f} vs PR {v['CS']['DP-PR']:.2f}"
            ),
        ),
    ]


def flow_findings(table: Any) -> list[Finding]:
    """Table 2.2's findings on the flow policy (``FLOW-*``), and its steering latency against DP's."""
    on_flow = on_other_policy(steer_findings, table, "FLOW-", "flow policy")
    latency = judge(
        "the flow policy steers (SS) no slower than DP",
        table.means("latency_ms", ["DP-SS", "FLOW-SS"]),
        lambda v: v["FLOW-SS"] <= 1.05 * v["DP-SS"],
        lambda v: f"FLOW-SS / DP-SS latency {v['FLOW-SS'] / v['DP-SS']:.2f}",
    )
    return [*on_flow, latency]


def table_findings(table: Any) -> list[Finding]:
    """Table 2.2's findings, then the safety cost's, then the flow policy's."""
    return [*steer_findings(table), *safety_findings(table), *flow_findings(table)]


register_suite(
    Suite(
        name=SUITE_NAME,
        description=(
            "ITPS block stacking (thesis Table 2.2): a simulated user builds a chosen 4-block tower by 3D "
            "sketches steering the skill Diffusion Policy (batch 32); TA, CS and the AS/AF/MS/MF quadrants."
        ),
        metrics=(
            Metric(
                "TA",
                f"aligned, the thesis's definition: the picked plan heads for the intended cube or tower ({SHARE})",
                fmt=".2f",
            ),
            Metric("CS", f"success: the executed skill happened, nothing dropped or toppled ({SHARE})", fmt=".2f"),
            *QUADRANT_METRICS,
            Metric(
                "TA_skill",
                f"skill-aligned: the picked plan is also the intended skill in shape (grasp or release) ({SHARE})",
                fmt=".2f",
            ),
            Metric("AS_skill", "skill-aligned success", fmt=".2f"),
            Metric("valid", f"the picked plan is some skill in shape, the intended one or not ({SHARE})", fmt=".2f"),
            Metric("executed_ok", "share of the valid plans executed as that skill, nothing dropped", fmt=".2f"),
            Metric("batch_aligned", "share of the batch doing the intended skill", fmt=".2f"),
            Metric("tower_built", "the user's tower stands at the end", fmt=".2f"),
            Metric("interactions", "steering calls of the trial", fmt=".1f"),
            Metric("latency_ms", "ms per steering call (batch 32)", kind="timing", higher_is_better=False, fmt=".0f"),
        ),
        run_trial=run_steer_trial,
        envs=(ENV_ID,),
        methods=METHODS,
        params=SteerParams(),
        default_seeds=20,
        generate=policy_planner("the BlockStack policy", "train it with scripts/train_blockstack_checkpoint.sh"),
        references=table_references(TABLE_2_2, env=ENV_ID, source="thesis Table 2.2"),
        quick={"batch": 8, "max_interactions": 1, "plot_seeds": 1},
        quick_seeds=1,
        plot="steer_envs.bench.suites.itps_blockstack.plots:plot_blockstack",
        findings=table_findings,
    )
)
