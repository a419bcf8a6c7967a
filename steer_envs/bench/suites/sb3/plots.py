"""The ``sb3`` learning curves: success rate against training steps, one line per env, a panel per method.

Each line is the mean over the seeds of a cell (the curves of a cell share
their evaluation steps; a seed stopped early or cut short ends its line where
fewer seeds remain). The 80 % target is a dashed line.

>>> from steer_envs.bench.suite import get_suite
>>> plot_learning_curves(get_suite("sb3"), [], "unused", methods=("sac",), target=80.0)  # no records: nothing
[]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.suite import Suite
from steer_envs.utils.plots import figure_legend, key_line, new_figure, save_figure

__all__ = ["learning_curves", "plot_learning_curves"]

_TITLES = {"sac": "SAC, SB3 defaults (dense envs)", "sac-her": "SAC + HER (goal-conditioned Maze2D)"}


def learning_curves(records: Sequence[Mapping[str, Any]]) -> dict[str, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """``{method: {env: (steps, mean success %)}}`` from the records' stored curves.

    >>> rec = {"config": {"env": "steer_envs/A-v0", "method": "sac"}, "extra": {"curve": [[0, 0.0], [10, 50.0]]}}
    >>> learning_curves([rec])["sac"]["steer_envs/A-v0"][1].tolist()
    [0.0, 50.0]
    """
    per_cell: dict[tuple[str, str], dict[int, list[float]]] = {}
    for rec in records:
        curve = (rec.get("extra") or {}).get("curve")
        if not curve:
            continue
        cell = per_cell.setdefault((str(rec["config"]["method"]), str(rec["config"]["env"])), {})
        for step, success in curve:
            cell.setdefault(int(step), []).append(float(success))
    out: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {}
    for (method, env), points in per_cell.items():
        steps = np.array(sorted(points), dtype=np.int64)
        means = np.array([np.mean(points[int(s)]) for s in steps])
        out.setdefault(method, {})[env] = (steps, means)
    return out


def plot_learning_curves(
    suite: Suite,
    records: Sequence[Mapping[str, Any]],
    out_dir: str,
    *,
    methods: Sequence[str] | None = None,
    target: float | None = None,
) -> list[str]:
    """Write ``<suite>_learning_curves.png`` (nothing without stored curves): ``methods`` first, ``target`` dashed.

    ``methods`` defaults to the suite's, ``target`` to the goal of its ``success`` metric.
    """
    curves = learning_curves(records)
    order = [m for m in suite.method_list() if m is not None] if methods is None else methods
    if target is None:
        target = suite.metric("success").goal or 0.0
    methods = [m for m in order if m in curves] + sorted(set(curves) - set(order))
    if not methods:
        return []
    from matplotlib import colormaps

    fig = new_figure(6.0 * len(methods) + 1.0, 4.8)
    axes = fig.subplots(1, len(methods), squeeze=False)[0]
    envs = sorted({env for m in methods for env in curves[m]})
    colours = colormaps["tab20"].resampled(max(len(envs), 2))
    handles = []
    for ax, method in zip(axes, methods, strict=True):
        for env, (steps, means) in sorted(curves[method].items()):
            colour = colours(envs.index(env))
            ax.plot(steps / 1000.0, means, "o-", ms=3, lw=1.5, color=colour)
            label = f"{env.split('/')[-1]} ({method})"
            handles.append(key_line(label, color=colour, marker="o", ms=3, lw=1.5))
        ax.axhline(target, color="black", ls="--", lw=1)
        ax.set_ylim(-3, 103)
        ax.set_xlabel("training steps (thousands)")
        ax.set_ylabel("success rate (%, deterministic evaluation)")
        ax.set_title(_TITLES.get(method, method), fontsize=10)
        ax.grid(alpha=0.3)
    handles.append(key_line(f"target {target:.0f} %", color="black", ls="--", lw=1))
    fig.suptitle(f"{suite.name}: success rate vs training steps (mean over seeds)")
    figure_legend(fig, handles, ncol=3, fontsize=8)
    return [str(save_figure(fig, Path(out_dir) / f"{suite.name}_learning_curves.png"))]
