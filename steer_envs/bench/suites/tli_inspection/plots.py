"""The tli-inspection figure: pushed episodes per method on the InspectionLine layout.

>>> plot_inspection(None, [], "unused")
[]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.plots import recorded_figures
from steer_envs.utils.plots import new_figure, save_figure

__all__ = ["plot_inspection"]

_COLOURS = {"track": "#9aa9c9", "entry": "#3b6fd1", "release": "#7ac57a"}


def plot_inspection(suite: Any, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """One PNG: columns are methods, the first plotted seed's pushed episodes overlaid; returns its path."""
    from matplotlib.patches import Rectangle

    from steer_envs.envs.inspection_line import RECTS

    cells: dict[str, Any] = {}
    for (_, method), fig_data in recorded_figures(records).items():
        cells.setdefault(method, fig_data)  # the first recorded
    if not cells:
        return []
    methods = [m for m in ("vanilla-ds", "ltl-ds", "ltl-ds+mod") if m in cells]
    fig = new_figure(3.6 * len(methods), 3.8)
    axes = fig.subplots(1, len(methods), squeeze=False)[0]
    for ax, method in zip(axes, methods, strict=True):
        for name in ("track", "entry", "release"):
            x0, y0, x1, y1 = RECTS[name]
            ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, color=_COLOURS[name], alpha=0.7, label=name))
        eps = cells[method]["episodes"]
        for k, ep in enumerate(eps):
            colour = "black" if ep["success"] else "#d62728"
            for seg in ep["trace"]:
                s = np.asarray(seg).reshape(-1, 2)
                ax.plot(s[:, 0], s[:, 1], color=colour, linewidth=0.8,
                        label=("success" if ep["success"] else "failed") if k == 0 else None)  # fmt: skip
            for push in ep["pushes"]:
                a, b = np.asarray(push["from"]), np.asarray(push["to"])
                ax.plot([a[0], b[0]], [a[1], b[1]], color="#ff8c00", linestyle="--", linewidth=0.9,
                        label="push" if k == 0 else None)  # fmt: skip
        ok = sum(ep["success"] for ep in eps)
        ax.set_title(f"{method}: {ok}/{len(eps)} inspected and released", fontsize=8)
        ax.set_xlim(-8, 8)
        ax.set_ylim(-8, 8)
        ax.set_aspect("equal")
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        ax.legend(fontsize=6, loc="upper left")
    name = getattr(suite, "name", "tli-inspection")
    fig.suptitle(f"{name}: pushed episodes (black: inspected and released, red: not)", fontsize=9)
    return [str(save_figure(fig, Path(out_dir) / f"{name}_rollouts.png"))]
