"""Figures of the robosuite GLiDE study: learned vs ground-truth modes along demonstrations (thesis Fig. A.2)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.suite import Suite
from steer_envs.utils.plots import new_figure, save_figure

#: one colour per mode index (up to 6 modes).
MODE_COLORS = ("#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860")


def draw_mode_strips(
    ax: Any, rows: Sequence[tuple[str, np.ndarray]], mode_names: Sequence[str], *, title: str = ""
) -> None:
    """Draw one horizontal strip per ``(label, modes)`` row on ``ax`` (time on x, a colour per mode), with a legend."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    k = len(mode_names)
    cmap = ListedColormap(MODE_COLORS[:k])
    length = max(len(m) for _, m in rows)
    grid = np.full((len(rows), length), np.nan)
    for i, (_, modes) in enumerate(rows):
        grid[i, : len(modes)] = modes
    ax.imshow(grid, aspect="auto", cmap=cmap, vmin=-0.5, vmax=k - 0.5, interpolation="nearest")
    ax.set_yticks(range(len(rows)), [label for label, _ in rows])
    ax.set_xlabel("control step (20 Hz)")
    if title:
        ax.set_title(title)
    ax.legend(
        handles=[Patch(color=MODE_COLORS[m], label=name) for m, name in enumerate(mode_names)],
        loc="upper left",
        bbox_to_anchor=(1.0, 1.0),
        fontsize="small",
    )


def save_mode_strips(labels: Mapping[str, Sequence[Mapping[str, Any]]], task: str, name: str, path: str | Path) -> Path:
    """One panel per kept demo: the ground truth, then each variant's learned modes; written to ``path`` (PNG).

    ``labels``: variant -> per demo ``{"pred": [...], "true": [...]}`` (what the grounding trials keep).
    """
    from steer_envs.envs.robosuite.tasks import TASKS

    first = next(iter(labels.values()))
    n = len(first)
    fig = new_figure(9.0, 1.2 + 0.35 * n * (len(labels) + 1))
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    for i, ax in enumerate(axes):
        rows = [("ground truth", np.asarray(first[i]["true"]))]
        rows += [(v, np.asarray(lab[i]["pred"])) for v, lab in labels.items() if i < len(lab)]
        draw_mode_strips(ax, rows, TASKS[task].modes, title=f"demo {i}")
    fig.suptitle(f"{name}: learned vs ground-truth modes along the demos", fontsize=10)
    return save_figure(fig, path)


def plot_mode_strips(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """One PNG per task: for each kept demo, the ground truth and every variant's learned modes."""
    by_env: dict[str, dict[str, Any]] = {}
    for r in records:
        labels = r.get("extra", {}).get("labels")
        if r["config"]["suite"] != suite.name or not labels:
            continue
        by_env.setdefault(r["config"]["env"], {})[r["config"]["method"]] = labels
    written = []
    for env, variants in sorted(by_env.items()):
        task = env.split("/")[-1].split("-")[0].lower()
        written.append(str(save_mode_strips(variants, task, env, Path(out_dir) / f"{suite.name}-{task}-modes.png")))
    return written
