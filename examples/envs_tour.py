"""Tour of the 2D mode environments: run each scripted expert, push it once, save a picture.

    python examples/envs_tour.py --out runs/tour

Writes one PNG per env (regions coloured by mode, the expert's trail in blue,
the agent in red, the push as a black arrow; the title names the env, the
outcome and the modes the expert went through, a legend the marks) and prints
the mode sequence each expert went through.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import steer_envs
from steer_envs.data.experts import make_expert
from steer_envs.utils.plots import figure_legend, key_line, key_patch, new_figure, save_figure


@dataclass
class Episode:
    """What one tour episode shows: the last frame, the push (from, to), the visited modes, success."""

    frame: np.ndarray
    low: np.ndarray
    high: np.ndarray
    push: tuple[np.ndarray, np.ndarray] | None
    modes: list[str]
    success: bool


def run_episode(env_id: str, seed: int, push_at: int = 30) -> Episode:
    """One expert episode with a single random push at step ``push_at``."""
    env = gym.make(env_id, render_mode="rgb_array")
    expert = make_expert(env)
    obs, info = env.reset(seed=seed)
    expert.reset(obs, info)
    task = env.unwrapped.task  # type: ignore[attr-defined]
    labels = dict(zip(task.modes, getattr(task, "labels", ()) or task.modes, strict=True))

    def named(mode: str) -> str:
        """The mode's descriptive label, with the thesis's name when it differs: ``scoop (b)``."""
        label = labels.get(mode, mode)
        return mode if label == mode else f"{label} ({mode})"

    modes = [named(info["mode_name"])]
    rng = np.random.default_rng(seed)
    model = env.unwrapped.model  # type: ignore[attr-defined]
    push = None
    for t in itertools.count():
        if t == push_at:
            span = model.high - model.low
            before = env.unwrapped.state.copy()  # type: ignore[attr-defined]
            info = env.unwrapped.perturb(delta=rng.normal(0.0, 0.05, size=2) * span)  # type: ignore[attr-defined]
            obs = env.unwrapped.state.astype(np.float32)  # type: ignore[attr-defined]
            push = (np.asarray(before[:2], dtype=np.float64), np.asarray(obs[:2], dtype=np.float64))
        obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
        if named(info["mode_name"]) != modes[-1]:
            modes.append(named(info["mode_name"]))
        if terminated or truncated:
            break
    frame = env.render()
    env.close()
    assert frame is not None
    low, high = np.asarray(model.low, dtype=np.float64), np.asarray(model.high, dtype=np.float64)
    return Episode(np.asarray(frame), low, high, push, modes, bool(info["success"]))


def tour_figure(env_id: str, episode: Episode) -> Any:
    """The episode's last frame in world coordinates, with a title (env, outcome, modes), the push and a legend."""
    fig = new_figure(5.4, 6.6)
    ax = fig.add_subplot()
    extent = (episode.low[0], episode.high[0], episode.low[1], episode.high[1])
    ax.imshow(episode.frame, extent=extent)  # the renderer draws y up, row 0 at the top: world coordinates
    handles = [
        key_line("expert's path", color=(40 / 255, 40 / 255, 200 / 255), lw=2),
        key_line("agent (end)", color=(220 / 255, 30 / 255, 30 / 255), marker="o", ls="none"),
    ]
    if episode.push is not None:
        (x0, y0), (x1, y1) = episode.push
        arrow = {"arrowstyle": "-|>", "color": "black", "lw": 1.8, "mutation_scale": 16, "shrinkA": 0, "shrinkB": 0}
        ax.annotate("", (x1, y1), (x0, y0), arrowprops=arrow, zorder=5)
        ax.plot([x0], [y0], "x", color="black", markersize=8, mew=2, zorder=5)
        ax.annotate(
            "push", (x0, y0), xytext=(8, 8), textcoords="offset points", fontsize=8, zorder=5,
            bbox={"boxstyle": "round,pad=0.2", "facecolor": "white", "alpha": 0.8},
        )  # fmt: skip
        handles.append(key_line("push (from x, along the arrow)", color="black", marker="x", lw=1.8))
    handles.append(key_patch("background: the env's mode regions", facecolor="0.85", edgecolor="0.5"))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    modes = " -> ".join(episode.modes)
    name = env_id.split("/")[-1]
    modes = "\n".join(textwrap.wrap(f"modes: {modes}", 70))
    fig.suptitle(f"{name}: {'success' if episode.success else 'no success'}", fontsize=10)
    ax.set_title(modes, fontsize=8)
    figure_legend(fig, handles, ncol=2, fontsize=8)
    return fig


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("runs/tour"), help="output directory for PNGs")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for env_id in steer_envs.env_ids(kinematic_only=True):
        episode = run_episode(env_id, args.seed)
        name = env_id.split("/")[1]
        save_figure(tour_figure(env_id, episode), args.out / f"{name}.png")
        print(f"{env_id:32s} success={episode.success!s:5s} modes: {' -> '.join(episode.modes)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
