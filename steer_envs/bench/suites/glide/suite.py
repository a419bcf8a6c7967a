"""GLiDE suites on PolygonNav (thesis ch. 4): mode grounding with ablations, and thesis Table 4.1.

* ``glide-polygon-grounding``: one trial = one env (3, 4, 5 modes) x one
  variant (``full`` loss; ablations ``no_counterfactuals``,
  ``wrong_feasibility`` (a plan one mode short), ``no_prediction_loss``
  (``L_succ`` and ``L_fail`` off) and the ``kmeans`` trajectory-segmentation
  baseline) x one layout (the seed; layouts 0-4 by default), through
  :func:`~steer_envs.baselines.glide.polygon.learn_grounding` and
  :func:`~steer_envs.baselines.glide.polygon_eval.grounding_scores`. Metrics: the
  overlap of the learned modes with the ground truth on a 200 x 200 grid (the
  report's mean over the seeds is the mean over layouts; target for the full
  loss: >= 0.95), the mean per-mode IoU (stricter: free space fills most of the
  grid, as ``free_only_overlap`` -- the overlap of "everything is free space"
  -- shows), the classifier's training time (goal < 2 min) and the data set's
  build time. The first ``plot_seeds`` layouts keep their grid labels and
  demos for the learned-boundaries figure (thesis Fig. 4.4: one row per env,
  ground truth with demos, then each variant).
* ``glide-polygon``: thesis Table 4.1. One trial = one env x one method
  (``bc``, ``glide_bc``, ``glide_planning``) x one training seed on layout
  ``layout_seed``: the trained policy is evaluated ``n_rollouts`` times
  (episodes of ``max_steps``, default 1000 as in the public evaluation loop,
  starting in free space or, with ``start=first_mode``, inside the first polygon)
  without and with the evaluation perturbations
  (:func:`~steer_envs.baselines.glide.polygon.make_polygon_policy`,
  :func:`~steer_envs.baselines.glide.polygon_eval.evaluate_polygon_policy`), and the
  report prints the thesis's success rates beside ours. The thesis averages BC
  over 10 seeds: ``bc_seeds`` (default 10) and ``glide_seeds`` (default 3: one
  data set + classifier per seed, since one seed says as much about the draw
  of replays as about the method) set how many training seeds each method
  gets unless ``--seeds`` is given. ``bc_demo_starts`` is where BC's demos
  start (:mod:`steer_envs.data.demo_starts`): ``uniform`` in free space (the
  default, the env's reset) or ``spread`` evenly around the workspace edge,
  as the public code's hand-drawn demos start; BC's gap to the thesis's 3-mode
  0.967 is mostly the uniform starts (layout 0, 10 seeds x 300 rollouts:
  0.825 uniform, 0.937 spread). The GLiDE methods keep the setup's demos.

Both suites take the data/training sizes as parameters (:class:`GlideSetupParams`,
shared by :class:`GroundingParams` and :class:`PolicyParams`; a tiny
configuration runs in seconds; ``demo_goal_steps`` is how far the demos go on
into the goal polygon, 0 for demos that end on entering it) and a
``cache_dir`` where data sets and classifiers are kept (safetensors / npz), so
the grounding suite, the policy suite and a resumed run train each classifier
once. Trials run with one BLAS and one torch thread.

>>> PolicyParams(n_rollouts=50).to_json()["n_rollouts"]
50
>>> GroundingParams(n_heads=0)
Traceback (most recent call last):
ValueError: glide-polygon-grounding: parameter 'n_heads' must be >= 1, got 0
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from steer_envs.bench.metrics import EVAL_SECONDS, evaluation_metrics, success_references, train_seconds
from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, TrialPlan, TrialResult, register_suite
from steer_envs.bench.trials import check_trial
from steer_envs.utils.fields import same_named
from steer_envs.utils.threads import single_threaded

if TYPE_CHECKING:
    from steer_envs.bench.suite import Trial, TrialRequest

GROUNDING_SUITE = "glide-polygon-grounding"
POLICY_SUITE = "glide-polygon"
ENV_IDS: tuple[str, ...] = tuple(f"steer_envs/PolygonNav-{k}Mode-v0" for k in (3, 4, 5))
VARIANTS: tuple[str, ...] = ("full", "no_counterfactuals", "wrong_feasibility", "no_prediction_loss", "kmeans")
METHODS: tuple[str, ...] = ("bc", "glide_bc", "glide_planning")
#: where evaluation episodes start: uniform in free space (the env's reset, the thesis's "starting in
#: the free space") or uniform inside the first polygon (the public polygon env's default reset, which
#: counts the agent as having just entered it). This and the names above are the library's
#: (``baselines.glide``: ``EVAL_STARTS``, ``POLYGON_ENV_IDS``, ``POLYGON_VARIANTS``, ``POLYGON_METHODS``),
#: repeated here, like the tables below, so declaring the suite imports no torch
EVAL_STARTS: tuple[str, ...] = ("free", "first_mode")
#: how GLiDE+Planning crosses free space; the same as ``planners.FREE_SPACE_PLANNERS``
FREE_SPACE_PLANNERS: tuple[str, ...] = ("costmap", "rrt")
#: thesis Table 4.1: method -> modes -> (success, success +perturb).
THESIS_TABLE_4_1: Mapping[str, Mapping[int, tuple[float, float]]] = {
    "bc": {3: (0.967, 0.908), 4: (0.814, 0.614), 5: (0.810, 0.596)},
    "glide_bc": {3: (0.963, 0.887), 4: (0.892, 0.753), 5: (0.893, 0.753)},
    "glide_planning": {3: (0.996, 0.996), 4: (0.987, 0.966), 5: (0.991, 0.974)},
}
#: where BC's demos start (``steer_envs.data.demo_starts.DEMO_STARTS``, repeated so declaring the suite
#: imports no env module)
DEMO_STARTS: tuple[str, ...] = ("uniform", "spread")
#: episode length of the Table 4.1 evaluation. The public evaluation loop (GLiDE's polygon code) runs
#: 1000 policy iterations, a free-space iteration executing a whole RRT path, and its env never enforces
#: its nominal 500-step limit; 500 steps leave three teleports (>= 100 steps apart) too little time on
#: layouts with a long chain of polygons. ``--param max_steps=500`` runs the env's own limit.
MAX_STEPS = 1000
#: target: full-loss overlap >= 0.95 (mean over 5 layouts); the thesis shows it only in figures.
OVERLAP_TARGET = 0.95
#: goal: classifier training on a PolygonNav data set takes < 2 minutes.
TRAIN_SECONDS_GOAL = 120.0


@dataclass(frozen=True)
class GlideSetupParams(SuiteParams):
    """Parameters shared by both GLiDE suites: what the GLiDE setup (data set, classifier) is built from.

    ``cache_dir`` (``None`` or ``""``: no cache) keeps data sets and classifiers between trials and runs.
    """

    n_demos: int = 7
    demo_goal_steps: int = 30
    n_success: int = 1000
    n_failure: int = 1000
    epochs: int = 2000
    n_heads: int = 5
    cache_dir: str | None = None

    def __post_init__(self) -> None:
        self.require_at_least(1, "n_demos", "n_success", "n_failure", "epochs", "n_heads")
        self.require_at_least(0, "demo_goal_steps")

    @property
    def cache(self) -> str | None:
        """:attr:`cache_dir`, with ``""`` read as no cache."""
        return self.cache_dir or None

    def setup(self, **extra: Any) -> Any:
        """The :class:`~steer_envs.baselines.glide.polygon.GlideSetup` these parameters describe."""
        from steer_envs.baselines.glide.polygon import GlideSetup

        base = GlideSetup()
        train = replace(base.train, epochs=self.epochs, n_heads=self.n_heads)
        return replace(base, **same_named(GlideSetup, self, train=train, **extra))


@dataclass(frozen=True)
class GroundingParams(GlideSetupParams):
    """Parameters of ``glide-polygon-grounding``: the setup, the overlap grid's side, the classifier seed."""

    suite_name: ClassVar[str] = GROUNDING_SUITE
    grid_resolution: int = 200
    train_seed: int = 0
    plot_seeds: int = 1

    def __post_init__(self) -> None:
        super().__post_init__()
        self.require_at_least(2, "grid_resolution")
        self.require_at_least(0, "train_seed", "plot_seeds")


