"""The ``sb3`` learning curves: success rate against training steps, a panel per env, a colour per method.

Each line is the mean over the seeds of a cell and its band spans the lowest
to the highest seed at each evaluated step (the curves of a cell share their
evaluation steps; a seed stopped early or cut short ends where fewer seeds
remain, and the panel title gives the most seeds of the env). The 80 %
target is a dashed line.

>>> from steer_envs.bench.suite import get_suite
>>> plot_learning_curves(get_suite("sb3"), [], "unused", methods=("sac",), target=80.0)  # no records: nothing
[]
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from steer_envs.bench.suite import Suite
from steer_envs.utils.plots import figure_legend, key_line, key_patch, new_figure, save_figure

__all__ = ["SeedCurve", "learning_curves", "plot_learning_curves"]

#: one colour per method, the same in every panel
_COLOURS = {"sac": "tab:blue", "ppo": "tab:orange", "sac-her": "tab:green"}
_LABELS = {"sac": "SAC (SB3 defaults)", "ppo": "PPO (SB3 defaults)", "sac-her": "SAC + HER"}
_COLUMNS = 4


class SeedCurve(NamedTuple):
    """A cell's curves over its seeds: the evaluated ``steps``, the ``mean``, ``low`` and ``high`` success (%)
    at each, and the number of ``seeds`` measured there."""

    steps: np.ndarray
    mean: np.ndarray
    low: np.ndarray
    high: np.ndarray
    seeds: np.ndarray


def learning_curves(records: Sequence[Mapping[str, Any]]) -> dict[str, dict[str, SeedCurve]]:
    """``{method: {env: SeedCurve}}`` from the records' stored curves.

    >>> rec = {"config": {"env": "steer_envs/A-v0", "method": "sac"}, "extra": {"curve": [[0, 0.0], [10, 50.0]]}}
    >>> other = {"config": {"env": "steer_envs/A-v0", "method": "sac"}, "extra": {"curve": [[0, 10.0], [10, 90.0]]}}
    >>> curve = learning_curves([rec, other])["sac"]["steer_envs/A-v0"]
    >>> curve.mean.tolist(), curve.low.tolist(), curve.high.tolist(), curve.seeds.tolist()
    ([5.0, 70.0], [0.0, 50.0], [10.0, 90.0], [2, 2])
    """
    per_cell: dict[tuple[str, str], dict[int, list[float]]] = {}
    for rec in records:
        curve = (rec.get("extra") or {}).get("curve")
        if not curve:
            continue
        cell = per_cell.setdefault((str(rec["config"]["method"]), str(rec["config"]["env"])), {})
        for step, success in curve:
            cell.setdefault(int(step), []).append(float(success))
    out: dict[str, dict[str, SeedCurve]] = {}
    for (method, env), points in per_cell.items():
        steps = sorted(points)
        values = [points[s] for s in steps]
        out.setdefault(method, {})[env] = SeedCurve(
            np.array(steps, dtype=np.int64),
            np.array([np.mean(v) for v in values]),
            np.array([min(v) for v in values]),
            np.array([max(v) for v in values]),
            np.array([len(v) for v in values], dtype=np.int64),
        )
    return out


def plot_learning_curves(
    suite: Suite,
    records: Sequence[Mapping[str, Any]],
    out_dir: str,
    *,
    methods: Sequence[str] | None = None,
    target: float | None = None,
) -> list[str]:
    """Write ``<suite>_learning_curves.png`` (nothing without stored curves): a panel per env, ``methods`` first.

    ``methods`` defaults to the suite's, ``target`` (dashed) to the goal of its ``success`` metric.
    """
    curves = learning_curves(records)
    order = [m for m in suite.method_list() if m is not None] if methods is None else methods
    if target is None:
        target = suite.metric("success").goal or 0.0
    methods = [m for m in order if m in curves] + sorted(set(curves) - set(order))
    if not methods:
        return []
    known = [e for e in suite.env_list() if e is not None]
    present = {env for m in methods for env in curves[m]}
    envs = [e for e in known if e in present] + sorted(present - set(known))
    cols = min(_COLUMNS, len(envs))
    rows = math.ceil(len(envs) / cols)
    fig = new_figure(3.6 * cols + 0.4, 2.9 * rows + 0.9)
    axes = fig.subplots(rows, cols, squeeze=False, sharex=False, sharey=True)
    fallback = iter(f"C{i}" for i in range(3, 10))
    colours = {m: _COLOURS.get(m) or next(fallback, "black") for m in methods}
    for ax, env in zip(axes.flat, envs, strict=False):
        seeds = 0
        for method in methods:
            curve = curves[method].get(env)
            if curve is None:
                continue
            x = curve.steps / 1000.0
            ax.fill_between(x, curve.low, curve.high, color=colours[method], alpha=0.2, lw=0)
            ax.plot(x, curve.mean, "o-", ms=2.5, lw=1.5, color=colours[method])
            seeds = max(seeds, int(curve.seeds.max()))
        ax.axhline(target, color="black", ls="--", lw=1)
        ax.set_ylim(-3, 103)
        ax.set_title(f"{env.split('/')[-1]} ({seeds} seed{'s' if seeds != 1 else ''})", fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(envs) :]:
        ax.set_visible(False)
    for ax in axes[:, 0]:
        ax.set_ylabel("success (%)")
    for i, ax in enumerate(axes.flat[: len(envs)]):
        if i + cols >= len(envs):  # the lowest panel of its column
            ax.set_xlabel("training steps (k)")
    handles = [key_line(_LABELS.get(m, m), color=colours[m], marker="o", ms=3, lw=1.5) for m in methods]
    handles.append(key_patch("min to max over seeds", facecolor="grey", alpha=0.3, edgecolor="none"))
    handles.append(key_line(f"target {target:.0f} %", color="black", ls="--", lw=1))
    fig.suptitle(f"{suite.name}: success rate vs training steps (mean over seeds, band: min to max)")
    figure_legend(fig, handles, ncol=len(handles), fontsize=8)
    return [str(save_figure(fig, Path(out_dir) / f"{suite.name}_learning_curves.png"))]
