"""Figures of ``itps-kitchen``: Table 2.3's quadrants, a rendered rollout strip, the guide-ratio sweep (Fig. 2.10).

* ``<suite>_quadrants.png``: stacked AS/AF/MS/MF bars per method, the
  thesis's TA and CS as hollow markers;
* ``<suite>_rollout.png``: the scene camera before each steered skill of one
  kept rollout (SS first, seed 0 first), the click (red ring) and the run plan
  projected (cyan aligned / orange misaligned, a dot where the gripper
  switches), titled with the watched, intended and planned skills, the last
  frame the rollout's end (:func:`steer_envs.steering.figures.rollout_strip`);
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

from steer_envs.bench.plots import quadrant_figure
from steer_envs.bench.suite import Suite
from steer_envs.utils.plots import figure_legend, new_figure, save_figure

__all__ = ["plot_kitchen", "plot_sweep"]

_SWEEP_STYLE = {"DP-GD": ("tab:blue", "o"), "DP-SS": ("tab:red", "s")}


def _rollout_figure(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> str | None:
    from steer_envs.steering.figures import rollout_strip
    from steer_envs.steering.kitchen import decode_frame

    kept = [r for r in records if r.get("extra", {}).get("frames")]
    if not kept:
        return None
    listed = suite.methods() if callable(suite.methods) else suite.methods
    order = {m: i for i, m in enumerate(dict.fromkeys(("DP-SS", *listed)))}
    rec = min(kept, key=lambda r: (order.get(r["config"]["method"], 99), int(r["seed"])))
    frames = [{**f, "image": decode_frame(f)} for f in rec["extra"]["frames"]]
    title = f"{suite.name}: {rec['config']['method']}, seed {rec['seed']} ({rec['extra'].get('task', '')} task)"
    return str(rollout_strip(frames, Path(out_dir) / f"{suite.name}_rollout.png", title))


def plot_kitchen(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """The suite's figures of the module docstring (those the records can fill)."""
    written = [quadrant_figure(suite, records, out_dir), _rollout_figure(suite, records, out_dir)]
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
