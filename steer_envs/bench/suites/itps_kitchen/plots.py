"""Figures of ``itps-kitchen``: Table 2.3's quadrants, a rendered rollout strip, the guide-ratio sweep (Fig. 2.10).

* ``<suite>_quadrants.png``: stacked AS/AF/MS/MF bars per method, the
  thesis's TA and CS as hollow markers;
* ``<suite>_rollout.png``: the scene camera before each steered skill of one
  kept rollout (SS first, seed 0 first), the click (red ring) and the run plan
  projected (cyan aligned / orange misaligned, a dot where the gripper
  switches), titled with the watched, intended and planned skills, the last
  frame the rollout's end (:func:`rollout_strip`, also used by ``examples/steer_kitchen.py``);
* :func:`plot_sweep`: the share of a batch doing the intended skill against the
  guide ratio, GD and SS (the sweep module's figure).

>>> from steer_envs.bench.suite import get_suite
>>> plot_kitchen(get_suite("itps-kitchen"), [], "unused")  # no records: nothing to draw
[]
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.plots import figure_legend, key_line, new_figure, save_figure
from steer_envs.bench.report import summarize
from steer_envs.bench.suite import Suite

__all__ = ["plot_kitchen", "plot_sweep", "rollout_strip"]

_QUADRANTS = (("AS", "tab:green"), ("AF", "tab:olive"), ("MS", "tab:cyan"), ("MF", "tab:gray"))
_ALIGNED, _MISALIGNED = "cyan", "orange"
_SWEEP_STYLE = {"DP-GD": ("tab:blue", "o"), "DP-SS": ("tab:red", "s")}


def _switch(plan: np.ndarray, grip: np.ndarray | None) -> int | None:
    if grip is None or len(grip) != len(plan):
        return None
    closed = np.asarray(grip) > 0
    changed = np.nonzero(closed != closed[0])[0]
    return int(changed[0]) if len(changed) else None


def rollout_strip(frames: Sequence[Mapping[str, Any]], path: str | os.PathLike[str], title: str) -> Path | None:
    """Save a strip of camera frames (each ``{"image", "pixel", "plan_uv", ...}`` or ``{"image", "end"}``).

    ``image``: an ``(H, W, 3)`` uint8 frame; ``pixel``: the click (column, row);
    ``plan_uv``: the run plan's waypoints projected (``(H, 2)`` columns, rows);
    ``grip`` (optional): the plan's gripper values; ``watched``, ``intended``,
    ``planned``, ``aligned``, ``success``: the panel's title. A frame with
    ``end`` shows the rollout's end (``goal``: whether it reached it). None when
    ``frames`` is empty.
    """
    if not frames:
        return None
    cols = len(frames)
    fig = new_figure(max(2.3 * cols, 6.0), 3.2)
    axes = fig.subplots(1, cols, squeeze=False)[0]
    for ax, item in zip(axes, frames, strict=True):
        image = np.asarray(item["image"])
        ax.imshow(image)
        ax.set_xlim(-0.5, image.shape[1] - 0.5)
        ax.set_ylim(image.shape[0] - 0.5, -0.5)
        ax.axis("off")
        if item.get("end"):
            ax.set_title(f"end: goal {'reached' if item.get('goal') else 'not reached'}", fontsize=7)
            continue
        uv = np.asarray(item["plan_uv"], dtype=np.float64)
        color = _ALIGNED if item["aligned"] else _MISALIGNED
        ax.plot(uv[:, 0], uv[:, 1], color=color, linewidth=1.6)
        k = _switch(uv, item.get("grip"))
        if k is not None:
            ax.scatter([uv[k, 0]], [uv[k, 1]], color=color, s=18, zorder=3)
        u, v = item["pixel"]
        ax.scatter([u], [v], facecolors="none", edgecolors="red", s=70, linewidths=1.8, zorder=4)
        verdict = ("aligned" if item["aligned"] else "misaligned") + (", ok" if item["success"] else ", failed")
        ax.set_title(
            f"saw {item['watched'] or 'none'}\nwant {item['intended']}\nplan {item['planned'] or 'none'}: {verdict}",
            fontsize=6.5,
        )
    fig.suptitle(title, fontsize=9)
    figure_legend(
        fig,
        [
            key_line("click (depth -> 3D point)", color="red", marker="o", ls="none", markersize=7, mfc="none"),
            key_line("run plan, aligned", color=_ALIGNED, lw=1.6),
            key_line("run plan, misaligned", color=_MISALIGNED, lw=1.6),
            key_line("gripper switch", color="0.3", marker="o", ls="none", markersize=4),
        ],
        ncol=4,
    )
    return save_figure(fig, path)


def _rollout_figure(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> str | None:
    from steer_envs.bench.suites.itps_kitchen.protocol import METHODS, decode_frame

    kept = [r for r in records if r.get("extra", {}).get("frames")]
    if not kept:
        return None
    order = {m: i for i, m in enumerate(dict.fromkeys(("DP-SS", *METHODS)))}
    rec = min(kept, key=lambda r: (order.get(r["config"]["method"], 99), int(r["seed"])))
    frames = [{**f, "image": decode_frame(f)} for f in rec["extra"]["frames"]]
    title = f"{suite.name}: {rec['config']['method']}, seed {rec['seed']} ({rec['extra'].get('task', '')} task)"
    return str(rollout_strip(frames, Path(out_dir) / f"{suite.name}_rollout.png", title))


def _quadrant_figure(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> str | None:
    from steer_envs.bench.suites.itps_kitchen.suite import TABLE_2_3

    tables = [t for t in summarize(records) if t.suite == suite.name]
    rows = [r for r in tables[0].rows if r.stats.get("TA") is not None] if tables else []
    if not rows:
        return None
    fig = new_figure(1.2 * len(rows) + 2.5, 4.0)
    ax = fig.add_subplot()
    x = np.arange(len(rows))
    bottom = np.zeros(len(rows))
    for name, color in _QUADRANTS:
        values = np.array([(r.stats[name].mean if r.stats.get(name) else 0.0) or 0.0 for r in rows])  # type: ignore[union-attr]
        ax.bar(x, values, bottom=bottom, color=color, label=name, width=0.6)
        bottom += values
    for i, r in enumerate(rows):
        ref = TABLE_2_3.get(r.method or "")
        if ref:
            ax.scatter([i - 0.15], [ref["TA"]], facecolors="none", edgecolors="black", marker="o", s=45)
            ax.scatter([i + 0.15], [ref["CS"]], facecolors="none", edgecolors="black", marker="D", s=40)
    ax.scatter([], [], facecolors="none", edgecolors="black", marker="o", label="thesis TA")
    ax.scatter([], [], facecolors="none", edgecolors="black", marker="D", label="thesis CS")
    ax.set_xticks(x, [r.method or "" for r in rows], fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("share of interactions")
    ax.set_title(f"{suite.name}: aligned / misaligned x success / failure", fontsize=10)
    figure_legend(fig, ax.get_legend_handles_labels()[0], ncol=3)
    ax.grid(alpha=0.3, axis="y")
    return str(save_figure(fig, Path(out_dir) / f"{suite.name}_quadrants.png"))


def plot_kitchen(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """The suite's figures of the module docstring (those the records can fill)."""
    written = [_quadrant_figure(suite, records, out_dir), _rollout_figure(suite, records, out_dir)]
    return [w for w in written if w is not None]


