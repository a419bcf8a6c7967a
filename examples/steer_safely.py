"""Steer the Maze2D Diffusion Policy with and without the maze's safety cost: collisions, alignment, a picture.

    python examples/steer_safely.py --sampler SS --starts 10 --out runs/steer_safely

For each start a simulated user sketches (through a wall when it can), and the
sampler steers a batch of plans toward the sketch twice: plain, and with
:func:`~steer_envs.steering.costs.safety_cost` of the env's ``TaskSpec`` (its
walls) added with ``--weight``. Prints the mean Min L2 to the sketch and the
share of plans through a wall, and draws the first start's two batches
(sketch magenta, plans teal, plans through a wall orange).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.baselines.pretrained import load_pretrained
from steer_envs.core.metrics import sketch_distances
from steer_envs.steering import make_sampler, policy_observation
from steer_envs.steering.costs import safety_cost
from steer_envs.users.sketcher import SketchUser
from steer_envs.utils.plots import figure_legend, key_line, new_figure, save_figure
from steer_envs.utils.threads import add_threads_argument, set_process_threads


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sampler", choices=("PR", "OP", "BI", "GD", "SS"), default="SS", help="default: SS")
    parser.add_argument("--starts", type=int, default=10, help="start locations (seeds 0..N-1; default 10)")
    parser.add_argument("--batch", type=int, default=32, help="plans per steering call (default 32)")
    parser.add_argument("--weight", type=float, default=1.0, help="the safety cost's weight (default 1)")
    parser.add_argument("--out", type=Path, default=Path("runs/steer_safely"), help="output directory")
    add_threads_argument(parser)
    args = parser.parse_args(argv)
    if args.starts < 1 or args.batch < 1 or not args.weight > 0:
        parser.error("--starts and --batch must be >= 1 and --weight > 0")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    set_process_threads(args.threads)
    policy = load_pretrained("dp")
    env: Any = gym.make("steer_envs/Maze2D-Large-v0", sample_goal=False).unwrapped
    samplers = {
        "plain": make_sampler(args.sampler),
        "safety": make_sampler(args.sampler, costs=[(safety_cost(env.task), args.weight)]),
    }
    scores: dict[str, list[tuple[float, float]]] = {name: [] for name in samplers}
    pictures = {}
    for seed in range(args.starts):
        obs, _ = env.reset(seed=seed)
        drawn = SketchUser(env.grid, through_wall=1.0, seed=seed).draw(env.state)
        for name, sampler in samplers.items():
            rng = np.random.default_rng(seed)  # both see the same initial noise
            result = sampler(policy, policy_observation(policy, [obs]), drawn.sketch, args.batch, generator=rng)
            plans = result.plans[:, policy.exec_start :]
            dist = sketch_distances(plans, drawn.sketch, scale=env.extent)
            scores[name].append((float(dist[result.chosen]), float(env.plan_collides(plans).mean())))
            if seed == 0:
                pictures[name] = env.render_overlay(drawn.sketch.points, plans)
    print(f"{args.sampler} over {args.starts} starts (batch {args.batch}), safety weight {args.weight}:")
    for name, rows in scores.items():
        min_l2, collision = np.mean(rows, axis=0)
        print(f"  {name:7s} Min L2 {min_l2:.3f}  plans through a wall {collision:.3f}")
    fig = new_figure(10.0, 4.8)
    for ax, (name, image) in zip(fig.subplots(1, 2), pictures.items(), strict=True):
        ax.imshow(image)
        ax.set_title(f"{args.sampler}, {name}", fontsize=10)
        ax.axis("off")
    fig.suptitle("Maze2D-Large, start 0: steering without and with the safety cost", fontsize=11)
    legend = [
        key_line("user sketch", color=(200 / 255, 30 / 255, 200 / 255), lw=3),
        key_line("plan", color=(20 / 255, 160 / 255, 160 / 255), lw=1.5),
        key_line("plan through a wall", color=(240 / 255, 140 / 255, 30 / 255), lw=1.5),
    ]
    figure_legend(fig, legend, ncol=3, fontsize=8)
    print(f"wrote {save_figure(fig, args.out / f'steer_safely_{args.sampler}.png')}")
    env.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
