"""GLiDE suites on PolygonNav (thesis ch. 4): mode grounding with ablations, and thesis Table 4.1.

* ``glide-polygon-grounding``: one trial = one env (3, 4, 5 modes) x one
  variant (``full`` loss; ablations ``no_counterfactuals``,
  ``wrong_feasibility`` (a plan one mode short), ``no_prediction_loss``
  (``L_succ`` and ``L_fail`` off) and the ``kmeans`` trajectory-segmentation
  baseline) x one layout (the seed; issue 6: layouts 0-4), through
  :func:`~steer_envs.bench.suites.glide.protocol.grounding_trial`. Metrics: the
  overlap of the learned modes with the ground truth on a 200 x 200 grid (the
  report's mean over the seeds is the mean over layouts; issue 6 target for
  the full loss: >= 0.95), the mean per-mode IoU (stricter: free space
  fills ~90 % of the grid, which ``free_only_overlap`` -- the overlap of
  "everything is free space" -- shows), the classifier's training time
  (issue target < 2 min on this CPU) and the data set's build time. The first
  ``plot_seeds`` layouts keep their grid labels and demos for the
  learned-boundaries figure (thesis Fig. 4.4: one row per env, ground truth
  with demos, then each variant).
* ``glide-polygon``: thesis Table 4.1. One trial = one env x one method
  (``bc``, ``glide_bc``, ``glide_planning``) x one training seed on layout
  ``layout_seed``: the trained policy is evaluated ``n_rollouts`` times
  (episodes of ``max_steps``, default 1000 as in the public evaluation loop,
  starting in free space or, with ``start=first_mode``, inside the first polygon)
  without and with the evaluation perturbations
  (:func:`~steer_envs.bench.suites.glide.protocol.policy_table_trial`), and the
  report prints the thesis's success rates beside ours. The thesis averages BC
  over 10 seeds: ``bc_seeds`` (default 10) and ``glide_seeds`` (default 3: one
  data set + classifier per seed; a single seed says as much about the draw
  of replays as about the method -- with 500 + 500 replays one 3-mode
  classifier in three missed a polygon tip, costing GLiDE+Planning 8 points)
  set how many training seeds each method gets unless ``--seeds`` is given.

Both suites take the data/training sizes as parameters (a tiny configuration
runs in seconds; ``demo_goal_steps`` is how far the demos go on into the goal
polygon, 0 for demos that end on entering it) and a ``cache_dir`` where data
sets and classifiers are kept (safetensors / npz), so the grounding suite, the
policy suite and a resumed run train each classifier once. Trials run with one BLAS and one torch
thread.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

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
from steer_envs.bench.suites.tli.suite import single_threaded

GROUNDING_SUITE = "glide-polygon-grounding"
POLICY_SUITE = "glide-polygon"
ENV_IDS: tuple[str, ...] = tuple(f"steer_envs/PolygonNav-{k}Mode-v0" for k in (3, 4, 5))
VARIANTS: tuple[str, ...] = ("full", "no_counterfactuals", "wrong_feasibility", "no_prediction_loss", "kmeans")
METHODS: tuple[str, ...] = ("bc", "glide_bc", "glide_planning")
#: where evaluation episodes start: uniform in free space (the env's reset, the thesis's "starting in
#: the free space") or uniform inside the first polygon (the public polygon env's default reset, which
#: counts the agent as having just entered it); glide_protocol.EVAL_STARTS
EVAL_STARTS: tuple[str, ...] = ("free", "first_mode")
#: thesis Table 4.1: method -> modes -> (success, success +perturb); the same numbers as
#: glide_protocol.THESIS_TABLE_4_1 (kept here so declaring the suite imports no torch).
THESIS_TABLE_4_1: Mapping[str, Mapping[int, tuple[float, float]]] = {
    "bc": {3: (0.967, 0.908), 4: (0.814, 0.614), 5: (0.810, 0.596)},
    "glide_bc": {3: (0.963, 0.887), 4: (0.892, 0.753), 5: (0.893, 0.753)},
    "glide_planning": {3: (0.996, 0.996), 4: (0.987, 0.966), 5: (0.991, 0.974)},
}
#: episode length of the Table 4.1 evaluation. The public evaluation loop (GLiDE's polygon code) runs
#: 1000 policy iterations, a free-space iteration executing a whole RRT path, and its env never enforces
#: its nominal 500-step limit; with 500 steps, three teleports (>= 100 steps apart) leave too little time
#: on layouts where the chain of polygons is long (layout 0, 4 modes: 7.6 % of perturbed episodes time
#: out). ``--param max_steps=500`` runs the env's own limit.
MAX_STEPS = 1000
#: issue 6 'done when': full-loss overlap >= 0.95 (mean over 5 layouts); the thesis shows it only in figures.
OVERLAP_TARGET = 0.95
#: issue 6: classifier training on a PolygonNav data set takes < 2 minutes on this CPU.
TRAIN_SECONDS_GOAL = 120.0

#: parameters shared by both suites: what the GLiDE setup is built from
_SETUP_PARAMS: dict[str, Any] = {
    "n_demos": 7,
    "demo_goal_steps": 30,
    "n_success": 1000,
    "n_failure": 1000,
    "epochs": 2000,
    "n_heads": 5,
    "cache_dir": None,
}


def _num_modes(env: str | None) -> int:
    if env not in ENV_IDS:
        raise ValueError(f"glide suites: unknown env {env!r}; expected one of {ENV_IDS}")
    return int(str(env).split("-")[1][0])


def _check_int_param(suite: str, params: Mapping[str, Any], name: str, low: int) -> int:
    value = params[name]
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise ValueError(f"{suite}: parameter {name!r} must be an int >= {low}, got {value!r}")
    return value


def setup_from_params(suite: str, params: Mapping[str, Any], **extra: Any) -> Any:
    """The :class:`~steer_envs.bench.suites.glide.protocol.GlideSetup` a trial's params describe."""
    from steer_envs.bench.suites.glide.protocol import GlideSetup

    for name, low in (("n_demos", 1), ("n_success", 1), ("n_failure", 1), ("epochs", 1), ("n_heads", 1)):
        _check_int_param(suite, params, name, low)
    goal_steps = _check_int_param(suite, params, "demo_goal_steps", 0) if "demo_goal_steps" in params else None
    base = GlideSetup()
    train = replace(base.train, epochs=int(params["epochs"]), n_heads=int(params["n_heads"]))
    return replace(
        base,
        n_demos=int(params["n_demos"]),
        demo_goal_steps=base.demo_goal_steps if goal_steps is None else goal_steps,
        n_success=int(params["n_success"]),
        n_failure=int(params["n_failure"]),
        train=train,
        **extra,
    )