@dataclass(frozen=True)
class PolicyParams(GlideSetupParams):
    """Parameters of ``glide-polygon`` (thesis Table 4.1): the setup plus the evaluation.

    ``n_rollouts`` episodes of ``max_steps`` on layout ``layout_seed``,
    starting as ``start`` says (:data:`EVAL_STARTS`); ``bc_seeds`` /
    ``glide_seeds`` training seeds per method; ``bc_steps`` of BC training;
    ``bc_demo_starts`` where BC's demos start (:data:`DEMO_STARTS`; the module docstring);
    ``free_space_planner`` of GLiDE+Planning (:data:`FREE_SPACE_PLANNERS`).
    """

    suite_name: ClassVar[str] = POLICY_SUITE
    n_rollouts: int = 1000
    layout_seed: int = 0
    bc_seeds: int = 10
    glide_seeds: int = 3
    bc_steps: int = 1500
    bc_demo_starts: str = "uniform"
    free_space_planner: str = "costmap"
    max_steps: int = MAX_STEPS
    start: str = "free"

    def __post_init__(self) -> None:
        super().__post_init__()
        self.require_at_least(1, "n_rollouts", "bc_seeds", "glide_seeds", "bc_steps", "max_steps")
        self.require_at_least(0, "layout_seed")
        self.require_in("free_space_planner", FREE_SPACE_PLANNERS)
        self.require_in("bc_demo_starts", DEMO_STARTS)
        self.require_in("start", EVAL_STARTS)

    def planner(self) -> Any:
        """GLiDE+Planning's settings: the setup's defaults, with :attr:`free_space_planner`."""
        from steer_envs.baselines.glide.polygon import GlideSetup

        return replace(GlideSetup().planner, free_space_planner=self.free_space_planner)

    def bc(self) -> Any:
        """The BC training settings: the setup's defaults, with :attr:`bc_steps`."""
        from steer_envs.baselines.glide.polygon import GlideSetup

        return replace(GlideSetup().bc, steps=self.bc_steps)


