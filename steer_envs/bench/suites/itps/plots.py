"""Figures of ``itps-maze2d``: the alignment-vs-collision trade-off and a qualitative grid of plans.

* :func:`plot_itps` writes ``<suite>_tradeoff.png`` (Avg / Min L2 against
  collision per method, the thesis's Table 2.1 values hollow; thesis
  Fig. 2.4) and ``<suite>_qualitative.png`` (a maze per seed x method with the
  sketch, the batch of plans coloured over time, thicker = closer to the
  sketch, collisions tinted white; thesis Fig. 2.5) from the records that kept
  their plans (the first ``plot_seeds`` seeds).

>>> from steer_envs.bench.suite import get_suite
>>> plot_itps(get_suite("itps-maze2d"), [], "unused")  # no records: nothing to draw
[]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.report import suite_table
from steer_envs.bench.suite import Suite
from steer_envs.utils.plots import figure_legend, key_line, key_patch, new_figure, save_figure

__all__ = ["plot_itps"]


def _maze_walls(records: Sequence[Mapping[str, Any]], default_env: str) -> np.ndarray:
    import gymnasium as gym

    import steer_envs  # noqa: F401

    env_id = next((r["config"]["env"] for r in records if r["config"].get("env")), default_env)
    env: Any = gym.make(env_id).unwrapped
    try:
        return np.array(env.grid.walls)
    finally:
        env.close()


def _draw_maze(ax: Any, walls: np.ndarray) -> None:
    # x = row (down), y = column (right): show the grid as an image with rows top to bottom
    rows, cols = walls.shape
    ax.imshow(np.where(walls, 0.35, 0.97), cmap="gray", vmin=0, vmax=1, extent=(-0.5, cols - 0.5, rows - 0.5, -0.5))
    ax.set_xlim(-0.5, cols - 0.5)
    ax.set_ylim(rows - 0.5, -0.5)
    ax.set_autoscale_on(False)
    ax.set_xticks([])
    ax.set_yticks([])


def _draw_plans(ax: Any, record: Mapping[str, Any]) -> None:
    from matplotlib import colormaps
    from matplotlib.collections import LineCollection

    extra = record["extra"]
    plans = np.asarray(extra["plans"], dtype=np.float64)
    collides = np.asarray(extra["collides"], dtype=bool)
    dist = np.asarray(extra["distances"], dtype=np.float64)
    sketch = np.asarray(extra["sketch"], dtype=np.float64)
    ax.plot(sketch[:, 1], sketch[:, 0], color="0.4", linewidth=4, alpha=0.7, solid_capstyle="round", zorder=4)
    # thicker = closer to the sketch (thesis Fig. 2.5); drawn far-to-near so the best plans are on top
    spread = max(float(dist.max() - dist.min()), 1e-9)
    cmap = colormaps["rainbow"]
    for b in np.argsort(-dist):
        pts = plans[b][:, ::-1]
        segments = np.stack([pts[:-1], pts[1:]], axis=1)
        colors = cmap(np.linspace(0.0, 1.0, len(segments)))
        if collides[b]:
            colors[:, :3] = 0.25 * colors[:, :3] + 0.75  # tinted white, as in the thesis
        width = 0.6 + 2.4 * (1.0 - (dist[b] - dist.min()) / spread)
        ax.add_collection(LineCollection(segments, colors=colors, linewidths=width, zorder=2))
    start = np.asarray(extra["start"], dtype=np.float64)
    ax.plot(start[1], start[0], "o", color="black", markersize=6, zorder=3)
    if extra.get("perturbed_state") is not None:
        moved = np.asarray(extra["perturbed_state"], dtype=np.float64)
        ax.plot(moved[1], moved[0], "o", color="black", markersize=6, markerfacecolor="none", zorder=3)


def _plans_key() -> list[Any]:
    """Legend entries of the qualitative grid (what :func:`_draw_plans` draws)."""
    from matplotlib import colormaps

    cmap = colormaps["rainbow"]
    faded = 0.25 * np.asarray(cmap(0.5)[:3]) + 0.75
    return [
        key_line("user sketch", color="0.4", lw=4, alpha=0.7),
        key_line("plan, first waypoint", color=cmap(0.0), lw=2),
        key_line("plan, last waypoint", color=cmap(1.0), lw=2),
        key_line("plan in collision (faded)", color=tuple(faded), lw=2),
        key_line("agent start", color="black", marker="o", ls="none"),
        key_line("pushed to", color="black", marker="o", markerfacecolor="none", ls="none"),
        key_patch("wall", facecolor="0.35"),
    ]


def plot_itps(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """Trade-off plot (Avg/Min L2 vs collision, thesis numbers hollow) and the qualitative grid."""
    written: list[str] = []
    table = suite_table(suite, records)
    rows = [r for r in table.rows if r.stats.get("avg_l2") is not None] if table else []
    thesis = {(ref.method, ref.metric): ref.value for ref in suite.references}
    if rows:
        fig = new_figure(6.5, 4.5)
        ax = fig.add_subplot()
        for i, r in enumerate(rows):
            color = f"C{i % 10}"
            marker = "o" if (r.method or "").startswith("DP") else "s"
            coll, avg, mn = (r.stats[k].mean for k in ("collision", "avg_l2", "min_l2"))  # type: ignore[union-attr]
            ax.scatter([coll], [avg], color=color, marker=marker, s=60, label=r.method)
            ax.scatter([coll], [mn], color=color, marker=marker, s=25, alpha=0.6)
            ax.plot([coll, coll], [mn, avg], color=color, linewidth=1, alpha=0.6)
            ref_coll, ref_avg = thesis.get((r.method, "collision")), thesis.get((r.method, "avg_l2"))
            if ref_coll is not None and ref_avg is not None:
                ax.scatter([ref_coll], [ref_avg], facecolors="none", edgecolors=color, marker=marker, s=60)
        ax.set_xlabel("collision rate (fraction of the batch)")
        ax.set_ylabel("L2 to sketch / maze extent (big: Avg, small: Min)")
        ax.set_title("itps-maze2d: alignment vs. collision (hollow: thesis Table 2.1)", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
        written.append(str(save_figure(fig, Path(out_dir) / f"{suite.name}_tradeoff.png")))
    with_plans = [r for r in records if "plans" in r.get("extra", {})]
    if with_plans:
        listed = suite.methods() if callable(suite.methods) else suite.methods
        methods = [m for m in listed if any(r["config"]["method"] == m for r in with_plans)]
        seeds = sorted({int(r["seed"]) for r in with_plans})[:3]
        envs = suite.envs() if callable(suite.envs) else suite.envs
        walls = _maze_walls(with_plans, str(envs[0]))
        fig = new_figure(max(2.4 * len(methods) + 0.5, 6.5), 1.9 * len(seeds) + 1.2)
        axes = fig.subplots(len(seeds), len(methods), squeeze=False)
        for i, seed in enumerate(seeds):
            for j, method in enumerate(methods):
                ax = axes[i][j]
                _draw_maze(ax, walls)
                rec = next((r for r in with_plans if r["config"]["method"] == method and int(r["seed"]) == seed), None)
                if rec is not None:
                    _draw_plans(ax, rec)
                if i == 0:
                    ax.set_title(method, fontsize=9)
                if j == 0:
                    ax.set_ylabel(f"seed {seed}", fontsize=8)
        fig.suptitle(f"{suite.name}: steered plans per sampler (thicker: closer to the sketch)", fontsize=9)
        figure_legend(fig, _plans_key(), ncol=4)
        written.append(str(save_figure(fig, Path(out_dir) / f"{suite.name}_qualitative.png")))
    return written
