"""SAC with stable-baselines3's defaults on a dense id as registered, from any seed: train, then evaluate.

    python examples/rl_any_seed.py --seed 11 --steps 100000

What a new RL user would write: ``gymnasium.make`` the id with no options
(the ``...Dense-v0`` ids register what RL needs: the shaped reward, the task's
sensor bits in the observation, ``[-1, 1]`` actions), ``SAC("MlpPolicy", env,
seed=SEED)`` with every default, ``learn`` for the printed budget, then
``--episodes`` deterministic episodes on reset seeds ``1_000_000 + i``, which
no training episode starts from (the training env's first reset is seeded
with ``--seed``, below 1_000_000; its later episodes continue that env's
generator). Success is ``info["is_success"]`` at the episode's end. Needs the
``rl`` extra (``pip install "steer-envs[rl]"``); 100k steps take tens of
minutes on one CPU thread.
"""

from __future__ import annotations

import argparse
import sys

import gymnasium as gym

import steer_envs
from steer_envs.utils.threads import add_threads_argument, set_process_threads

#: evaluation episode ``i`` starts from ``reset(seed=EVAL_SEED_OFFSET + i)``; training seeds stay below it
EVAL_SEED_OFFSET = 1_000_000
DEFAULT_ENV = "steer_envs/PolygonNav-3ModeDense-v0"
DEFAULT_STEPS = 100_000


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an int, got {text!r}") from None


def _at_least_one(text: str) -> int:
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def _training_seed(text: str) -> int:
    value = _int(text)
    if not 0 <= value < EVAL_SEED_OFFSET:
        raise argparse.ArgumentTypeError(
            f"must be in [0, {EVAL_SEED_OFFSET}) (the evaluation seeds' range), got {value}"
        )
    return value


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    dense = [i for i in steer_envs.env_ids(variants=True) if i.endswith("Dense-v0") and not i.endswith("GoalDense-v0")]
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", choices=dense, default=DEFAULT_ENV, metavar="ID", help=f"default: {DEFAULT_ENV}")
    parser.add_argument(
        "--seed", type=_training_seed, default=0, help="seed of the agent and training env (default: 0)"
    )
    parser.add_argument(
        "--steps", type=_at_least_one, default=DEFAULT_STEPS, help=f"training steps (default: {DEFAULT_STEPS})"
    )
    parser.add_argument("--episodes", type=_at_least_one, default=20, help="evaluation episodes (default: 20)")
    add_threads_argument(parser)
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        from stable_baselines3 import SAC
    except ImportError:
        print('this example needs stable-baselines3: pip install "steer-envs[rl]"', file=sys.stderr)
        return 1
    set_process_threads(args.threads)

    env = gym.make(args.env)  # as registered: no options
    print(f"{args.env}: observation {env.observation_space}, action {env.action_space}")
    print(f"training SAC (SB3 defaults), seed {args.seed}, budget {args.steps} steps")
    agent = SAC("MlpPolicy", env, seed=args.seed, verbose=0)
    agent.learn(total_timesteps=args.steps)

    evaluation = gym.make(args.env)
    successes = 0
    for i in range(args.episodes):
        obs, info = evaluation.reset(seed=EVAL_SEED_OFFSET + i)
        terminated = truncated = False
        while not (terminated or truncated):
            action, _ = agent.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = evaluation.step(action)
        successes += bool(info["is_success"])
    rate = 100.0 * successes / args.episodes
    print(
        f"success rate {rate:.0f} % ({successes}/{args.episodes} deterministic episodes, reset seeds "
        f"{EVAL_SEED_OFFSET}..{EVAL_SEED_OFFSET + args.episodes - 1}) after {args.steps} steps"
    )
    env.close()
    evaluation.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