def _num_modes(env: str | None) -> int:
    if env not in ENV_IDS:
        raise ValueError(f"glide suites: unknown env {env!r}; expected one of {ENV_IDS}")
    return int(str(env).split("-")[1][0])


# ------------------------------------------------------------ glide-polygon-grounding
def run_grounding_trial(trial: Trial) -> TrialResult:
    """One env x variant x layout (the seed): overlap and IoU of the learned modes."""
    from steer_envs.baselines.glide import grounding_scores, learn_grounding
    from steer_envs.bench.suites.glide.plots import encode_labels

    check_trial(trial, envs=ENV_IDS, methods=VARIANTS, method_word="variant")
    params = GroundingParams.from_json(trial.params)
    resolution = params.grid_resolution
    setup = params.setup(grid_resolution=resolution)
    env, variant = str(trial.env), str(trial.method)
    with single_threaded():
        grounding = learn_grounding(env, trial.seed, variant, params.train_seed, setup=setup, cache_dir=params.cache)
        scores, labels = grounding_scores(env, trial.seed, grounding.predictor, setup.grid_resolution)
    res = {**scores, **grounding.info}
    metrics = {
        "overlap": res["overlap"],
        "mean_iou": res["mean_iou"],
        "free_only_overlap": res["all_free_overlap"],
        "train_seconds": res["train_seconds"],
        "data_seconds": None
        if res.get("cached") or res.get("data_cached") or "raw_success_rate" not in res
        else res["data_seconds"],
    }
    extra: dict[str, Any] = {
        "iou": res["iou"],
        "cached": bool(res.get("cached", False)),
        **{
            k: res[k]
            for k in ("raw_success_rate", "head_losses", "best_head", "n_trajectories", "load_avg")
            if k in res
        },
    }
    if trial.seed < params.plot_seeds:
        extra["figure"] = {
            "resolution": resolution,
            "labels": encode_labels(labels),
            "demos": [[[round(float(v), 3) for v in p] for p in d.states[::2]] for d in grounding.demos],
        }
    return TrialResult(metrics, extra)


