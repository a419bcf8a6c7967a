"""Figures of steered rollouts: :func:`rollout_strip`, the camera frames of a clicked Kitchen rollout.

Each panel is the scene camera before one steered skill with the click (red
ring) and the run plan projected (cyan aligned / orange misaligned, a dot
where the gripper switches), titled with the watched, intended and planned
skills; a last panel shows the rollout's end. :func:`~steer_envs.steering.kitchen.kitchen_trial`
keeps such frames with ``keep_frames`` (:func:`~steer_envs.steering.kitchen.decode_frame`
turns them back into images).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.utils.plots import figure_legend, key_line, new_figure, save_figure

__all__ = ["rollout_strip"]

_ALIGNED, _MISALIGNED = "cyan", "orange"


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