def plot_sweep(sweep: Mapping[str, Any], path: str | os.PathLike[str]) -> Path:
    """Fig. 2.10: share of the batch doing the intended skill vs the guide ratio (a ``guide_ratio_sweep`` result)."""
    ratios = np.asarray(sweep["ratios"], dtype=np.float64)
    fig = new_figure(5.0, 3.6)
    ax = fig.add_subplot()
    for method, shares in sweep["share"].items():
        color, marker = _SWEEP_STYLE.get(method, ("tab:gray", "^"))
        ax.plot(ratios, shares, color=color, marker=marker, label=method)
    if len(ratios) > 1 and ratios.max() > 10 * max(float(ratios[ratios > 0].min(initial=1.0)), 1e-9):
        ax.set_xscale("symlog", linthresh=1.0)  # ratios span decades; 0 (unguided) stays on the axis
    ax.set_xlabel("guide ratio beta (every DDIM step)")
    ax.set_ylabel("share of batch doing the intended skill")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    scenes = len(sweep.get("scenes", ()))
    ax.set_title(f"Kitchen: guide-ratio sensitivity ({scenes} scenes, batch {sweep.get('batch', '?')})", fontsize=9)
    figure_legend(fig, ax.get_legend_handles_labels()[0], ncol=2)
    return save_figure(fig, path)
