"""The tli-arm-scoop figure: the scoop mode's boundary and cuts in (y, z, pitch), nominal vs modulated flows.

Like the thesis's 3D modulation figure: sampled DS trajectories from pushed
scoop states, left as learned, right modulated by the cuts the arm learned;
the guard surface, the bowl's walls, the cut planes, the arm's invariance
failures and the attractor.

>>> plot_arm_scoop(None, [], "unused")
[]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.plots import recorded_figures
from steer_envs.utils.plots import figure_legend, key_line, new_figure, save_figure

__all__ = ["plot_arm_scoop"]

_GUARD, _WALL, _CUT = "#ff9f1c", "#9ecae1", "#1f4e9c"


def _box() -> tuple[np.ndarray, np.ndarray]:
    """The drawn (y, z, pitch) box around the soup."""
    from steer_envs.envs.robosuite.arm_scoop import BOWL_RADIUS, SOUP_SURFACE, SOUP_Y, WORKSPACE

    low = np.array([SOUP_Y - BOWL_RADIUS - 0.02, WORKSPACE[0][1], -1.2])
    high = np.array([SOUP_Y + BOWL_RADIUS + 0.02, SOUP_SURFACE + 0.04, 1.2])
    return low, high


def _plane(ax: Any, point: np.ndarray, normal: np.ndarray, low: np.ndarray, high: np.ndarray, **style: Any) -> None:
    """Draw the plane through ``point`` with ``normal`` inside the box, solved for its steepest coordinate."""
    k = int(np.argmax(np.abs(normal)))
    a, b = (i for i in range(3) if i != k)
    grid_a, grid_b = np.meshgrid(np.linspace(low[a], high[a], 12), np.linspace(low[b], high[b], 12))
    value = point[k] - (normal[a] * (grid_a - point[a]) + normal[b] * (grid_b - point[b])) / normal[k]
    value = np.where((value >= low[k]) & (value <= high[k]), value, np.nan)
    coords: list[np.ndarray] = [np.empty(0)] * 3
    coords[a], coords[b], coords[k] = grid_a, grid_b, value
    ax.plot_surface(coords[0], coords[2], coords[1], **style)  # drawn as (y, pitch, z): height up


def _boundary(ax: Any, low: np.ndarray, high: np.ndarray) -> None:
    from steer_envs.envs.robosuite.arm_scoop import BOWL_RADIUS, PITCH_HIGH, PITCH_LOW, SOUP_SURFACE, SOUP_Y

    y = np.linspace(SOUP_Y - BOWL_RADIUS, SOUP_Y + BOWL_RADIUS, 2)
    p = np.linspace(PITCH_LOW, PITCH_HIGH, 2)
    yy, pp = np.meshgrid(y, p)
    ax.plot_surface(yy, pp, np.full_like(yy, SOUP_SURFACE), color=_GUARD, alpha=0.45)
    zz, pp = np.meshgrid(np.linspace(low[1], SOUP_SURFACE, 2), np.linspace(low[2], high[2], 2))
    for wall in (SOUP_Y - BOWL_RADIUS, SOUP_Y + BOWL_RADIUS):
        ax.plot_surface(np.full_like(zz, wall), pp, zz, color=_WALL, alpha=0.25)


def plot_arm_scoop(suite: Any, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """One PNG from the first recorded ``ltl-ds+mod`` trial (else any recorded one); returns its path."""
    recorded = sorted(recorded_figures(records).items(), key=lambda cell: cell[0][1] != "ltl-ds+mod")
    data = recorded[0][1] if recorded else None
    if not data:
        return []
    low, high = _box()
    fig = new_figure(11.0, 5.2)
    panels = (
        ("scoop DS as learned (no cuts)", data["sampled_nominal"], False),
        (f"modulated by the {len(data['cuts'])} cut(s) learned on the arm", data["sampled_modulated"], True),
    )
    for col, (title, traces, with_cuts) in enumerate(panels):
        ax = fig.add_subplot(1, 2, col + 1, projection="3d")
        _boundary(ax, low, high)
        if with_cuts:
            for cut in data["cuts"]:
                _plane(ax, np.asarray(cut["point"]), np.asarray(cut["normal"]), low, high, color=_CUT, alpha=0.15)
        exits = 0
        for trace in traces:
            t = np.asarray(trace).reshape(-1, 3)
            wrong = _wrong_exit(t[-1])
            exits += wrong
            ax.plot(t[:, 0], t[:, 2], t[:, 1], color="#d62728" if wrong else "black", linewidth=0.8)
            ax.scatter(t[0, 0], t[0, 2], t[0, 1], color="grey", s=6)
        fails = np.asarray(data["failure_states"]).reshape(-1, 3)
        if len(fails):
            ax.scatter(fails[:, 0], fails[:, 2], fails[:, 1], color="#d62728", marker="x", s=40)
        att = np.asarray(data["attractor"])
        ax.scatter(att[0], att[2], att[1], color="#e377c2", marker="D", s=40)
        ax.set_xlim(low[0], high[0])
        ax.set_xticks(np.round(np.arange(low[0] + 0.01, high[0], 0.04), 2))
        ax.set_ylim(low[2], high[2])
        ax.set_zlim(low[1], high[1])
        ax.set_xlabel("y (m)")
        ax.set_ylabel("pitch (rad)")
        ax.set_zlabel("z (m)")
        ax.view_init(elev=18, azim=-60)
        ax.set_title(f"{title}\n{exits}/{len(traces)} shown flows leave the mode wrongly", fontsize=8)
    handles = [
        key_line("guard: soup surface, spoon level enough (scoop -> transport)", color=_GUARD, lw=6),
        key_line("bowl wall (scoop mode boundary)", color=_WALL, lw=6),
        key_line("learned cut", color=_CUT, lw=6),
        key_line("flow stays / exits through the guard", color="black"),
        key_line("flow exits the mode wrongly (empty, or through the wall)", color="#d62728"),
        key_line("invariance failure on the arm (last in-mode state)", color="#d62728", marker="x", ls="none"),
        key_line("scoop attractor", color="#e377c2", marker="D", ls="none"),
    ]
    figure_legend(fig, handles, ncol=3)
    name = getattr(suite, "name", "tli-arm-scoop")
    fig.suptitle(f"{name}: the scoop mode in (y, z, pitch), sampled DS flows before and after modulation", fontsize=9)
    return [str(save_figure(fig, Path(out_dir) / f"{name}_modulation.png"))]


def _wrong_exit(x: np.ndarray) -> bool:
    """The flow's last state left the soup other than through the guard."""
    from steer_envs.envs.robosuite.arm_scoop import BOWL_RADIUS, PITCH_HIGH, PITCH_LOW, SOUP_SURFACE, SOUP_Y

    in_soup = abs(x[0] - SOUP_Y) <= BOWL_RADIUS and x[1] <= SOUP_SURFACE
    through_guard = x[1] > SOUP_SURFACE and PITCH_LOW <= x[2] <= PITCH_HIGH
    return not in_soup and not through_guard
