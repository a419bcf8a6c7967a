"""``itps-maze2d``: thesis Table 2.1 — steering DP and ACT with sketches in Maze2D-Large.

One trial = one random start location (the seed) x one method. The agent is
reset at a random free cell (``env.reset(seed=seed)``), a simulated user
(:class:`~steer_envs.users.sketcher.SketchUser`, seeded by the trial seed) draws
a sketch from there (a share of them through walls), and the method (policy x
sampler) samples a batch of 32 plans. Every method of a seed sees the same
start, the same sketch and the same initial noise (ITPS fixed the seed per
call). Methods: DP with RS, PR, OP, BI, GD, SS; ACT with RS, PR, OP.

Metrics per trial (distances divided by the maze extent, ITPS's normalization;
plans scored from the policy's ``exec_start``, i.e. the executed waypoints):

* ``min_l2``: mean per-step L2 distance between the sketch (resampled to the
  plan length) and the plan the sampler *picks*. Every sampler but RS picks the
  batch's closest plan, so this is the batch minimum; RS picks a random plan,
  which is how Table 2.1 has RS's Min L2 (0.27) ~ its Avg L2 (0.28);
* ``avg_l2``: the batch mean of those distances;
* ``collision``: fraction of the batch with a waypoint in a wall cell;
* ``latency_ms`` (timing): wall time of the steering call (batch 32), after a
  per-process warm-up;
* ``ss_gd_latency`` (timing, DP-SS rows): SS's time per call over GD's, the
  medians of ``latency_repeats`` interleaved calls on the trial's input (goal
  <= 4.5, issue 7; the report's mean over the 100 trials smooths the noise of
  one pair);
* ``network_evals``: denoiser calls per steering call (DP-BI/GD/SS).

Timings run with ``torch_threads`` intra-op threads per trial process (default
1: the local executor already runs one trial per core, and on a loaded 2-core
machine two spinning OpenMP threads per process made a forward pass ~8x slower
and distorted the SS/GD ratio; 0 keeps torch's default).

Policies come from :func:`steer_envs.baselines.pretrained.load_pretrained`
(``kind`` = ``"dp"`` / ``"act"``, the committed checkpoints); the ``dp_checkpoint``
/ ``act_checkpoint`` parameters take another ``train_maze`` checkpoint file
(e.g. ``--preset itps`` trained on a GPU), and the ``dp_loader`` /
``act_loader`` parameters hold ``module:function`` paths, so other policies
plug in. While a loader's module, the function or its checkpoint does not
exist, the methods of that policy are skipped with a note. The ``plot`` hook draws the
alignment-vs-collision trade-off (thesis Fig. 2.4) and a qualitative grid of
plans per method (thesis Fig. 2.5) from the first ``plot_seeds`` trials.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

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
    resolve_function,
)

SUITE_NAME = "itps-maze2d"
ENV_ID = "steer_envs/Maze2D-Large-v0"
DP_SAMPLERS: tuple[str, ...] = ("RS", "PR", "OP", "BI", "GD", "SS")
ACT_SAMPLERS: tuple[str, ...] = ("RS", "PR", "OP")
METHODS: tuple[str, ...] = tuple(f"DP-{s}" for s in DP_SAMPLERS) + tuple(f"ACT-{s}" for s in ACT_SAMPLERS)
_DIFFUSION_ONLY = frozenset({"BI", "GD", "SS"})
#: exceptions that mean "this policy is not available (yet)": module, function or checkpoint missing
_UNAVAILABLE = (ImportError, AttributeError, FileNotFoundError)

#: thesis Table 2.1: method -> (Min L2, Avg L2, Collision)
TABLE_2_1: dict[str, tuple[float, float, float]] = {
    "DP-RS": (0.27, 0.28, 0.01),
    "DP-PR": (0.16, 0.28, 0.01),
    "DP-OP": (0.16, 0.28, 0.02),
    "DP-BI": (0.11, 0.14, 0.06),
    "DP-GD": (0.11, 0.18, 0.06),
    "DP-SS": (0.10, 0.12, 0.01),
    "ACT-RS": (0.26, 0.26, 0.16),
    "ACT-PR": (0.26, 0.26, 0.16),
    "ACT-OP": (0.26, 0.26, 0.35),
}


def split_method(method: str) -> tuple[str, str]:
    """``"DP-SS"`` -> ``("dp", "SS")``; ``ValueError`` for an unknown method."""
    if method not in METHODS:
        raise ValueError(f"itps-maze2d: unknown method {method!r}; methods: {', '.join(METHODS)}")
    kind, sampler = method.split("-")
    return kind.lower(), sampler


@functools.lru_cache(maxsize=4)
def load_policy(loader: str, kind: str, checkpoint: str = "") -> Any:
    """The frozen policy ``kind`` from a checkpoint file or the ``"module:function"`` loader (cached per process).

    A non-empty ``checkpoint`` (a ``train_maze`` output, e.g. a GPU run) wins;
    else the loader is called as ``loader(kind)`` when it takes an argument,
    else ``loader()``. Raises ImportError/AttributeError/FileNotFoundError while
    the policy is not available.
    """
    if checkpoint:
        from steer_envs.baselines.pretrained import load_checkpoint

        return load_checkpoint(kind, checkpoint)  # a wrong path is a ValueError, not a skipped policy
    fn = resolve_function(loader)
    try:
        takes_arg = bool(inspect.signature(fn).parameters)
    except (TypeError, ValueError):
        takes_arg = True
    policy = fn(kind) if takes_arg else fn()
    from steer_envs.core.policy import TrajectoryPolicy

    if not isinstance(policy, TrajectoryPolicy):
        raise TypeError(f"{loader}({kind!r}) must return a TrajectoryPolicy, got {type(policy).__name__}")
    return policy


def _policy(params: Mapping[str, Any], kind: str) -> Any:
    return load_policy(str(params[f"{kind}_loader"]), kind, str(params[f"{kind}_checkpoint"]))


def _check_params(params: Mapping[str, Any]) -> None:
    if params["batch"] < 1:
        raise ValueError(f"itps-maze2d: batch must be >= 1, got {params['batch']}")
    if not 0.0 <= params["through_wall"] <= 1.0:
        raise ValueError(f"itps-maze2d: through_wall must be in [0, 1], got {params['through_wall']}")
    if params["torch_threads"] < 0:
        raise ValueError(
            f"itps-maze2d: torch_threads must be >= 0 (0 = torch's default), got {params['torch_threads']}"
        )
    if params["latency_repeats"] < 1:
        raise ValueError(f"itps-maze2d: latency_repeats must be >= 1, got {params['latency_repeats']}")
    if params["plot_seeds"] < 0:
        raise ValueError(f"itps-maze2d: plot_seeds must be >= 0, got {params['plot_seeds']}")


def _plan_itps(suite: Suite, request: TrialRequest) -> TrialPlan:
    from steer_envs.core.policy import DiffusionPolicyLike

    params = suite.resolve_params(request.params, request.trials, base=request.base)
    _check_params(params)
    notes: list[str] = []
    available: dict[str, Any] = {}
    for kind in ("dp", "act"):
        if not any(m is not None and split_method(m)[0] == kind for m in request.methods):
            continue
        try:
            available[kind] = _policy(params, kind)
        except _UNAVAILABLE as exc:
            notes.append(
                f"skipped {kind.upper()} methods: policy not available ({type(exc).__name__}: {exc}); "
                f"train the checkpoint (issue 7) or set --param {kind}_loader=module:function"
            )
    trials: list[Trial] = []
    for env in request.envs:
        for method in request.methods:
            assert method is not None
            kind, name = split_method(method)
            if kind not in available:
                continue
            if name in _DIFFUSION_ONLY and not isinstance(available[kind], DiffusionPolicyLike):
                notes.append(f"skipped {method}: the {kind.upper()} policy does not expose its denoiser")
                continue
            trials += [Trial(suite.name, env, method, seed, params, suite.fn) for seed in suite.seed_list(request)]
    return TrialPlan(tuple(trials), tuple(notes))


_warm: set[tuple[int, str]] = set()


def _warm_up(policy: Any, sampler: Any, obs: Any, sketch: Any) -> None:
    """One small untimed call per (policy, sampler) and process: lazy initialisation stays out of latency_ms."""
    key = (id(policy), sampler.name)
    if key not in _warm:
        sampler(policy, obs, sketch, 2, generator=np.random.default_rng(0))
        _warm.add(key)


def run_itps_trial(trial: Trial) -> TrialResult:
    """One start location x one method (see the module docstring)."""
    import gymnasium as gym

    import steer_envs  # noqa: F401 - registers the envs in a fresh worker
    from steer_envs.core.metrics import sketch_distances
    from steer_envs.users.sketcher import SketchUser
    from steer_envs.wrappers.samplers import GuidedDiffusion, OutputPerturbation, benchmark_latency, make_sampler
    from steer_envs.wrappers.steering import policy_observation

    params = trial.params
    if params["torch_threads"] > 0:
        import torch

        torch.set_num_threads(int(params["torch_threads"]))
    kind, name = split_method(str(trial.method))
    policy = _policy(params, kind)
    env = gym.make(str(trial.env), sample_goal=False).unwrapped
    try:
        obs, _ = env.reset(seed=trial.seed)
        user = SketchUser(env.grid, through_wall=float(params["through_wall"]), seed=trial.seed)
        drawn = user.draw(env.state)
        sampler = OutputPerturbation(collides=env.is_wall) if name == "OP" else make_sampler(name)
        obs_in = policy_observation(policy, [obs])
        _warm_up(policy, sampler, obs_in, drawn.sketch)
        generator = np.random.default_rng(np.random.SeedSequence([trial.seed, 0x1795]))
        result = sampler(policy, obs_in, drawn.sketch, int(params["batch"]), generator=generator)
        # ITPS scores the executed waypoints (LeRobot's DP restates the current position in plan[0])
        plans = result.plans[:, int(getattr(policy, "exec_start", 0)) :]
        dist = sketch_distances(plans, drawn.sketch, scale=env.extent)
        collides = env.plan_collides(plans)
        metrics: dict[str, float | None] = {
            "min_l2": float(dist[result.chosen]),
            "avg_l2": float(dist.mean()),
            "collision": float(collides.mean()),
            "latency_ms": float(result.timings["total_ms"]),
            "ss_gd_latency": None,
            "network_evals": result.timings.get("network_evals"),
        }
        if name == "SS":
            _warm_up(policy, GuidedDiffusion(), obs_in, drawn.sketch)
            ms = benchmark_latency(
                policy,
                {"GD": GuidedDiffusion(), "SS": sampler},
                obs_in,
                drawn.sketch,
                batch=int(params["batch"]),
                repeats=int(params["latency_repeats"]),
                warmup=0,
                seed=trial.seed,
            )
            metrics["ss_gd_latency"] = ms["SS"] / ms["GD"]
        extra: dict[str, Any] = {
            "start": np.asarray(env.state).round(4).tolist(),
            "sketch_kind": drawn.kind,
            "sketch_collides": drawn.collides,
        }
        if trial.seed < int(params["plot_seeds"]):
            extra.update(
                sketch=drawn.sketch.points.round(3).tolist(),
                plans=plans.round(3).tolist(),
                collides=collides.tolist(),
                distances=dist.round(4).tolist(),
                chosen=int(result.chosen),
                perturbed_state=None if result.perturbed_state is None else result.perturbed_state.round(4).tolist(),
            )
        return TrialResult(metrics, extra)
    finally:
        env.close()


# -------------------------------------------------------------------- plots
def _maze_walls(records: Sequence[Mapping[str, Any]]) -> np.ndarray:
    import gymnasium as gym

    import steer_envs  # noqa: F401

    env_id = next((r["config"]["env"] for r in records if r["config"].get("env")), ENV_ID)
    env = gym.make(env_id).unwrapped
    try:
        return np.array(env.grid.walls)
    finally:
        env.close()


def _draw_maze(ax: Any, walls: np.ndarray) -> None:
    # x = row (down), y = column (right): show the grid as an image with rows top to bottom
    rows, cols = walls.shape
    ax.imshow(np.where(walls, 0.35, 0.97), cmap="gray", vmin=0, vmax=1, extent=(-0.5, cols - 0.5, rows - 0.5, -0.5))
    ax.set_xlim(-0.5, cols - 0.5)
    ax.set_ylim(rows - 0.5, -0.5)
    ax.set_autoscale_on(False)
    ax.set_xticks([])
    ax.set_yticks([])


def _draw_plans(ax: Any, record: Mapping[str, Any]) -> None:
    from matplotlib import colormaps
    from matplotlib.collections import LineCollection

    extra = record["extra"]
    plans = np.asarray(extra["plans"], dtype=np.float64)
    collides = np.asarray(extra["collides"], dtype=bool)
    dist = np.asarray(extra["distances"], dtype=np.float64)
    sketch = np.asarray(extra["sketch"], dtype=np.float64)
    ax.plot(sketch[:, 1], sketch[:, 0], color="0.4", linewidth=4, alpha=0.7, solid_capstyle="round", zorder=4)
    # thicker = closer to the sketch (thesis Fig. 2.5); drawn far-to-near so the best plans are on top
    spread = max(float(dist.max() - dist.min()), 1e-9)
    cmap = colormaps["rainbow"]
    for b in np.argsort(-dist):
        pts = plans[b][:, ::-1]
        segments = np.stack([pts[:-1], pts[1:]], axis=1)
        colors = cmap(np.linspace(0.0, 1.0, len(segments)))
        if collides[b]:
            colors[:, :3] = 0.25 * colors[:, :3] + 0.75  # tinted white, as in the thesis
        width = 0.6 + 2.4 * (1.0 - (dist[b] - dist.min()) / spread)
        ax.add_collection(LineCollection(segments, colors=colors, linewidths=width, zorder=2))
    start = np.asarray(extra["start"], dtype=np.float64)
    ax.plot(start[1], start[0], "o", color="red", markersize=6, zorder=3)
    if extra.get("perturbed_state") is not None:
        moved = np.asarray(extra["perturbed_state"], dtype=np.float64)
        ax.plot(moved[1], moved[0], "o", color="red", markersize=6, markerfacecolor="none", zorder=3)


def plot_itps(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """Trade-off plot (Avg/Min L2 vs collision, thesis numbers hollow) and the qualitative grid."""
    from steer_envs.bench.plots import new_figure, save_figure
    from steer_envs.bench.report import summarize

    written: list[str] = []
    tables = [t for t in summarize(records) if t.suite == suite.name]
    rows = [r for r in tables[0].rows if r.stats.get("avg_l2") is not None] if tables else []
    if rows:
        fig = new_figure(6.5, 4.5)
        ax = fig.add_subplot()
        for i, r in enumerate(rows):
            color = f"C{i % 10}"
            marker = "o" if (r.method or "").startswith("DP") else "s"
            coll, avg, mn = (r.stats[k].mean for k in ("collision", "avg_l2", "min_l2"))  # type: ignore[union-attr]
            ax.scatter([coll], [avg], color=color, marker=marker, s=60, label=r.method)
            ax.scatter([coll], [mn], color=color, marker=marker, s=25, alpha=0.6)
            ax.plot([coll, coll], [mn, avg], color=color, linewidth=1, alpha=0.6)
            ref = TABLE_2_1.get(r.method or "")
            if ref is not None:
                ax.scatter([ref[2]], [ref[1]], facecolors="none", edgecolors=color, marker=marker, s=60)
        ax.set_xlabel("collision rate (fraction of the batch)")
        ax.set_ylabel("L2 to sketch / maze extent (big: Avg, small: Min)")
        ax.set_title("itps-maze2d: alignment vs. collision (hollow: thesis Table 2.1)", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
        written.append(str(save_figure(fig, Path(out_dir) / f"{suite.name}_tradeoff.png")))
    with_plans = [r for r in records if "plans" in r.get("extra", {})]
    if with_plans:
        methods = [m for m in METHODS if any(r["config"]["method"] == m for r in with_plans)]
        seeds = sorted({int(r["seed"]) for r in with_plans})[:3]
        walls = _maze_walls(with_plans)
        fig = new_figure(2.4 * len(methods) + 0.5, 1.9 * len(seeds) + 0.6)
        axes = fig.subplots(len(seeds), len(methods), squeeze=False)
        for i, seed in enumerate(seeds):
            for j, method in enumerate(methods):
                ax = axes[i][j]
                _draw_maze(ax, walls)
                rec = next((r for r in with_plans if r["config"]["method"] == method and int(r["seed"]) == seed), None)
                if rec is not None:
                    _draw_plans(ax, rec)
                if i == 0:
                    ax.set_title(method, fontsize=9)
                if j == 0:
                    ax.set_ylabel(f"seed {seed}", fontsize=8)
        fig.suptitle("itps-maze2d: sketch (gray), plans blue->red over time, collisions tinted white", fontsize=9)
        written.append(str(save_figure(fig, Path(out_dir) / f"{suite.name}_qualitative.png")))
    return written


def itps_findings(table: Any) -> list[Finding]:
    """Table 2.1's qualitative findings (issue 7's Done-when), checked on a run's summary table."""
    dp = [f"DP-{s}" for s in DP_SAMPLERS]
    min_l2, avg_l2, coll = (table.means(m, dp) for m in ("min_l2", "avg_l2", "collision"))

    def fmt(values: Mapping[str, float] | None, *methods: str) -> str:
        return ", ".join(f"{m[3:]} {values[m]:.3f}" for m in methods) if values else ""

    findings = []
    claim = "SS has the best Min L2 and Avg L2 among the DP samplers"
    if min_l2 is None or avg_l2 is None:
        findings.append(Finding(claim, None))
    else:
        others = [m for m in dp if m != "DP-SS"]
        best_min, best_avg = min(others, key=min_l2.__getitem__), min(others, key=avg_l2.__getitem__)
        holds = min_l2["DP-SS"] < min_l2[best_min] and avg_l2["DP-SS"] < avg_l2[best_avg]
        detail = f"Min L2 {fmt(min_l2, 'DP-SS', best_min)}; Avg L2 {fmt(avg_l2, 'DP-SS', best_avg)}"
        findings.append(Finding(claim, holds, detail))
    claim = "SS's collision rate is within 0.02 of RS's"
    holds = None if coll is None else abs(coll["DP-SS"] - coll["DP-RS"]) <= 0.02
    findings.append(Finding(claim, holds, fmt(coll, "DP-SS", "DP-RS")))
    claim = "GD and BI collide more than SS"
    holds = None if coll is None else coll["DP-GD"] > coll["DP-SS"] and coll["DP-BI"] > coll["DP-SS"]
    findings.append(Finding(claim, holds, fmt(coll, "DP-GD", "DP-BI", "DP-SS")))
    claim = "PR improves Min L2 over RS but not Avg L2"
    if min_l2 is None or avg_l2 is None:
        findings.append(Finding(claim, None))
    else:
        holds = min_l2["DP-PR"] < min_l2["DP-RS"] and avg_l2["DP-PR"] >= avg_l2["DP-RS"] - 0.005
        detail = f"Min L2 {fmt(min_l2, 'DP-PR', 'DP-RS')}; Avg L2 {fmt(avg_l2, 'DP-PR', 'DP-RS')}"
        findings.append(Finding(claim, holds, detail))
    return findings


