"""Figures of ``itps-blockstack``: steered plans in 3D like thesis Fig. 2.6, and the Table 2.2 quadrants.

* ``<suite>_plans.png``: one 3D panel per method (columns) and kept
  interaction (rows, the first interactions of the first ``plot_seeds``
  seeds): the cubes, the user's sketch (black, dashed), the batch of plans
  (thin grey) and the picked plan (purple when aligned with the intended
  skill, brown dash-dotted when not; a dot where the gripper closes or opens),
  all named in the legend below;
* ``<suite>_quadrants.png``: stacked AS/AF/MS/MF bars per method, the
  thesis's TA and CS as hollow markers.

>>> from steer_envs.bench.suite import get_suite
>>> plot_blockstack(get_suite("itps-blockstack"), [], "unused")  # no records: nothing to draw
[]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.plots import quadrant_figure
from steer_envs.bench.suite import Suite
from steer_envs.utils.plots import figure_legend, key_line, new_figure, save_figure

__all__ = ["plot_blockstack"]

_CUBE_COLORS = ("tab:red", "tab:green", "tab:blue", "tab:orange")
#: the picked plan's (colour, line style) when aligned / misaligned: no cube colour means a verdict
_ALIGNED, _MISALIGNED = ("tab:purple", "-"), ("tab:brown", "-.")


def _switch(plan: np.ndarray) -> int | None:
    """Index of the first waypoint whose gripper command differs from the first one's."""
    sign = np.sign(plan[:, 3])
    changed = np.nonzero(sign != sign[0])[0]
    return int(changed[0]) if len(changed) else None


def _draw_interaction(ax: Any, item: Mapping[str, Any]) -> None:
    cubes = np.asarray(item["cube_pos"], dtype=np.float64)
    for i, c in enumerate(cubes):
        ax.scatter(*c, color=_CUBE_COLORS[i % 4], marker="s", s=70, depthshade=False)
    plans = np.asarray(item["plans"], dtype=np.float64)
    for p in plans:
        ax.plot(p[:, 0], p[:, 1], p[:, 2], color="0.6", linewidth=0.5, alpha=0.6)
    chosen = plans[int(item["chosen"])]
    color, style = _ALIGNED if item["aligned"] else _MISALIGNED
    ax.plot(chosen[:, 0], chosen[:, 1], chosen[:, 2], color=color, linestyle=style, linewidth=2.2)
    k = _switch(chosen)
    if k is not None:
        ax.scatter(*chosen[k, :3], color=color, s=25, depthshade=False)
    sketch = np.asarray(item["sketch"], dtype=np.float64)
    ax.plot(sketch[:, 0], sketch[:, 1], sketch[:, 2], color="black", linestyle="--", linewidth=1.4)
    eef = np.asarray(item["eef"], dtype=np.float64)
    ax.scatter(*eef, color="black", marker="^", s=30, depthshade=False)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_zticks([])
    ax.view_init(elev=28, azim=-60)


def _plans_figure(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> str | None:
    with_plans = [r for r in records if r.get("extra", {}).get("plans")]
    if not with_plans:
        return None
    from steer_envs.steering.blockstack import METHOD_SAMPLERS

    methods = [m for m in METHOD_SAMPLERS if any(r["config"]["method"] == m for r in with_plans)]
    seeds = sorted({int(r["seed"]) for r in with_plans})
    rows = [(s, k) for s in seeds for k in range(2)]
    rows = [(s, k) for s, k in rows if any(int(r["seed"]) == s and len(r["extra"]["plans"]) > k for r in with_plans)][
        :4
    ]
    fig = new_figure(2.6 * len(methods) + 0.4, 2.5 * len(rows) + 0.7)
    for i, (seed, k) in enumerate(rows):
        for j, method in enumerate(methods):
            ax = fig.add_subplot(len(rows), len(methods), i * len(methods) + j + 1, projection="3d")
            rec = next((r for r in with_plans if r["config"]["method"] == method and int(r["seed"]) == seed), None)
            if rec is None or len(rec["extra"]["plans"]) <= k:
                ax.set_axis_off()
                continue
            item = rec["extra"]["plans"][k]
            _draw_interaction(ax, item)
            verdict = ("aligned" if item["aligned"] else "misaligned") + (", ok" if item["success"] else ", failed")
            title = f"{method}\n" if i == 0 else ""
            ax.set_title(f"{title}seed {seed} #{k + 1}: {item['intended']}\n{verdict}", fontsize=7)
    fig.suptitle(f"{suite.name}: steered plans per method and interaction", fontsize=9)
    figure_legend(
        fig,
        [
            key_line("user sketch", color="black", ls="--", lw=1.4),
            key_line("sampled batch", color="0.6", lw=0.8),
            key_line("picked plan, aligned", color=_ALIGNED[0], ls=_ALIGNED[1], lw=2.2),
            key_line("picked plan, misaligned", color=_MISALIGNED[0], ls=_MISALIGNED[1], lw=2.2),
            key_line("gripper closes / opens", color="0.3", marker="o", ls="none", markersize=4),
            key_line("end effector", color="black", marker="^", ls="none", markersize=5),
            *(key_line(f"cube {i}", color=c, marker="s", ls="none", markersize=6) for i, c in enumerate(_CUBE_COLORS)),
        ],
        ncol=5,
    )
    return str(save_figure(fig, Path(out_dir) / f"{suite.name}_plans.png"))


def plot_blockstack(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """The figures of the module docstring (those the records can fill)."""
    written = [quadrant_figure(suite, records, out_dir), _plans_figure(suite, records, out_dir)]
    return [w for w in written if w is not None]
