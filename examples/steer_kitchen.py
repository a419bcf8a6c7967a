"""Steer the Kitchen skill policy by clicking pixels: pixel -> depth -> 3D point -> steered plan -> executed skill.

    python examples/steer_kitchen.py --pixel 117 151 --method DP-SS --out runs/steer_kitchen

Each ``--pixel U V`` (column, row of the 256 x 256 scene camera frame; give it
again for the next skill) is one click: its 3D point comes from the depth
buffer (``env.pixel_to_world``) and is read as the legal skill whose target is
nearest (for the aligned / misaligned verdict), the Kitchen Diffusion Policy samples a batch of
whole-skill plans steered toward it (``--method``: the methods of
:mod:`steer_envs.steering.kitchen`; OP pushes the end effector toward the point instead), and the chosen
plan runs on the arm. Without ``--pixel`` the simulated user
(:class:`~steer_envs.users.kitchen_clicker.KitchenClickUser`) clicks, for
``--max-skills`` skills, the target of a legal skill other than the one it
watched the policy sample. The strip under ``--out`` shows the scene before each
skill with the click (red ring) and the run plan projected, and the end.
Exit 2 on a usage error or a missing policy.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.steering.kitchen import METHODS

#: the scene camera's frame size (the pixels' range)
FRAME = 256


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (argparse exits 2 on a usage error)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--pixel",
        nargs=2,
        type=float,
        action="append",
        metavar=("U", "V"),
        help=f"a click: column U and row V in [0, {FRAME}) of the scene camera (repeat for later skills)",
    )
    parser.add_argument("--method", choices=METHODS, default="DP-SS", help="steering method (default DP-SS)")
    parser.add_argument("--task", choices=("microwave", "sink", "clean"), default="microwave", help="the env's task")
    parser.add_argument("--batch", type=int, default=16, help="plans per sampling call (default 16)")
    parser.add_argument("--seed", type=int, default=0, help="scene, user and noise seed (default 0)")
    parser.add_argument("--max-skills", type=int, default=2, help="skills the simulated user steers without --pixel")
    parser.add_argument("--checkpoint", default="", help="a Kitchen DP checkpoint (default: the shipped one)")
    parser.add_argument("--out", type=Path, default=Path("runs/steer_kitchen"), help="output directory")
    args = parser.parse_args(argv)
    for u, v in args.pixel or ():
        if not (0 <= u < FRAME and 0 <= v < FRAME):
            parser.error(f"--pixel must lie in [0, {FRAME}) x [0, {FRAME}), got {u:g} {v:g}")
    for name in ("batch", "max_skills"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    if args.seed < 0:
        parser.error(f"--seed must be >= 0, got {args.seed}")
    return args


def _meant(env: object, point: np.ndarray) -> str | None:
    """The legal skill whose target centre is nearest a clicked point: what the click is read as."""
    from steer_envs.envs.robosuite.kitchen import legal_skills
    from steer_envs.users.kitchen_clicker import skill_centre

    legal = legal_skills(env.task.modes[env._mode])  # type: ignore[attr-defined]
    if not legal:
        return None
    return min(legal, key=lambda s: float(np.linalg.norm(skill_centre(env, s) - point)))


def _click(env: Any, user: Any, pixel: tuple[float, float] | None, watched: str | None) -> Any:
    """``((u, v), 3D point, intended skill)`` of a given pixel, or the simulated user's click (None: no click)."""
    if pixel is None:
        click = user.act(env, watched)
        return None if click is None else (click.pixel, click.point, click.skill)
    u, v = pixel
    point = env.pixel_to_world(u, v)
    return (u, v), point, _meant(env, point)


def main(argv: list[str] | None = None) -> int:
    """Run the clicks, print each skill, save the strip; 0 on success, 2 without a policy."""
    args = parse_args(argv)
    from steer_envs.baselines.pretrained import POLICY_UNAVAILABLE, load_pretrained
    from steer_envs.control.kitchen import classify_kitchen_plan, execute_kitchen_plan
    from steer_envs.steering import RandomSampling
    from steer_envs.steering.figures import rollout_strip
    from steer_envs.steering.kitchen import make_env, make_method_sampler, steered_plan
    from steer_envs.users.kitchen_clicker import KitchenClickUser

    try:
        policy = load_pretrained("kitchen", checkpoint=args.checkpoint or None)
    except (ValueError, *POLICY_UNAVAILABLE) as exc:  # a missing or bad checkpoint file
        print(f"the Kitchen policy is not available ({type(exc).__name__}: {exc})", file=sys.stderr)
        return 2
    env = make_env(args.task)
    try:
        obs, _ = env.reset(seed=args.seed)
        user = KitchenClickUser(args.seed)
        sampler = make_method_sampler(args.method)
        clicks = [tuple(p) for p in args.pixel] if args.pixel else [None] * args.max_skills
        frames: list[dict[str, object]] = []
        for k, pixel in enumerate(clicks):
            rng = np.random.default_rng([args.seed, k])
            watched = classify_kitchen_plan(env, RandomSampling()(policy, obs, None, args.batch, generator=rng).plan)
            target = _click(env, user, pixel, watched)
            if target is None:
                print(f"skill {k + 1}: no legal skill other than the watched {watched}; stopping")
                break
            (u, v), point, intended = target
            image = env.render()
            plan, obs, ms = steered_plan(env, policy, obs, args.method, point, sampler, args.batch, rng)
            planned = classify_kitchen_plan(env, plan)
            outcome = execute_kitchen_plan(env, plan)
            obs = outcome.obs
            aligned = planned == intended
            print(
                f"skill {k + 1}: click ({u:g}, {v:g}) -> point {np.round(point, 3).tolist()}; watched "
                f"{watched or 'nothing'}, wanted {intended or 'nothing'}; plan does {planned or 'nothing'}, "
                f"executed {outcome.executed or 'nothing'} ({'ok' if outcome.success else 'failed'}, {ms:.0f} ms)"
            )
            frames.append(
                {
                    "image": image,
                    "pixel": (u, v),
                    "plan_uv": [env.world_to_pixel(p)[:2] for p in plan[:, :3]],
                    "grip": plan[:, 4],
                    "watched": watched,
                    "intended": intended or "none",
                    "planned": planned,
                    "aligned": aligned,
                    "success": outcome.success,
                }
            )
            if not outcome.success:
                break
        goal = env.task.modes[env._mode] in env.task.goal
        frames.append({"image": env.render(), "end": True, "goal": goal})
        title = f"Kitchen ({args.task}) steered by clicks: {args.method}, seed {args.seed}"
        path = rollout_strip(frames, args.out / f"steer_kitchen_{args.method}_seed{args.seed}.png", title)
        print(f"wrote {path}")
    finally:
        env.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
