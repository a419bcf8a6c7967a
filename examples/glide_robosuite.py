"""GLiDE on a robosuite arm end to end: expert demos -> perturbed replays -> mode classifier -> PNG of the modes.

    python examples/glide_robosuite.py --task can --demos 10 --out runs/glide_robosuite

The scripted expert records ``--demos`` demonstrations; each is replayed
``--replays`` times with GLiDE's perturbations (the end effector pulled off
its path, or the gripper forced open) and labelled only by task success. The
mode classifier learns from the recorded LLM response's features (thesis
appendix) with the full underactuated loss (eq. 4.3); printed are the replays'
success rate, the training time and the accuracy of the learned modes against
the ground truth on every demo sample, with the k-means baseline beside it.
The PNG shows the true and learned modes along the first demos. The replays
are cached under ``--out`` (a second run with the same settings reuses them).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from steer_envs.baselines.glide import ArmGroundingSetup, evaluate_arm_grounding
from steer_envs.data import robosuite_replays as rr
from steer_envs.data.robosuite_replay_sets import replay_set, split_demos
from steer_envs.envs.robosuite.tasks import TASK_NAMES, TASKS
from steer_envs.utils.threads import add_threads_argument, set_process_threads


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", choices=TASK_NAMES, default="can", help="robosuite task (default can)")
    parser.add_argument("--demos", type=int, default=10, help="expert demonstrations (default 10)")
    parser.add_argument("--replays", type=int, default=10, help="perturbed replays per demo (default 10)")
    parser.add_argument("--epochs", type=int, default=1000, help="classifier training epochs (default 1000)")
    parser.add_argument("--seed", type=int, default=0, help="classifier seed (default 0)")
    parser.add_argument("--show", type=int, default=3, help="demos drawn in the PNG (default 3)")
    parser.add_argument("--out", type=Path, default=Path("runs/glide_robosuite"), help="output directory")
    add_threads_argument(parser)
    args = parser.parse_args(argv)
    for name, low in (("demos", 1), ("replays", 1), ("epochs", 1), ("seed", 0), ("show", 1)):
        if getattr(args, name) < low:
            parser.error(f"--{name} must be >= {low}, got {getattr(args, name)}")
    return args


def trajectories(args: argparse.Namespace) -> list[rr.ArmTrajectory]:
    """The demos and their replays, read from ``--out``'s cache when an earlier run wrote them."""
    cache = args.out / "cache" / f"{args.task}-{args.demos}demos-{args.replays}replays.npz"
    if cache.exists():
        return rr.load_trajectories(cache)[0]
    trajs = replay_set(args.task, args.demos, replays_per_demo=args.replays)
    rr.save_trajectories(cache, trajs)
    return trajs


def save_mode_strips(labels: dict[str, list[dict[str, list[int]]]], task: str, png: Path) -> Path:
    """One panel per kept demo: a strip of the true modes, then one per variant's learned modes, over time."""
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    names, colors = TASKS[task].modes, ("#4c72b0", "#dd8452", "#55a868", "#c44e52")
    first = next(iter(labels.values()))
    fig = Figure(figsize=(9.0, 1.2 + 0.35 * len(first) * (len(labels) + 1)), layout="constrained")
    for i, ax in enumerate(fig.subplots(len(first), 1, squeeze=False)[:, 0]):
        rows = [("ground truth", first[i]["true"])] + [(v, lab[i]["pred"]) for v, lab in labels.items()]
        grid = np.full((len(rows), max(len(m) for _, m in rows)), np.nan)
        for r, (_, modes) in enumerate(rows):
            grid[r, : len(modes)] = modes
        cmap = ListedColormap(list(colors[: len(names)]))
        ax.imshow(grid, aspect="auto", cmap=cmap, vmin=-0.5, vmax=len(names) - 0.5, interpolation="nearest")
        ax.set_yticks(range(len(rows)), [label for label, _ in rows])
        ax.set(xlabel="control step (20 Hz)", title=f"demo {i}")
    handles = [Patch(color=colors[m], label=name) for m, name in enumerate(names)]
    fig.legend(handles=handles, loc="outside right upper", fontsize="small")
    fig.suptitle(f"{task}: learned vs ground-truth modes along the demos", fontsize=10)
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=120)
    return png


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    set_process_threads(args.threads)
    start = time.perf_counter()
    trajs = trajectories(args)
    demos, replays = split_demos(trajs)
    plain = [r for r in replays if r.perturbation.kind != "truncated"]
    print(
        f"{args.task}: {len(demos)} demos, {len(plain)} replays ({np.mean([r.success for r in plain]):.0%} "
        f"successful) in {time.perf_counter() - start:.0f} s"
    )
    setup = ArmGroundingSetup(
        n_demos=args.demos, replay_demos=args.demos, replays_per_demo=args.replays, epochs=args.epochs
    )
    show = min(args.show, len(demos))
    results = {}
    for variant in ("full", "kmeans"):
        res = evaluate_arm_grounding(args.task, variant, trajs, seed=args.seed, setup=setup, keep=show)
        results[variant] = res
        per_mode = ", ".join(
            f"{name} {acc:.2f}" for name, acc in zip(TASKS[args.task].modes, res["accuracy_per_mode"], strict=True)
        )
        print(f"{variant:>6}: accuracy {res['accuracy']:.3f} ({per_mode}); {res['train_seconds']:.0f} s")
    labels = {variant: res["labels"] for variant, res in results.items()}
    path = save_mode_strips(labels, args.task, args.out / f"glide_{args.task}_modes.png")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
