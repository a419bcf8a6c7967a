"""The tli-cooking figure, like the thesis's generalization figure (c)-(f): one column per edited automaton.

Rows: the first episode without pushes and the first with pushes of a plotted
experiment; the Cooking regions (white, yellow chicken corridor, green
broccoli corridor, dark pot), the rollout (black), pushes (red dashed), the
skills' attractors (orange).

>>> plot_cooking(None, [], "unused")
[]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.plots import recorded_figures
from steer_envs.utils.plots import figure_legend, new_figure, save_figure

__all__ = ["plot_cooking"]

_ORDER = ("phi_cb", "phi_bc", "phi_c", "phi_cc")
_COLOURS = {"yellow": "#f2d94e", "green": "#7ac57a", "dark": "#555555"}


def _regions(ax: Any) -> None:
    from matplotlib.patches import Rectangle

    from steer_envs.envs.cooking import RECTS

    for name, (x0, y0, x1, y1) in RECTS.items():
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, color=_COLOURS[name], alpha=0.6, zorder=1))
    ax.set_xlim(-8, 8)
    ax.set_ylim(-8, 8)
    ax.set_aspect("equal")


def plot_cooking(suite: Any, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """One PNG per plotted experiment seed; returns the paths."""
    by_seed: dict[int, dict[str, Mapping[str, Any]]] = {}
    for (seed, method), fig_data in recorded_figures(records).items():
        by_seed.setdefault(seed, {})[method] = fig_data
    name = getattr(suite, "name", "tli-cooking")
    paths = []
    for seed, cells in sorted(by_seed.items()):
        methods = [m for m in _ORDER if m in cells]
        fig = new_figure(3.0 * len(methods), 6.4)
        axes = fig.subplots(2, len(methods), squeeze=False)
        for j, method in enumerate(methods):
            data = cells[method]
            for i, cond in enumerate(("clean", "push")):
                ax = axes[i][j]
                _regions(ax)
                ep = data[cond]
                for seg in ep["trace"]:
                    s = np.asarray(seg).reshape(-1, 2)
                    ax.plot(s[:, 0], s[:, 1], color="black", linewidth=0.9, zorder=3, label="rollout")
                for push in ep["pushes"]:
                    a, b = np.asarray(push["from"]), np.asarray(push["to"])
                    ax.plot([a[0], b[0]], [a[1], b[1]], color="#d62728", linestyle="--", linewidth=1.0, zorder=4,
                            label="push")  # fmt: skip
                att = np.asarray(list(data["attractors"].values())).reshape(-1, 2)
                ax.plot(att[:, 0], att[:, 1], "o", color="#ff8c00", markersize=4, zorder=5, label="skill attractors")
                verdict = "success" if ep["success"] else "FAILED"
                cond_label = "no pushes" if cond == "clean" else "random pushes"
                ax.set_title(f"{method}, {cond_label}: {verdict}\n{' '.join(ep['mode_path'])[:60]}", fontsize=7)
                ax.set_xlabel("x")
                ax.set_ylabel("y")
        handles, labels = axes[1][0].get_legend_handles_labels()
        unique = dict(zip(labels, handles, strict=True))
        figure_legend(fig, list(unique.values()), ncol=3)
        fig.suptitle(f"{name}: one skill set, four edited automata (experiment {seed})", fontsize=9)
        paths.append(str(save_figure(fig, Path(out_dir) / f"{name}_rollouts_seed{seed}.png")))
    return paths
