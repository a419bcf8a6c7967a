"""The tli-color-tracing figure: pushed episodes per replanning automaton on the ColorTracing tiles.

One column per automaton (a), (b), (c): the tiles and the dark region, the
first plotted experiment's pushed episodes (one colour each) and their pushes
(dashed arrows).

>>> plot_color_tracing(None, [], "unused")
[]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.plots import recorded_figures
from steer_envs.utils.plots import figure_legend, key_line, key_patch, new_figure, save_figure

__all__ = ["plot_color_tracing"]

_ORDER = ("a", "b", "c")
_TILE_COLOURS = {
    "yellow": "#ffdd57",
    "blue": "#5a8ce6",
    "green": "#6ebe6e",
    "orange": "#ffa046",
    "pink": "#ffa0c8",
    "red": "#d73232",
}
_DARK = "#464650"
_EPISODE_COLOURS = ("#00e5ff", "#b6ff00", "#ff4dff")
_RULES = {
    "a": "(a) every D re-enters at yellow",
    "b": "(b) after yellow: re-enter at blue",
    "c": "(c) yellow exit -> blue, blue exit -> pink",
}


def _scene(ax: Any) -> None:
    from matplotlib.patches import Rectangle

    from steer_envs.envs.color_tracing import RECTS, WORKSPACE_HALF_WIDTH

    w = WORKSPACE_HALF_WIDTH
    ax.add_patch(Rectangle((-w, -w), 2 * w, 2 * w, color=_DARK, zorder=0))
    for name, (x0, y0, x1, y1) in RECTS.items():
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, color=_TILE_COLOURS[name], zorder=1))
        ax.text((x0 + x1) / 2, y0 - 0.6, name[0].upper(), ha="center", va="top", fontsize=7, color="white")
    ax.set_xlim(-w, w)
    ax.set_ylim(-w, w)
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")


def plot_color_tracing(suite: Any, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """One PNG: columns are automata, the first plotted seed's pushed episodes; returns its path."""
    cells: dict[str, Any] = {}
    seeds: dict[str, int] = {}
    for (seed, method), fig_data in sorted(recorded_figures(records).items(), key=lambda cell: cell[0][0]):
        if method not in cells:  # its lowest recorded seed
            cells[method], seeds[method] = fig_data, seed
    methods = [m for m in _ORDER if m in cells]
    if not methods:
        return []
    fig = new_figure(3.4 * len(methods), 4.2)
    axes = fig.subplots(1, len(methods), squeeze=False)[0]
    n_shown = 0
    for ax, method in zip(axes, methods, strict=True):
        _scene(ax)
        episodes = cells[method]["push"]
        n_shown = max(n_shown, len(episodes))
        for k, ep in enumerate(episodes):
            colour = _EPISODE_COLOURS[k % len(_EPISODE_COLOURS)]
            for seg in ep["trace"]:
                s = np.asarray(seg).reshape(-1, 2)
                ax.plot(s[:, 0], s[:, 1], color=colour, linewidth=0.9, zorder=3)
            for push in ep["pushes"]:
                a, b = np.asarray(push["from"]), np.asarray(push["to"])
                ax.annotate("", xy=b, xytext=a, zorder=4,
                            arrowprops={"arrowstyle": "->", "color": colour, "linestyle": "--", "lw": 0.9})  # fmt: skip
        ok = sum(bool(ep["success"]) for ep in episodes)
        ax.set_title(f"{_RULES[method]}\n{ok}/{len(episodes)} pushed episodes reached red", fontsize=8)
    handles = [
        key_line(f"episode {k + 1}", color=_EPISODE_COLOURS[k % len(_EPISODE_COLOURS)], lw=1.5) for k in range(n_shown)
    ]
    handles += [
        key_line("push into D", color="black", ls="--", lw=1.0),
        key_patch("dark region D (D1..D4 by the tile left)", facecolor=_DARK),
    ]
    figure_legend(fig, handles, ncol=3)
    name = getattr(suite, "name", "tli-color-tracing")
    seed = min(seeds.values())
    fig.suptitle(f"{name}: one demonstration, three replanning automata (experiment {seed})", fontsize=9)
    return [str(save_figure(fig, Path(out_dir) / f"{name}_rollouts.png"))]
