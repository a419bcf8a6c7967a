"""GLiDE on PolygonNav end to end: demos -> counterfactual replays -> mode classifier -> GLiDE+Planning -> PNG.

    python examples/glide_polygon.py --modes 4 --layout 1 --out runs/glide

Seven expert demonstrations are replayed with GLiDE's segment perturbations
(X -> random Z -> Y) and labelled only by task success; the mode classifier is
trained on them with the full loss (thesis eq. 4.2), and GLiDE+Planning follows
the learned modes (free space: the exposure-weighted grid path, ``--planner
rrt`` for the thesis's RRT). Printed: classifier training time, overlap and
per-mode IoU of the learned modes with the ground truth, and the planner's
success rate without and with the evaluation teleports (thesis Table 4.1).
The PNG shows the true polygons, the learned modes and a few rollouts (blue:
success, red: failure; no mode is drawn red), with a legend. The classifier is
cached under ``--out`` (a second run with the same settings skips training).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.baselines.glide import (
    FREE_SPACE_PLANNERS,
    GlidePlanningPolicy,
    GlideSetup,
    PlannerConfig,
    counterfactual_data,
    evaluate_polygon_policy,
    learn_grounding,
    make_polygon_policy,
    mode_iou,
    mode_overlap,
    polygon_demonstrations,
    workspace_grid,
)
from steer_envs.utils.threads import add_threads_argument, limit_threads

#: mode colours (free space first), none of them the rollouts' blue or red
MODE_COLORS = ("#f2f2f2", "#8dd3c7", "#ffffb3", "#bebada", "#fdb462", "#b3de69")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--modes", type=int, choices=(3, 4, 5), default=4, help="PolygonNav-KMode-v0 (default 4)")
    parser.add_argument("--layout", type=int, default=0, help="layout seed of the polygon chain (default 0)")
    parser.add_argument("--seed", type=int, default=0, help="seed of demos, replays, training and rollouts")
    parser.add_argument("--replays", type=int, default=1000, help="successful and failed replays, each (default 1000)")
    parser.add_argument("--epochs", type=int, default=2000, help="classifier training epochs (default 2000)")
    parser.add_argument("--rollouts", type=int, default=200, help="evaluation episodes per column (default 200)")
    parser.add_argument("--planner", choices=FREE_SPACE_PLANNERS, default="costmap", help="free-space planner")
    parser.add_argument(
        "--max-steps", type=int, default=1000, help="episode length (default 1000, as Table 4.1's evaluation)"
    )
    parser.add_argument("--show", type=int, default=12, help="rollouts drawn in the PNG (default 12)")
    parser.add_argument("--out", type=Path, default=Path("runs/glide"), help="output directory (default runs/glide)")
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show (or hide) the training progress bar (default: shown only when stderr is a terminal)",
    )
    add_threads_argument(parser)
    args = parser.parse_args(argv)
    for name in ("layout", "seed"):
        if getattr(args, name) < 0:
            parser.error(f"--{name} must be >= 0")
    for name in ("replays", "epochs", "rollouts", "show", "max_steps"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1")
    return args


def say(line: str) -> None:
    """Print ``line`` now (flushed: a log shows each phase as it starts, not at the end)."""
    print(line, flush=True)


def record_rollouts(
    policy: GlidePlanningPolicy, env_id: str, layout: int, n: int, seed: int
) -> tuple[list[np.ndarray], list[bool]]:
    """``n`` unperturbed episodes at once: each agent's path and whether it succeeded."""
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", layout_seed=layout)
    try:
        obs, _ = venv.reset(seed=seed)
        policy.reset()
        paths = [[o.copy()] for o in obs]
        done = np.zeros(n, dtype=bool)
        success = np.zeros(n, dtype=bool)
        while not done.all():
            action = np.asarray(policy.act(np.asarray(obs, dtype=np.float64)), dtype=np.float32)
            action[done] = 0.0
            obs, _, terminated, truncated, info = venv.step(action)
            live = ~done
            for i in np.flatnonzero(live):
                paths[i].append(obs[i].copy())
            ended = live & (np.asarray(terminated) | np.asarray(truncated))
            success |= ended & np.asarray(info["success"], dtype=bool)
            done |= ended
    finally:
        venv.close()
    return [np.asarray(p) for p in paths], success.tolist()


