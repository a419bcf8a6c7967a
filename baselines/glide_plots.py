"""Plots of learned mode boundaries on PolygonNav (thesis Fig. 4.4 / appendix figures).

:func:`plot_groundings` draws one panel per labelling (ground truth first,
then any learned classifiers or baselines) as a colour map over the
workspace, with the polygons' outlines, optional trajectories on top and the
overlap with the ground truth in each panel's title. Written with
matplotlib's Agg backend to a PNG, atomically (temp file + ``os.replace``).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.baselines.glide import ModePredictor, mode_overlap, workspace_grid

#: mode colours (free space first), as in the thesis figures: light free space, saturated polygons.
MODE_COLORS: tuple[str, ...] = (
    "#f2f2f2",
    "#e41a1c",
    "#377eb8",
    "#4daf4a",
    "#984ea3",
    "#ff7f00",
    "#a65628",
    "#f781bf",
    "#999999",
)


def plot_groundings(
    model: Any,
    predictors: Mapping[str, ModePredictor],
    path: str | os.PathLike[str],
    *,
    resolution: int = 200,
    trajectories: Sequence[np.ndarray] = (),
    trajectory_success: Sequence[bool] | None = None,
    title: str | None = None,
    panel_size: float = 3.2,
) -> Path:
    """Write a PNG: ground truth + one panel per predictor, each with its grid overlap.

    Args:
        model: the env's task model (``env.unwrapped.model``) with ``low``,
            ``high``, ``num_modes``, ``vertices`` and ``mode_of``.
        predictors: panel title -> object with ``predict(states) -> modes``.
        path: output ``.png`` path.
        resolution: grid side (the overlap metric uses 200).
        trajectories: ``(T_i, 2)`` paths drawn on every panel (e.g. the demos).
        trajectory_success: colours those paths blue (success) / red (failure).
        title: figure title.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    path = Path(path)
    if path.suffix != ".png":
        raise ValueError(f"path must end in .png, got {str(path)!r}")
    if not isinstance(predictors, Mapping):
        raise TypeError(f"predictors must be a mapping name -> predictor, got {type(predictors).__name__}")
    for name, p in predictors.items():
        if not hasattr(p, "predict"):
            raise TypeError(f"predictor {name!r} has no predict(states) method")
    if trajectory_success is not None and len(trajectory_success) != len(trajectories):
        raise ValueError("trajectory_success must have one flag per trajectory")
    k = int(model.num_modes)
    grid = workspace_grid(model.low, model.high, resolution)
    truth = model.mode_of(grid)
    panels = [("ground truth", truth, None)]
    for name, p in predictors.items():
        pred = np.asarray(p.predict(grid))
        panels.append((name, pred, mode_overlap(pred, truth)))
    cmap = ListedColormap(list(MODE_COLORS[: max(k, 2)]))
    extent = (model.low[0], model.high[0], model.low[1], model.high[1])
    fig, axes = plt.subplots(1, len(panels), figsize=(panel_size * len(panels), panel_size + 0.4), squeeze=False)
    for ax, (name, labels, overlap) in zip(axes[0], panels, strict=True):
        img = np.clip(labels, 0, k - 1).reshape(resolution, resolution)
        ax.imshow(img, origin="lower", extent=extent, cmap=cmap, vmin=-0.5, vmax=k - 0.5, interpolation="nearest")
        for v in model.vertices:
            loop = np.vstack([v, v[:1]])
            ax.plot(loop[:, 0], loop[:, 1], color="k", lw=0.6)
        for i, tr in enumerate(trajectories):
            tr = np.asarray(tr)
            ok = True if trajectory_success is None else bool(trajectory_success[i])
            ax.plot(tr[:, 0], tr[:, 1], color="#1f3fbf" if ok else "#bf1f1f", lw=0.7, alpha=0.8)
        ax.set_title(name if overlap is None else f"{name}\noverlap {overlap:.3f}", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_aspect("equal")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        fig.savefig(tmp, format="png", dpi=100)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    finally:
        plt.close(fig)
    return path


__all__ = ["MODE_COLORS", "plot_groundings"]
