"""A stable-baselines3 agent as the "user": PPO drives SteeringWrapper by drawing sketches.

    python examples/sb3_steering.py --steps 32 --out runs/sb3_steering

``SteeringWrapper(..., sketch_points=8)`` turns Maze2D into an env whose action
is a flattened 8-point sketch (a ``Box``, which SB3 needs). Every agent step
the frozen Diffusion Policy samples a batch of plans, the sampler (default PR)
picks the one closest to the agent's sketch and its 63 waypoints run in the
MuJoCo maze; the reward is the maze's sparse goal reward. The script trains
PPO for a few steps (a smoke run, not a trained agent), then lets it steer a
short episode, prints what happened and saves the agent.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.baselines.pretrained import PRETRAINED_LOADER, add_policy_arguments, resolve_policy
from steer_envs.io import atomic_open
from steer_envs.steering import SAMPLERS, make_sampler
from steer_envs.utils.threads import add_threads_argument, set_process_threads
from steer_envs.wrappers import SteeringWrapper


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_policy_arguments(parser)
    parser.add_argument("--sampler", choices=tuple(SAMPLERS), default="PR", help="default: PR")
    parser.add_argument("--batch", type=int, default=8, help="plans per steering call (default: 8)")
    parser.add_argument("--steps", type=int, default=16, help="PPO training steps (default: 16)")
    parser.add_argument("--seed", type=int, default=0, help="seed of env, agent and sampling (default: 0)")
    parser.add_argument("--out", type=Path, default=Path("runs/sb3_steering"), help="output directory")
    add_threads_argument(parser)
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure

    args = parse_args(argv)
    set_process_threads(args.threads)
    if args.steps < 1 or args.batch < 1:
        print("--steps and --batch must be >= 1", file=sys.stderr)
        return 2
    try:
        policy = resolve_policy(args.loader or PRETRAINED_LOADER, args.policy, args.checkpoint)
    except (ImportError, AttributeError, FileNotFoundError, ValueError) as exc:
        print(f"the {args.policy} policy is not available ({type(exc).__name__}: {exc})", file=sys.stderr)
        return 2
    env = SteeringWrapper(
        gym.make("steer_envs/Maze2D-Large-v0"), policy, make_sampler(args.sampler), batch=args.batch, sketch_points=8
    )
    print(f"action space: {env.action_space} (a flattened 8-point sketch); observation space: {env.observation_space}")
    agent = PPO("MlpPolicy", env, n_steps=8, batch_size=8, n_epochs=1, seed=args.seed, verbose=0)
    # SB3's default logger makes an SB3-<date> folder in the temp dir on every run; log into --out instead
    agent.set_logger(configure(str(args.out / "sb3_log"), ["csv"]))
    agent.learn(total_timesteps=args.steps)

    obs, _ = env.reset(seed=args.seed)
    for step in range(4):
        action, _ = agent.predict(obs, deterministic=True)
        obs, reward, terminated, truncated, info = env.step(action)
        chosen = info["chosen"]
        print(
            f"step {step}: agent at {np.round(obs.astype(np.float64), 2).tolist()}, reward {reward:.0f}, "
            f"chosen plan {chosen} (cost {info['costs'][chosen]:.2f}), "
            f"{int(info['plan_collides'].sum())}/{len(info['plans'])} plans in collision, "
            f"{info['latency_ms']:.0f} ms"
        )
        if terminated or truncated:
            break
    path = args.out / "ppo_steering.zip"
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "wb") as fh:
        agent.save(fh)  # type: ignore[arg-type]  # a binary file object, as SB3 accepts
    print(f"saved the agent to {path}")
    env.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
