"""Tour of the 2D mode environments: run each scripted expert, push it once, save a picture.

    python examples/envs_tour.py --out runs/tour

Writes one PNG per env (regions coloured by mode, the expert's trail in blue,
the agent in red) and prints the mode sequence each expert went through.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
from matplotlib.image import imsave

import steer_envs
from steer_envs.data.experts import make_expert
from steer_envs.io import atomic_open


def run_episode(env_id: str, seed: int, push_at: int = 30) -> tuple[np.ndarray, list[str], bool]:
    """One expert episode with a single random push; returns the last frame, modes, success."""
    env = gym.make(env_id, render_mode="rgb_array")
    expert = make_expert(env)
    obs, info = env.reset(seed=seed)
    expert.reset(obs, info)
    modes = [info["mode_name"]]
    rng = np.random.default_rng(seed)
    for t in itertools.count():
        if t == push_at:
            span = env.unwrapped.model.high - env.unwrapped.model.low
            info = env.unwrapped.perturb(delta=rng.normal(0.0, 0.05, size=2) * span)
            obs = env.unwrapped.state.astype(np.float32)
        obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
        if info["mode_name"] != modes[-1]:
            modes.append(info["mode_name"])
        if terminated or truncated:
            break
    frame = env.render()
    env.close()
    return frame, modes, bool(info["success"])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("runs/tour"), help="output directory for PNGs")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for env_id in steer_envs.env_ids(kinematic_only=True):
        frame, modes, success = run_episode(env_id, args.seed)
        name = env_id.split("/")[1]
        with atomic_open(args.out / f"{name}.png") as fh:
            imsave(fh, frame, format="png")
        print(f"{env_id:32s} success={success!s:5s} modes: {' -> '.join(modes)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
