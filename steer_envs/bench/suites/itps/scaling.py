"""``itps-maze2d-scaling``: how the Maze2D DP's collisions fall with training samples and width.

Table 2.1's collision findings need a DP that rarely collides unsteered (ITPS:
1 % of plans); a CPU budget buys far fewer samples than ITPS's 25.6 M. This
suite measures the trade: one method is one *pilot*, ``w{W}@{S}M``, a DP of
down dims ``(W, 2W, 4W)`` (the ``cpu`` preset otherwise) trained on ``S``
million samples of the shipped random walk, then scored on ``eval_starts``
starts of the ITPS protocol (:func:`~steer_envs.steering.maze.steering_trial`)
with RS, PR, BI, GD and SS. Pilots train resumably under ``cache_dir``
(``--run-dir`` of the training CLI): a killed run continues where it stopped,
a finished pilot is only re-scored. Seeds are training seeds.

The report adds a figure of collision against samples (log axis) per width
and a finding with the samples each width would need for RS collision
<= 0.05, from a power law fitted to its pilots.

>>> parse_pilot("w32@0.5M")
(32, 0.5)
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Metric, Suite, Trial, TrialResult, register_suite
from steer_envs.io import default_cache_dir
from steer_envs.utils.threads import limit_threads

__all__ = ["ITPS_MAZE2D_SCALING", "PILOTS", "ScalingParams", "parse_pilot", "pilot_checkpoint"]

SUITE_NAME = "itps-maze2d-scaling"
ENV_ID = "steer_envs/Maze2D-Large-v0"
#: the pilots: widths (first U-Net level) x millions of training samples
WIDTHS = (16, 32)
BUDGETS_M = (0.5, 1.0, 2.0, 4.0)
PILOTS: tuple[str, ...] = tuple(f"w{w}@{b:g}M" for w in WIDTHS for b in BUDGETS_M)
SAMPLERS = ("RS", "PR", "BI", "GD", "SS")
#: ITPS's training samples (100k steps x batch 256) and the unsteered collision its DP reaches
ITPS_SAMPLES_M = 25.6
TARGET_COLLISION = 0.05


def parse_pilot(name: str) -> tuple[int, float]:
    """``"w32@0.5M"`` -> ``(32, 0.5)``; ``ValueError`` for another form."""
    try:
        width, budget = name.removeprefix("w").split("@")
        out = int(width), float(budget.removesuffix("M"))
    except (AttributeError, ValueError):
        raise ValueError(f"{SUITE_NAME}: a pilot is 'w<width>@<millions>M', e.g. 'w32@0.5M', got {name!r}") from None
    if out[0] < 8 or out[0] % 8 or not 0 < out[1] <= 1000:
        raise ValueError(f"{SUITE_NAME}: pilot {name!r} needs a width that is a multiple of 8 and 0 < millions <= 1000")
    return out


@dataclass(frozen=True)
class ScalingParams(SuiteParams):
    """Parameters of ``itps-maze2d-scaling``.

    ``batch_size``, ``precision``, ``fused_optimizer``, ``compile_model``: the
    pilots' training (the ``cpu`` preset otherwise; its batch of 64 gives a
    small budget 4x the updates of ITPS's 256; ``bf16`` pays only on
    CPUs with native bfloat16, e.g. AMX, and is many times slower on AVX2);
    ``eval_starts`` ITPS
    starts scored per pilot, ``batch`` plans per steering call,
    ``through_wall`` the share of sketches through walls (as ``itps-maze2d``);
    ``torch_threads`` per trial process; ``cache_dir`` holds the data and the
    pilots' run folders (default: :func:`~steer_envs.io.default_cache_dir`
    of the suite's name); ``walk_steps``
    raw steps of the random walk (the shipped checkpoints': 1M, seed 0).
    """

    suite_name: ClassVar[str] = SUITE_NAME
    batch_size: int = 64
    precision: str = "fp32"
    fused_optimizer: bool = True
    compile_model: bool = False
    eval_starts: int = 100
    batch: int = 32
    through_wall: float = 0.3
    torch_threads: int = 1
    cache_dir: str = ""
    walk_steps: int = 1_000_000

    def __post_init__(self) -> None:
        self.require_at_least(1, "batch_size", "eval_starts", "batch", "torch_threads")
        self.require_at_least(1000, "walk_steps")
        if self.precision != "fp32":  # the import pulls in torch: only for a non-default value
            from steer_envs.baselines.common.configuration import PRECISIONS

            self.require_in("precision", PRECISIONS)
        self.require("through_wall", 0.0 <= self.through_wall <= 1.0, "in [0, 1]")

    @property
    def cache(self) -> Path:
        """The folder of the data and the pilots' runs."""
        return Path(self.cache_dir) if self.cache_dir else default_cache_dir(SUITE_NAME)


def _dataset(cache: Path, steps: int) -> Any:
    """The shipped checkpoints' random walk (``steps`` raw steps, seed 0), generated once into ``cache``."""
    from steer_envs.data.datasets import load_dataset
    from steer_envs.data.maze_random_walk import generate_random_walk, save_random_walk

    path = cache / f"maze2d-large-randomwalk-{steps}-seed0.npz"
    if not path.exists():
        save_random_walk(generate_random_walk("large", steps, seed=0, progress=False), path)
    return load_dataset(path)


def pilot_checkpoint(params: ScalingParams, pilot: str, seed: int) -> Path:
    """The pilot's checkpoint, trained (or resumed) under ``params.cache`` unless it exists."""
    from steer_envs.baselines.factory import get_preset, make_policy
    from steer_envs.baselines.training.trainer import save_trained, train_policy

    width, millions = parse_pilot(pilot)
    preset = get_preset("dp", "cpu")
    config = preset.model.replace(down_dims=(width, 2 * width, 4 * width))
    settings = preset.train.replace(
        steps=max(1, round(millions * 1e6 / params.batch_size)),
        batch_size=params.batch_size,
        precision=params.precision,
        fused_optimizer=params.fused_optimizer,
        compile_model=params.compile_model,
        seed=seed,
    )
    recipe = json.dumps({"settings": settings.to_dict(), "walk_steps": params.walk_steps}, sort_keys=True)
    tag = f"{pilot.replace('@', '-')}-seed{seed}-{hashlib.sha256(recipe.encode()).hexdigest()[:10]}"
    run_dir = params.cache / "pilots" / tag  # one folder per recipe: another batch size never resumes this one
    out = run_dir / "dp.safetensors"
    if out.exists():
        return out
    dataset = _dataset(params.cache, params.walk_steps)
    policy = make_policy(config, dataset=dataset, seed=seed)
    record = train_policy(policy, dataset, settings, progress=False, run_dir=run_dir, save_every=300.0)
    return save_trained(policy, out, "dp", {**record, "preset": "cpu"})


def run_scaling_trial(trial: Trial) -> TrialResult:
    """Train (or load) one pilot, then score it with every DP sampler on the ITPS starts."""
    from steer_envs.baselines.diffusion import DiffusionPolicy
    from steer_envs.baselines.training.trainer import sidecar_path
    from steer_envs.bench.table_2_1 import table_2_1_checks
    from steer_envs.steering.maze import steering_trial

    params = ScalingParams.from_json(trial.params)
    pilot = str(trial.method)
    width, millions = parse_pilot(pilot)
    with limit_threads(blas_threads=None, torch_threads=params.torch_threads):
        path = pilot_checkpoint(params, pilot, trial.seed)
        policy = DiffusionPolicy.load(path)
        training = json.loads(sidecar_path(path).read_text())["training"]
        scores: dict[str, dict[str, list[float]]] = {s: {"min_l2": [], "avg_l2": [], "collision": []} for s in SAMPLERS}
        for start in range(params.eval_starts):
            for sampler in SAMPLERS:
                result, _ = steering_trial(
                    str(trial.env), start, policy, sampler, batch=params.batch, through_wall=params.through_wall
                )
                for key, values in scores[sampler].items():
                    values.append(float(result[key]))  # type: ignore[arg-type]
    mean = {s: {k: float(np.mean(v)) for k, v in m.items()} for s, m in scores.items()}
    metrics: dict[str, float | None] = {
        "samples_m": millions,
        "parameters_m": policy.num_parameters() / 1e6,
        "train_hours": float(training["wall_s"]) / 3600,
        "final_loss": float(training["final_loss"]),
    }
    for sampler in SAMPLERS:
        metrics[f"collision_{sampler}"] = mean[sampler]["collision"]
    per_metric = ({s: mean[s][key] for s in SAMPLERS} for key in ("min_l2", "avg_l2", "collision"))
    metrics["findings_held"] = float(sum(bool(v) for v in table_2_1_checks(*per_metric)))
    return TrialResult(metrics, {"scores": mean, "width": width})


def samples_needed(points: Sequence[tuple[float, float]], target: float = TARGET_COLLISION) -> float | None:
    """Millions of samples where a power law ``c = a * S**b`` fitted to ``(S, c)`` points reaches ``target``.

    ``None`` with fewer than two points, a non-positive collision, or a fit that does not fall.

    >>> round(samples_needed([(1.0, 0.4), (4.0, 0.2)]), 1)
    64.0
    """
    fit = power_law(points)
    if fit is None or fit[0] >= 0:
        return None
    slope, intercept = fit
    return float(math.exp((math.log(target) - intercept) / slope))


def power_law(points: Sequence[tuple[float, float]]) -> tuple[float, float] | None:
    """``(b, log a)`` of ``c = a * S**b`` fitted in log-log to the positive ``(S, c)`` points; ``None`` below two S."""
    pts = [(s, c) for s, c in points if s > 0 and c > 0]
    if len({s for s, _ in pts}) < 2:
        return None
    slope, intercept = np.polyfit(np.log([s for s, _ in pts]), np.log([c for _, c in pts]), 1)
    return float(slope), float(intercept)


def _curves(table: Any) -> dict[int, list[tuple[float, float]]]:
    curves: dict[int, list[tuple[float, float]]] = {}
    for pilot in PILOTS:
        value = table.mean("collision_RS", pilot)
        if value is not None:
            width, millions = parse_pilot(pilot)
            curves.setdefault(width, []).append((millions, value))
    return curves


def scaling_findings(table: Any) -> list[Finding]:
    """Collisions fall with samples at every width; the samples each width needs for RS collision <= 0.05."""
    curves = _curves(table)
    out = []
    claim = "unsteered (RS) collision falls as training samples grow, at every width"
    if not any(len(c) > 1 for c in curves.values()):
        out.append(Finding(claim, None))
    else:
        falls = all(all(b[1] < a[1] for a, b in itertools.pairwise(c)) for c in curves.values() if len(c) > 1)
        detail = "; ".join(f"w{w}: " + ", ".join(f"{s:g}M {c:.3f}" for s, c in pts) for w, pts in curves.items())
        out.append(Finding(claim, falls, detail))
    claim = f"a CPU-sized DP reaches RS collision <= {TARGET_COLLISION} within ITPS's {ITPS_SAMPLES_M} M samples"
    needs = {w: samples_needed(pts) for w, pts in curves.items()}
    if not any(n is not None for n in needs.values()):
        out.append(Finding(claim, None))
    else:
        words = {
            w: "one pilot" if len(curves[w]) < 2 else "no fall" if n is None else f"{n:.1f} M" for w, n in needs.items()
        }
        detail = "; ".join(f"w{w}: {text}" for w, text in words.items())
        out.append(Finding(claim, any(n is not None and n <= ITPS_SAMPLES_M for n in needs.values()), detail))
    return out


def _plot(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    from steer_envs.bench.report import summarize
    from steer_envs.utils.plots import new_figure, save_figure

    tables = [t for t in summarize(records) if t.suite == suite.name]
    if not tables:
        return []
    table = tables[0]
    curves = _curves(table)
    if not curves:
        return []
    fig = new_figure(7.0, 4.2)
    ax = fig.add_subplot()
    for width, pts in sorted(curves.items()):
        xs = [s for s, _ in pts]
        (line,) = ax.plot(xs, [c for _, c in pts], "o-", label=f"RS, down dims {width}/{2 * width}/{4 * width}")
        needed, law = samples_needed(pts), power_law(pts)
        if needed is not None and law is not None:  # the power law through the pilots, out to where it meets the target
            fit = np.geomspace(min(xs), max(needed, ITPS_SAMPLES_M), 50)
            ax.plot(fit, np.exp(law[1]) * fit ** law[0], ":", color=line.get_color(), label=f"RS fit, width {width}")
        ss = [table.mean("collision_SS", f"w{width}@{s:g}M") for s in xs]
        if all(v is not None for v in ss):
            ax.plot(xs, ss, "s--", alpha=0.7, label=f"SS, width {width}")
    ax.axhline(TARGET_COLLISION, color="grey", ls=":", label=f"target {TARGET_COLLISION}")
    ax.axvline(ITPS_SAMPLES_M, color="black", ls="-.", lw=0.8, label=f"ITPS's {ITPS_SAMPLES_M} M samples")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("training samples (millions, log)")
    ax.set_ylabel("fraction of plans in a wall (log)")
    ax.set_title("Maze2D DP: RS and SS collision vs training samples")
    ax.legend(fontsize=8)
    return [str(save_figure(fig, Path(out_dir) / f"{suite.name}_collision.png"))]


ITPS_MAZE2D_SCALING = register_suite(
    Suite(
        name=SUITE_NAME,
        description=(
            "Maze2D DP scaling pilots (for Table 2.1's collision findings): collision of each DP sampler vs "
            "training samples and width; pilots 'w<width>@<millions>M' train resumably under cache_dir."
        ),
        metrics=(
            Metric("collision_RS", "unsteered plans in a wall (fraction)", higher_is_better=False, fmt=".3f"),
            Metric("collision_PR", "PR plans in a wall", higher_is_better=False, fmt=".3f"),
            Metric("collision_BI", "BI plans in a wall", higher_is_better=False, fmt=".3f"),
            Metric("collision_GD", "GD plans in a wall", higher_is_better=False, fmt=".3f"),
            Metric("collision_SS", "SS plans in a wall", higher_is_better=False, fmt=".3f"),
            Metric("findings_held", "Table 2.1 findings that hold for this pilot (of 4)", fmt=".0f"),
            Metric("samples_m", "training samples (millions)", fmt=".2f"),
            Metric("parameters_m", "network parameters (millions)", fmt=".2f"),
            Metric("train_hours", "training wall time (h)", kind="timing", higher_is_better=False, fmt=".2f"),
            Metric("final_loss", "final training loss", higher_is_better=False, fmt=".4f"),
        ),
        run_trial=run_scaling_trial,
        envs=(ENV_ID,),
        methods=PILOTS,
        params=ScalingParams(),
        default_seeds=1,
        plot=_plot,
        findings=scaling_findings,
    )
)