def _cache_dir(params: Mapping[str, Any]) -> str | None:
    value = params.get("cache_dir")
    if value is None or value == "":
        return None
    if not isinstance(value, str):
        raise ValueError(f"glide suites: cache_dir must be a directory path or null, got {value!r}")
    return value


# ------------------------------------------------------------ glide-polygon-grounding
def run_grounding_trial(trial: Trial) -> TrialResult:
    """One env x variant x layout (the seed): overlap and IoU of the learned modes."""
    from steer_envs.bench.suites.glide.plots import encode_labels
    from steer_envs.bench.suites.glide.protocol import grounding_trial

    _num_modes(trial.env)
    if trial.method not in VARIANTS:
        raise ValueError(f"{GROUNDING_SUITE}: unknown variant {trial.method!r}; expected one of {VARIANTS}")
    params = trial.params
    resolution = _check_int_param(GROUNDING_SUITE, params, "grid_resolution", 2)
    train_seed = _check_int_param(GROUNDING_SUITE, params, "train_seed", 0)
    plot_seeds = _check_int_param(GROUNDING_SUITE, params, "plot_seeds", 0)
    setup = setup_from_params(GROUNDING_SUITE, params, grid_resolution=resolution)
    keep = trial.seed < plot_seeds
    with single_threaded():
        res = grounding_trial(
            str(trial.env),
            trial.seed,
            str(trial.method),
            train_seed,
            setup=setup,
            cache_dir=_cache_dir(params),
            keep_labels=keep,
        )
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
    if keep:
        extra["figure"] = {
            "resolution": resolution,
            "labels": encode_labels(res["labels"]),
            "demos": [[[round(float(v), 3) for v in p] for p in d[::2]] for d in res["demo_states"]],
        }
    return TrialResult(metrics, extra)


# ------------------------------------------------------------------ findings
#: "measurably worse" (issue 6): a lower mean overlap and a mean IoU lower by at least this. Overlap alone
#: cannot show a missed goal polygon: it covers under 1 % of the grid on the 5-mode layouts.
ABLATION_IOU_MARGIN = 0.05


def _modes_label(env: str) -> str:
    return f"{_num_modes(env)} modes"


def grounding_findings(table: Any) -> list[Finding]:
    """Issue 6 / thesis Fig. 4.4: the full loss finds the modes on every env and every ablation does worse."""
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
    """Issue 6 / thesis Table 4.1: GLiDE+Planning >= 0.98 with and without perturbations, above BC perturbed."""
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
            Metric(
                "train_seconds",
                "classifier training wall time (s; k-means: its fit)",
                kind="timing",
                higher_is_better=False,
                fmt=".1f",
                goal=TRAIN_SECONDS_GOAL,
            ),
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
        params={**_SETUP_PARAMS, "grid_resolution": 200, "train_seed": 0, "plot_seeds": 1},
        default_seeds=5,
        references=tuple(
            Reference("overlap", OVERLAP_TARGET, env=env, method="full", source="issue 6 target (full loss)")
            for env in ENV_IDS
        ),
        plot=plot_grounding,
        findings=grounding_findings,
    )
)


