"""Build a chosen 4-block tower by sketching: 3D sketch -> steered skill plans -> executed skill -> picture strip.

    python examples/steer_blockstack.py --order 2,0,3,1 --method DP-GD-I50 --out runs/steer_blockstack

A simulated user (:class:`~steer_envs.users.block_sketcher.TowerSketchUser`)
wants the tower ``--order`` (cube ids bottom to top: 0 red, 1 green, 2 blue,
3 yellow). At every skill it sketches in 3D from the end effector toward the
cube to pick or the spot to place on; the committed BlockStack Diffusion
Policy samples a batch of whole-skill plans steered by the sketch (``--method``:
the methods of :mod:`steer_envs.steering.blockstack`), and the picked plan is executed in
robosuite. Each step of the strip shows the scene before the skill with the
sketch (magenta) and the picked plan (cyan aligned / orange not) projected
into the camera. A plan is *aligned* when it heads for the intended cube or
tower (the thesis's definition, the suite's ``TA``); the script also prints
which skill the plan's shape performs (the stricter ``TA_skill``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.baselines.pretrained import POLICY_UNAVAILABLE, load_pretrained
from steer_envs.control.blockstack import classify_plan, execute_plan, plan_target, yaw_of
from steer_envs.envs.robosuite.blockstack import BlockStackEnv
from steer_envs.steering.blockstack import METHOD_SAMPLERS, make_method_sampler, tower_stands
from steer_envs.users.block_sketcher import TowerSketchUser
from steer_envs.utils.plots import figure_legend, key_line, new_figure, save_figure
from steer_envs.utils.threads import add_threads_argument, set_process_threads


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--order", default="0,1,2,3", help="the tower, cube ids bottom to top (default 0,1,2,3)")
    parser.add_argument(
        "--method", choices=sorted(METHOD_SAMPLERS), default="DP-GD-I50", help="steering method (default DP-GD-I50)"
    )
    parser.add_argument("--batch", type=int, default=32, help="plans per steering call (default 32)")
    parser.add_argument("--seed", type=int, default=0, help="scene, user and noise seed (default 0)")
    parser.add_argument("--max-skills", type=int, default=8, help="most skills to try (default 8; a tower takes 6)")
    parser.add_argument("--checkpoint", default="", help="a BlockStack DP checkpoint (default: the shipped one)")
    parser.add_argument("--out", type=Path, default=Path("runs/steer_blockstack"), help="output directory")
    add_threads_argument(parser)
    args = parser.parse_args(argv)
    try:
        order = tuple(int(c) for c in args.order.split(","))
    except ValueError:
        parser.error(f"--order must be 4 comma-separated cube ids, got {args.order!r}")
    if sorted(order) != [0, 1, 2, 3]:
        parser.error(f"--order must name each of the cubes 0-3 once, got {args.order!r}")
    args.order = order
    for name in ("batch", "max_skills"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    return args


def _overlay(ax: object, env: BlockStackEnv, points: np.ndarray, **style: object) -> None:
    uv = np.array([env.world_to_pixel(p) for p in points])
    ax.plot(uv[:, 0], uv[:, 1], **style)  # type: ignore[attr-defined]


def _strip(
    env: BlockStackEnv,
    frames: list[tuple[np.ndarray, np.ndarray, np.ndarray, str, bool]],
    final: np.ndarray,
    built: bool,
    title: str,
) -> Any:
    """One panel per skill (the scene, the sketch and the picked plan projected), then the end."""
    cols = len(frames) + 1
    fig = new_figure(max(2.3 * cols, 6.0), 3.1)
    axes = fig.subplots(1, cols, squeeze=False)[0]
    for ax, (image, sketch_points, plan, name, aligned) in zip(axes, frames, strict=False):
        ax.imshow(image)
        _overlay(ax, env, sketch_points, color="magenta", linewidth=2)
        _overlay(ax, env, plan, color="cyan" if aligned else "orange", linewidth=1.5)
        ax.set_title(f"{name}\n{'aligned' if aligned else 'misaligned'}", fontsize=8)
        ax.axis("off")
    axes[-1].imshow(final)
    axes[-1].set_title(f"end: tower {'built' if built else 'not built'}", fontsize=8)
    axes[-1].axis("off")
    fig.suptitle(title, fontsize=10)
    figure_legend(
        fig,
        [
            key_line("user sketch", color="magenta", lw=2),
            key_line("steered plan, aligned", color="cyan", lw=1.5),
            key_line("steered plan, misaligned", color="orange", lw=1.5),
        ],
        ncol=3,
    )
    return fig


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    set_process_threads(args.threads)
    try:
        policy = load_pretrained("blockstack", checkpoint=args.checkpoint or None)
    except (ValueError, *POLICY_UNAVAILABLE) as exc:  # a missing or bad checkpoint file
        print(f"the BlockStack policy is not available ({type(exc).__name__}: {exc})", file=sys.stderr)
        return 2
    sampler = make_method_sampler(args.method)
    env = BlockStackEnv(render_mode="rgb_array", fast_render=True, render_size=256)
    obs, _ = env.reset(seed=args.seed)
    home_yaw = yaw_of(env.robosuite_obs["robot0_eef_quat"])
    user = TowerSketchUser(args.order, seed=args.seed)
    frames: list[tuple[np.ndarray, np.ndarray, np.ndarray, str, bool]] = []
    aligned_count = skill_count = 0
    for k in range(args.max_skills):
        if tower_stands(env, args.order):
            break
        skill = user.intended_skill(env)
        sketch = user.sketch(env, skill)
        image = env.render()
        result = sampler(policy, obs, sketch, args.batch, generator=np.random.default_rng([args.seed, k]))
        planned = classify_plan(env, result.plan)
        target = plan_target(env, result.plan)
        outcome = execute_plan(env, result.plan, home_yaw=home_yaw)
        obs = outcome.obs
        aligned = target == skill.name
        aligned_count += aligned
        skill_count += planned == skill.name
        print(
            f"skill {k + 1}: wanted {skill.name:<18} plan heads for {target:<18} does {planned or 'nothing':<18} "
            f"executed {outcome.executed or 'nothing':<18} ({result.timings['total_ms']:.0f} ms to steer)"
        )
        assert image is not None
        frames.append((image, sketch.points, result.plan[:, :3], skill.name, aligned))
    built = tower_stands(env, args.order)
    print(
        f"{args.method}: {aligned_count}/{len(frames)} plans aligned, {skill_count} of them the intended skill; "
        f"tower {args.order} built: {built}"
    )
    final = env.render()
    assert final is not None
    title = f"BlockStack, tower {args.order} by sketching ({args.method}, seed {args.seed})"
    fig = _strip(env, frames, final, built, title)
    path = save_figure(fig, args.out / f"steer_blockstack_{args.method}_seed{args.seed}.png")
    print(f"wrote {path}")
    env.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