# ------------------------------------------------------------------ findings
#: "measurably worse": a lower mean overlap and a mean IoU lower by at least this. Overlap alone cannot
#: show a missed goal polygon: it covers a tiny share of the grid.
ABLATION_IOU_MARGIN = 0.05


def _modes_label(env: str) -> str:
    return f"{_num_modes(env)} modes"


def grounding_findings(table: Any) -> list[Finding]:
    """Thesis Fig. 4.4: the full loss finds the modes on every env and every ablation does worse."""
    claims = (
        "the full loss labels >= 95 % of the grid with the true mode on every env",
        f"every ablation is worse than the full loss on every env (lower overlap, mean IoU >= {ABLATION_IOU_MARGIN} "
        "lower)",
    )
    overlap = {env: table.means("overlap", VARIANTS, env) for env in ENV_IDS}
    iou = {env: table.means("mean_iou", VARIANTS, env) for env in ENV_IDS}
    if any(v is None for v in (*overlap.values(), *iou.values())):
        return [Finding(c, None) for c in claims]
    full = {env: overlap[env]["full"] for env in ENV_IDS}  # type: ignore[index]
    detail = ", ".join(f"{_modes_label(e)} {x:.3f}" for e, x in full.items())
    findings = [Finding(claims[0], min(full.values()) >= OVERLAP_TARGET, detail)]
    gaps = [
        (iou[env]["full"] - iou[env][v], overlap[env]["full"] - overlap[env][v], env, v)  # type: ignore[index]
        for env in ENV_IDS
        for v in VARIANTS
        if v != "full"
    ]
    holds = all(d_iou >= ABLATION_IOU_MARGIN and d_overlap > 0 for d_iou, d_overlap, _, _ in gaps)
    *_, env, variant = min(gaps, key=lambda g: (g[0] >= ABLATION_IOU_MARGIN and g[1] > 0, g[0]))  # worst first
    detail = (
        f"closest: {variant} on {_modes_label(env)}, overlap {overlap[env][variant]:.3f} vs {full[env]:.3f}, "  # type: ignore[index]
        f"IoU {iou[env][variant]:.2f} vs {iou[env]['full']:.2f}"  # type: ignore[index]
    )
    findings.append(Finding(claims[1], holds, detail))
    return findings


def policy_findings(table: Any) -> list[Finding]:
    """Thesis Table 4.1: GLiDE+Planning >= 0.98 with and without perturbations, above BC perturbed."""
    claims = (
        "GLiDE+Planning succeeds in >= 98 % of rollouts with and without perturbations on every env",
        "GLiDE+Planning beats BC under perturbations on every env",
    )
    pair = ("bc", "glide_planning")
    plain = {env: table.means("success", pair, env) for env in ENV_IDS}
    pert = {env: table.means("success_perturbed", pair, env) for env in ENV_IDS}
    if any(v is None for v in (*plain.values(), *pert.values())):
        return [Finding(c, None) for c in claims]
    gp = {e: (plain[e]["glide_planning"], pert[e]["glide_planning"]) for e in ENV_IDS}  # type: ignore[index]
    bc = {e: pert[e]["bc"] for e in ENV_IDS}  # type: ignore[index]
    return [
        Finding(
            claims[0],
            all(min(v) >= 0.98 for v in gp.values()),
            ", ".join(f"{_modes_label(e)} {a:.3f}/{b:.3f}" for e, (a, b) in gp.items())
            + "; the thesis's own: "
            + ", ".join(
                "{} {:.3f}/{:.3f}".format(_modes_label(e), *THESIS_TABLE_4_1["glide_planning"][_num_modes(e)])
                for e in ENV_IDS
            ),
        ),
        Finding(
            claims[1],
            all(gp[e][1] > bc[e] for e in ENV_IDS),
            ", ".join(f"{_modes_label(e)} {gp[e][1]:.3f} vs {bc[e]:.3f}" for e in ENV_IDS),
        ),
    ]