# ---------------------------------------------------------------------- glide-polygon
def _planner(params: Mapping[str, Any]) -> Any:
    """GLiDE+Planning's settings: the defaults, with the free-space planner the params name."""
    from steer_envs.baselines.glide.mode_policies import FREE_SPACE_PLANNERS, PlannerConfig

    name = params.get("free_space_planner", "costmap")
    if name not in FREE_SPACE_PLANNERS:
        raise ValueError(
            f"{POLICY_SUITE}: parameter 'free_space_planner' must be one of {FREE_SPACE_PLANNERS}, got {name!r}"
        )
    return PlannerConfig(free_space_planner=name)


def _check_start(params: Mapping[str, Any]) -> str:
    """Where evaluation episodes start: ``free`` (default) or ``first_mode`` (the public env's reset)."""
    value = params.get("start", "free")
    if value not in EVAL_STARTS:
        raise ValueError(f"{POLICY_SUITE}: parameter 'start' must be one of {EVAL_STARTS}, got {value!r}")
    return str(value)


def _plan_policy(suite: Suite, request: TrialRequest) -> TrialPlan:
    params = suite.resolve_params(request.params, request.trials, base=request.base)
    for name, low in (
        ("n_rollouts", 1),
        ("bc_seeds", 1),
        ("glide_seeds", 1),
        ("layout_seed", 0),
        ("bc_steps", 1),
        ("max_steps", 1),
    ):
        _check_int_param(POLICY_SUITE, params, name, low)
    _check_start(params)
    setup_from_params(POLICY_SUITE, params, planner=_planner(params))
    trials = []
    for env in request.envs:
        for method in request.methods:
            if request.seeds is not None:
                seeds: Sequence[int] = request.seeds
            else:
                seeds = range(int(params["bc_seeds" if method == "bc" else "glide_seeds"]))
            trials += [Trial(suite.name, env, method, int(s), params, suite.fn) for s in seeds]
    return TrialPlan(tuple(trials))


def run_policy_trial(trial: Trial) -> TrialResult:
    """One env x method x training seed: success without and with perturbations (thesis Table 4.1)."""
    from steer_envs.baselines.glide.mode_policies import BCConfig
    from steer_envs.bench.suites.glide.protocol import policy_table_trial

    _num_modes(trial.env)
    if trial.method not in METHODS:
        raise ValueError(f"{POLICY_SUITE}: unknown method {trial.method!r}; expected one of {METHODS}")
    params = trial.params
    n_rollouts = _check_int_param(POLICY_SUITE, params, "n_rollouts", 1)
    layout = _check_int_param(POLICY_SUITE, params, "layout_seed", 0)
    max_steps = _check_int_param(POLICY_SUITE, params, "max_steps", 1)
    start = _check_start(params)
    bc = BCConfig(steps=_check_int_param(POLICY_SUITE, params, "bc_steps", 1))
    setup = setup_from_params(POLICY_SUITE, params, bc=bc, planner=_planner(params))
    with single_threaded():
        res = policy_table_trial(
            str(trial.env),
            layout,
            str(trial.method),
            n_rollouts,
            trial.seed,
            setup=setup,
            cache_dir=_cache_dir(params),
            max_steps=max_steps,
            start=start,
        )
    metrics = {
        "success": res["success"],
        "success_perturbed": res["success_perturbed"],
        "violation": res["unperturbed"]["violation_rate"],
        "violation_perturbed": res["perturbed"]["violation_rate"],
        "timeout_perturbed": res["perturbed"]["timeout_rate"],
        "train_seconds": res["train_seconds"],
        "eval_seconds": res["eval_seconds"],
    }
    extra = {
        "unperturbed": res["unperturbed"],
        "perturbed": res["perturbed"],
        "classifier_cached": res["classifier_cached"],
    }
    return TrialResult(metrics, extra)


def _policy_references() -> tuple[Reference, ...]:
    refs = []
    for method, by_modes in THESIS_TABLE_4_1.items():
        for k, (plain, perturbed) in by_modes.items():
            env = f"steer_envs/PolygonNav-{k}Mode-v0"
            refs.append(Reference("success", plain, env=env, method=method, source="thesis Table 4.1"))
            refs.append(Reference("success_perturbed", perturbed, env=env, method=method, source="thesis Table 4.1"))
    return tuple(refs)


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
            Metric(
                "train_seconds",
                "training wall time (s): the classifier for GLiDE (as first trained), the MLP for BC",
                kind="timing",
                higher_is_better=False,
                fmt=".1f",
                goal=TRAIN_SECONDS_GOAL,
            ),
            Metric("eval_seconds", "both evaluations' wall time (s)", kind="timing", higher_is_better=False, fmt=".1f"),
        ),
        run_trial=run_policy_trial,
        envs=ENV_IDS,
        methods=METHODS,
        params={
            **_SETUP_PARAMS,
            "n_rollouts": 1000,
            "layout_seed": 0,
            "bc_seeds": 10,
            "glide_seeds": 3,
            "bc_steps": 1500,
            "free_space_planner": "costmap",
            "max_steps": MAX_STEPS,
            "start": "free",
        },
        trials_param="n_rollouts",
        default_seeds=1,
        generate=_plan_policy,
        references=_policy_references(),
        findings=policy_findings,
    )
)