def draw_modes(
    model: Any,
    panels: dict[str, np.ndarray],
    paths: list[np.ndarray],
    success: list[bool],
    mode_names: list[str],
    png: Path,
    title: str,
) -> None:
    """One panel per labelling of the 200 x 200 grid, with the polygons and the rollouts (blue: success, red: not)."""
    from matplotlib.artist import Artist
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    colors = list(MODE_COLORS[: len(mode_names)])
    fig = Figure(figsize=(4.2 * len(panels), 4.8), layout="constrained")
    extent = (model.low[0], model.high[0], model.low[1], model.high[1])
    for ax, (name, labels) in zip(fig.subplots(1, len(panels), squeeze=False)[0], panels.items(), strict=True):
        image = np.asarray(labels).reshape(200, 200)
        ax.imshow(image, origin="lower", extent=extent, cmap=ListedColormap(colors), vmin=-0.5, vmax=len(colors) - 0.5)
        for vertices in model.vertices:
            loop = np.vstack([vertices, vertices[:1]])
            ax.plot(loop[:, 0], loop[:, 1], color="k", lw=0.6)
        for path, ok in zip(paths, success, strict=True):
            ax.plot(path[:, 0], path[:, 1], color="#1f3fbf" if ok else "#d62728", lw=0.7)
        ax.set(title=name, xticks=[], yticks=[], aspect="equal")
    handles: list[Artist] = [
        Patch(facecolor=c, edgecolor="0.4", label=f"mode {m}: {n}")
        for m, (c, n) in enumerate(zip(colors, mode_names, strict=True))
    ]
    handles += [
        Line2D([], [], color="#1f3fbf", label="rollout, success"),
        Line2D([], [], color="#d62728", label="rollout, failure"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncol=3, fontsize="small")
    fig.suptitle(title, fontsize=10)
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=120)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    with limit_threads(blas_threads=args.threads, torch_threads=args.threads):
        return run(args)


def run(args: argparse.Namespace) -> int:
    """The example, printing each phase as it starts (a log gets no progress bar, but these lines)."""
    env_id = f"steer_envs/PolygonNav-{args.modes}Mode-v0"
    base = GlideSetup()
    setup = replace(
        base,
        n_success=args.replays,
        n_failure=args.replays,
        train=replace(base.train, epochs=args.epochs, num_threads=args.threads, progress=args.progress),
        planner=PlannerConfig(free_space_planner=args.planner),
    )
    cache = args.out / "cache"
    say(f"{env_id} layout {args.layout}: {setup.n_demos} demos, {args.replays} + {args.replays} replays ...")
    tic = time.perf_counter()
    demos = polygon_demonstrations(env_id, args.layout, setup.n_demos, args.seed, goal_steps=setup.demo_goal_steps)
    data = counterfactual_data(env_id, args.layout, args.seed, setup, demos, cache)  # cached for learn_grounding
    say(
        f"replays: {len(data.success)} labelled trajectories ({time.perf_counter() - tic:.1f} s); training the mode "
        f"classifier ({args.epochs} epochs, about a minute on one core; a cached one is reused) ..."
    )
    tic = time.perf_counter()
    grounding = learn_grounding(env_id, args.layout, "full", args.seed, setup=setup, cache_dir=cache)
    say(
        f"classifier: trained in {grounding.info['train_seconds']:.1f} s "
        f"({'cached' if grounding.info.get('cached') else f'{time.perf_counter() - tic:.0f} s in all'})"
    )

    env = gym.make(env_id, layout_seed=args.layout)
    model = env.unwrapped.model  # type: ignore[attr-defined]
    mode_names = list(env.unwrapped.task.modes)  # type: ignore[attr-defined]
    env.close()
    grid = workspace_grid(model.low, model.high, 200)
    truth, learned = model.mode_of(grid), np.asarray(grounding.predictor.predict(grid))
    iou = mode_iou(learned, truth, args.modes)
    print(f"learned modes: overlap {mode_overlap(learned, truth):.3f}, IoU per mode {np.round(iou, 2).tolist()}")

    policy, _ = make_polygon_policy("glide_planning", env_id, args.layout, args.seed, setup=setup, cache_dir=cache)
    assert isinstance(policy, GlidePlanningPolicy)
    for perturbed in (False, True):
        say(f"evaluating GLiDE+Planning on {args.rollouts} episodes {'with' if perturbed else 'without'} teleports ...")
        res = evaluate_polygon_policy(
            policy,
            env_id,
            args.layout,
            n_rollouts=args.rollouts,
            perturbed=perturbed,
            seed=args.seed,
            max_steps=args.max_steps,
        )
        label = "with teleports   " if perturbed else "without teleports"
        say(
            f"GLiDE+Planning ({args.planner}) {label}: success {res['success_rate']:.3f}, "
            f"invalid transitions {res['violation_rate']:.3f}, out of steps {res['timeout_rate']:.3f} "
            f"({args.rollouts} episodes of <= {args.max_steps} steps)"
        )

    paths, success = record_rollouts(policy, env_id, args.layout, args.show, args.seed + 1)
    png = args.out / f"glide_{args.modes}modes_layout{args.layout}.png"
    title = f"GLiDE on PolygonNav-{args.modes}Mode (layout {args.layout}): true vs learned modes, rollouts"
    draw_modes(model, {"true modes": truth, "learned modes": learned}, paths, success, mode_names, png, title)
    print(f"wrote {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