def _references() -> tuple[Reference, ...]:
    refs = []
    for method, (mn, avg, coll) in TABLE_2_1.items():
        for metric, value in (("min_l2", mn), ("avg_l2", avg), ("collision", coll)):
            refs.append(Reference(metric, value, env=ENV_ID, method=method, source="thesis Table 2.1"))
    return tuple(refs)


ITPS_MAZE2D = register_suite(
    Suite(
        name=SUITE_NAME,
        description="ITPS Maze2D (thesis Table 2.1): sketch steering of DP (6 samplers) and ACT (RS/PR/OP), batch 32.",
        metrics=(
            Metric("min_l2", "L2 of the picked plan to the sketch / maze extent", higher_is_better=False, fmt=".3f"),
            Metric("avg_l2", "batch-mean L2 to the sketch / maze extent", higher_is_better=False, fmt=".3f"),
            Metric("collision", "fraction of the batch with a waypoint in a wall", higher_is_better=False, fmt=".3f"),
            Metric("latency_ms", "ms per steering call (batch 32)", kind="timing", higher_is_better=False, fmt=".1f"),
            Metric(
                "ss_gd_latency",
                "SS / GD time per call, back to back",
                kind="timing",
                higher_is_better=False,
                fmt=".2f",
                goal=4.5,
            ),
            Metric("network_evals", "denoiser calls per steering call", higher_is_better=False, fmt=".0f"),
        ),
        run_trial=run_itps_trial,
        envs=(ENV_ID,),
        methods=METHODS,
        params={
            "batch": 32,
            "through_wall": 0.3,
            "plot_seeds": 3,
            "torch_threads": 1,
            "latency_repeats": 1,
            "dp_loader": "steer_envs.baselines.pretrained:load_pretrained",
            "act_loader": "steer_envs.baselines.pretrained:load_pretrained",
            "dp_checkpoint": "",
            "act_checkpoint": "",
        },
        default_seeds=100,
        generate=_plan_itps,
        references=_references(),
        quick={"plot_seeds": 2},
        quick_seeds=4,
        plot=plot_itps,
        findings=itps_findings,
    )
)
