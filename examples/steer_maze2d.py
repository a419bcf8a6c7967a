"""Steer a frozen Maze2D policy with a sketch: sketch -> steered batch of plans -> rollout -> PNG.

    python examples/steer_maze2d.py --sampler SS --seed 3 --out runs/steer

A simulated user draws a sketch from the agent's start (sometimes through a
wall), :class:`~steer_envs.wrappers.SteeringWrapper` samples a batch of plans
from the committed Diffusion Policy (or ACT) checkpoint with the chosen sampler
and executes the best plan in the MuJoCo maze. The PNG shows the sketch
(magenta), the sampled plans (teal; orange = in collision) and, on the right,
the executed rollout (blue trail) and the agent (red); a legend names them. Alignment and collision numbers are printed
as in thesis Table 2.1.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.baselines.pretrained import PRETRAINED_LOADER, add_policy_arguments, resolve_policy
from steer_envs.core.metrics import sketch_distances
from steer_envs.steering import SAMPLERS, OutputPerturbation, make_sampler
from steer_envs.users.sketcher import SketchUser
from steer_envs.utils.plots import figure_legend, key_line, key_patch, new_figure, save_figure
from steer_envs.utils.threads import add_threads_argument, set_process_threads
from steer_envs.wrappers import SteeringWrapper

#: the colours ``Maze2DEnv.render_overlay`` draws with (RGB 0-255), named in the figure's legend
OVERLAY_COLOURS = {
    "sketch": (200, 30, 200),
    "plan": (20, 160, 160),
    "collision": (240, 140, 30),
    "trail": (40, 40, 200),
    "agent": (220, 30, 30),
    "wall": (90, 90, 100),
}


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_policy_arguments(parser)
    parser.add_argument("--sampler", choices=sorted(SAMPLERS), default="SS", help="steering sampler (default: SS)")
    parser.add_argument("--batch", type=int, default=32, help="plans sampled per call (default: 32)")
    parser.add_argument("--seed", type=int, default=0, help="start location, sketch and noise seed (default: 0)")
    parser.add_argument("--through-wall", action="store_true", help="make the user sketch straight through walls")
    parser.add_argument("--out", type=Path, default=Path("runs/steer_maze2d"), help="output directory")
    add_threads_argument(parser)
    return parser.parse_args(argv)


def steering_figure(before: np.ndarray, after: np.ndarray, title: str) -> Any:
    """The two panels (sketch + steered batch; chosen plan + rollout) with a legend of every colour."""
    fig = new_figure(10.0, 4.8)
    panels = ("sketch + steered batch", "chosen plan + executed rollout")
    for ax, image, name in zip(fig.subplots(1, 2), (before, after), panels, strict=True):
        ax.imshow(image)
        ax.set_title(name, fontsize=10)
        ax.axis("off")
    fig.suptitle(title, fontsize=11)
    rgb = {name: tuple(c / 255 for c in value) for name, value in OVERLAY_COLOURS.items()}
    figure_legend(
        fig,
        [
            key_line("user sketch (dot: its start)", color=rgb["sketch"], lw=3, marker="o", markersize=4),
            key_line("sampled plan", color=rgb["plan"], lw=1.5),
            key_line("plan through a wall (collision)", color=rgb["collision"], lw=1.5),
            key_line("executed rollout", color=rgb["trail"], lw=2),
            key_line("agent", color=rgb["agent"], marker="o", ls="none", markersize=7),
            key_patch("wall", facecolor=rgb["wall"]),
        ],
        ncol=3,
        fontsize=8,
    )
    return fig


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    set_process_threads(args.threads)  # one thread: an SS call took 15-23 s instead of 0.9 s on a busy machine
    try:
        policy = resolve_policy(args.loader or PRETRAINED_LOADER, args.policy, args.checkpoint)
    except (ImportError, AttributeError, FileNotFoundError, ValueError) as exc:
        print(f"the {args.policy} policy is not available ({type(exc).__name__}: {exc})", file=sys.stderr)
        return 2
    env = gym.make("steer_envs/Maze2D-Large-v0", sample_goal=False)
    sampler = OutputPerturbation() if args.sampler == "OP" else make_sampler(args.sampler)
    steer = SteeringWrapper(env, policy, sampler, batch=args.batch)
    steer.reset(seed=args.seed)
    maze: Any = env.unwrapped
    user = SketchUser(maze, seed=args.seed)
    drawn = user.draw(maze.state, kind="through" if args.through_wall else None)
    try:
        _, _, _, _, info = steer.step(drawn.sketch)
    except TypeError as exc:  # BI/GD/SS need a diffusion policy (ACT has no denoiser to steer)
        print(exc, file=sys.stderr)
        return 2

    start = getattr(policy, "exec_start", 0)
    plans = info["plans"][:, start:]
    dist = sketch_distances(plans, drawn.sketch, scale=maze.extent)
    print(f"{args.policy.upper()}-{args.sampler}: sketch '{drawn.kind}' (through a wall: {drawn.collides})")
    print(
        f"  min L2 {dist[info['chosen']]:.3f}  avg L2 {dist.mean():.3f}  collision {info['plan_collides'].mean():.2f}"
    )
    executed = len(info["executed"])
    print(f"  {info['latency_ms']:.0f} ms per steering call (batch {args.batch}); executed {executed} waypoints")

    before = maze.render_overlay(drawn.sketch.points, plans)
    after = maze.render_overlay(drawn.sketch.points, plans[info["chosen"]][None])
    title = f"Maze2D-Large, {args.policy.upper()} steered with {args.sampler} (seed {args.seed})"
    fig = steering_figure(before, after, title)
    path = save_figure(fig, args.out / f"steer_{args.policy}_{args.sampler}_seed{args.seed}.png")
    print(f"wrote {path}")
    steer.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