def plot_grounding(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """Thesis Fig. 4.4: per plotted layout, one row per env (ground truth + demos, then each variant)."""
    import gymnasium as gym
    import numpy as np

    import steer_envs  # noqa: F401  (registers the envs)
    from steer_envs.bench.suites.glide.plots import ModeMapRow, decode_labels, plot_mode_maps

    with_fig = [r for r in records if "figure" in r.get("extra", {}) and r["config"]["suite"] == suite.name]
    written: list[str] = []
    by_layout: dict[int, list[Mapping[str, Any]]] = {}
    for r in with_fig:
        by_layout.setdefault(int(r["seed"]), []).append(r)
    for layout in sorted(by_layout):
        recs = by_layout[layout]
        resolutions = {int(r["extra"]["figure"]["resolution"]) for r in recs}
        for resolution in sorted(resolutions):
            rows = []
            for env in ENV_IDS:
                cell = {
                    r["config"]["method"]: r
                    for r in recs
                    if r["config"]["env"] == env and int(r["extra"]["figure"]["resolution"]) == resolution
                }
                if not cell:
                    continue
                panels = {
                    v: decode_labels(cell[v]["extra"]["figure"]["labels"], resolution) for v in VARIANTS if v in cell
                }
                first = next(iter(cell.values()))
                demos = [np.asarray(d, dtype=np.float64) for d in first["extra"]["figure"]["demos"]]
                e = gym.make(env, layout_seed=layout)
                model = e.unwrapped.model  # type: ignore[attr-defined]
                e.close()
                name = env.split("/")[-1].removesuffix("-v0")
                rows.append(ModeMapRow(model, panels, f"{name}, layout {layout}: truth + demos", demos))
            if not rows:
                continue
            suffix = "" if len(resolutions) == 1 else f"_r{resolution}"
            path = Path(out_dir) / f"{suite.name}_layout{layout}{suffix}.png"
            title = "Learned mode boundaries (thesis Fig. 4.4): GLiDE full loss and ablations"
            written.append(str(plot_mode_maps(rows, path, resolution=resolution, title=title)))
    return written


GLIDE_POLYGON_GROUNDING = register_suite(
    Suite(
        name=GROUNDING_SUITE,
        description=(
            "GLiDE mode grounding on PolygonNav 3/4/5 modes (thesis §4.3.1, Fig. 4.4): overlap of the learned modes "
            "with the ground truth on a 200 x 200 grid, full loss vs. ablations and k-means++; seeds are layouts."
        ),
        metrics=(
            Metric("overlap", "fraction of the 200 x 200 grid labelled with the true mode", fmt=".3f"),
            Metric("mean_iou", "mean over modes of the IoU of learned and true mode regions", fmt=".3f"),
            Metric("free_only_overlap", "overlap of labelling everything free space (trivial floor)", fmt=".3f"),
            train_seconds("classifier training wall time (s; k-means: its fit)", goal=TRAIN_SECONDS_GOAL),
            Metric(
                "data_seconds",
                "perturbation data set build time (s; none when cached or not used)",
                kind="timing",
                higher_is_better=False,
                fmt=".1f",
            ),
        ),
        run_trial=run_grounding_trial,
        envs=ENV_IDS,
        methods=VARIANTS,
        params=GroundingParams(),
        default_seeds=5,
        references=tuple(
            Reference("overlap", OVERLAP_TARGET, env=env, method="full", source="target (full loss)") for env in ENV_IDS
        ),
        plot=plot_grounding,
        findings=grounding_findings,
    )
)


# ---------------------------------------------------------------------- glide-polygon
def _plan_policy(suite: Suite, request: TrialRequest) -> TrialPlan:
    params: PolicyParams = suite.resolve_params(request.params, request.trials, base=request.base)
    params.setup(planner=params.planner())  # the protocol's own checks, before any trial runs
    trials = []
    for env in request.envs:
        for method in request.methods:
            if request.seeds is not None:
                seeds: Sequence[int] = request.seeds
            else:
                seeds = range(params.bc_seeds if method == "bc" else params.glide_seeds)
            trials += [suite.trial(env, method, int(s), params) for s in seeds]
    return TrialPlan(tuple(trials))


def _evaluate_column(policy: Any, trial: Trial, params: PolicyParams, perturbed: bool) -> dict[str, Any]:
    """One column of a Table 4.1 cell; for GLiDE+Planning also its planner's calls over these rollouts."""
    from steer_envs.baselines.glide import GlidePlanningPolicy, evaluate_polygon_policy

    res = evaluate_polygon_policy(
        policy,
        str(trial.env),
        params.layout_seed,
        n_rollouts=params.n_rollouts,
        perturbed=perturbed,
        seed=trial.seed,
        max_steps=params.max_steps,
        start=params.start,
    )
    if isinstance(policy, GlidePlanningPolicy):
        res["planner_calls"] = dict(policy.stats)
        policy.stats = dict.fromkeys(policy.stats, 0)
    return res


def run_policy_trial(trial: Trial) -> TrialResult:
    """One env x method x training seed: success without and with perturbations (thesis Table 4.1).

    One trained policy, ``n_rollouts`` episodes each without and with the evaluation perturbations
    (the same start states in both). ``train_seconds``: the classifier's training for the GLiDE
    methods (a cached classifier reports its original training time), the MLP's for BC.
    """
    from steer_envs.baselines.glide import make_polygon_policy

    check_trial(trial, envs=ENV_IDS, methods=METHODS)
    params = PolicyParams.from_json(trial.params)
    setup = params.setup(bc=params.bc(), planner=params.planner())
    with single_threaded():
        policy, info = make_polygon_policy(
            str(trial.method), str(trial.env), params.layout_seed, trial.seed, setup=setup, cache_dir=params.cache
        )
        began = time.perf_counter()
        clean = _evaluate_column(policy, trial, params, False)
        perturbed = _evaluate_column(policy, trial, params, True)
        eval_seconds = time.perf_counter() - began
    metrics = {
        **evaluation_metrics(clean, perturbed),
        "timeout_perturbed": perturbed["timeout_rate"],
        "train_seconds": float(info.get("train_seconds", 0.0)),
        "eval_seconds": eval_seconds,
    }
    extra = {"unperturbed": clean, "perturbed": perturbed, "classifier_cached": bool(info.get("cached", False))}
    return TrialResult(metrics, extra)


GLIDE_POLYGON = register_suite(
    Suite(
        name=POLICY_SUITE,
        description=(
            "GLiDE on PolygonNav (thesis Table 4.1): success of BC, GLiDE+BC and GLiDE+Planning over n_rollouts "
            "episodes without / with teleport perturbations; seeds are training seeds (BC: bc_seeds)."
        ),
        metrics=(
            Metric("success", "success rate, no perturbations", fmt=".3f"),
            Metric("success_perturbed", "success rate with the evaluation perturbations (+perturb)", fmt=".3f"),
            Metric("violation", "episodes with an invalid transition, no perturbations", higher_is_better=False),
            Metric("violation_perturbed", "episodes with an invalid transition, +perturb", higher_is_better=False),
            Metric(
                "timeout_perturbed",
                "episodes out of steps (neither success nor an invalid transition), +perturb",
                higher_is_better=False,
            ),
            train_seconds(
                "training wall time (s): the classifier for GLiDE (as first trained), the MLP for BC",
                goal=TRAIN_SECONDS_GOAL,
            ),
            EVAL_SECONDS,
        ),
        run_trial=run_policy_trial,
        envs=ENV_IDS,
        methods=METHODS,
        params=PolicyParams(),
        trials_param="n_rollouts",
        default_seeds=1,
        generate=_plan_policy,
        references=success_references(THESIS_TABLE_4_1, "steer_envs/PolygonNav-{}Mode-v0".format, "thesis Table 4.1"),
        findings=policy_findings,
    )
)
