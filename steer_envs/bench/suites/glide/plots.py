"""Plots of learned mode boundaries on PolygonNav (thesis Fig. 4.4 / appendix figures).

* :func:`plot_mode_maps` draws rows of panels; each panel is a mode labelling
  of the workspace grid (ground truth first, then learned classifiers or
  baselines) as a colour map, with the polygons' outlines, optional
  trajectories on top and the overlap with the ground truth in its title.
  One row per env reproduces the layout of thesis Fig. 4.4 ((a) ground truth
  with the demos, (b) GLiDE, (c) no counterfactuals, (d) wrong feasibility
  matrix, (e) k-means++).
* :func:`plot_groundings` is the one-row version that labels the grid with
  predictor objects.
* :func:`encode_labels` / :func:`decode_labels` store a labelling compactly
  in a JSON record (one digit per grid point), so benchmark records can be
  plotted later without the classifiers.

Figures come from :func:`steer_envs.bench.plots.new_figure` and are written
with :func:`steer_envs.bench.plots.save_figure`.

>>> decode_labels(encode_labels(np.array([0, 2, 1, 0])), resolution=2).tolist()
[0, 2, 1, 0]
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.baselines.glide.modes import ModePredictor, mode_overlap, workspace_grid
from steer_envs.utils.plots import figure_legend, key_line, key_patch, new_figure, save_figure

#: mode colours (free space first): light pastels, so no mode shares a colour with a rollout's
#: success (:data:`SUCCESS_COLOR`) or failure (:data:`FAILURE_COLOR`); no red among them.
MODE_COLORS: tuple[str, ...] = (
    "#f2f2f2",
    "#8dd3c7",
    "#ffffb3",
    "#bebada",
    "#fdb462",
    "#b3de69",
    "#fccde5",
    "#d9d9d9",
    "#bc80bd",
)
#: rollouts drawn on the mode maps: a successful one dark blue, a failed one red
SUCCESS_COLOR, FAILURE_COLOR = "#1f3fbf", "#d62728"


def encode_labels(labels: np.ndarray) -> str:
    """A labelling ``(N,)`` with modes in ``[0, 9]`` as a string of digits (JSON-friendly).

    >>> encode_labels(np.array([0, 1, 3]))
    '013'
    """
    arr = np.asarray(labels)
    if arr.ndim != 1 or (arr.size and (arr.min() < 0 or arr.max() > 9)):
        raise ValueError(f"labels must be a 1-D array of modes in [0, 9], got shape {arr.shape}")
    return (arr.astype(np.uint8) + ord("0")).tobytes().decode("ascii")


def decode_labels(text: str, resolution: int | None = None) -> np.ndarray:
    """Inverse of :func:`encode_labels`; checks the length against ``resolution ** 2`` when given."""
    if not isinstance(text, str) or not text.isdigit():
        raise ValueError("text must be a non-empty string of digits (see encode_labels)")
    out = np.frombuffer(text.encode("ascii"), dtype=np.uint8).astype(np.int64) - ord("0")
    if resolution is not None and len(out) != resolution * resolution:
        raise ValueError(f"text has {len(out)} labels, expected resolution**2 = {resolution * resolution}")
    return out


@dataclass
class ModeMapRow:
    """One row of :func:`plot_mode_maps`: one layout and its labellings.

    Attributes:
        model: the env's task model (``env.unwrapped.model``) with ``low``,
            ``high``, ``num_modes``, ``vertices`` and ``mode_of``.
        panels: panel title -> labels ``(resolution**2,)`` on
            :func:`~steer_envs.baselines.glide.modes.workspace_grid`'s grid; a ground-truth
            panel is added in front.
        title: row title (shown on the ground-truth panel).
        trajectories: ``(T_i, 2)`` paths drawn on the ground-truth panel (or every panel).
        trajectory_success: colours those paths dark blue (success) / red (failure).
    """

    model: Any
    panels: Mapping[str, np.ndarray]
    title: str = ""
    trajectories: Sequence[np.ndarray] = ()
    trajectory_success: Sequence[bool] | None = None
    notes: Mapping[str, str] = field(default_factory=dict)


def plot_mode_maps(
    rows: Sequence[ModeMapRow],
    path: str | os.PathLike[str],
    *,
    resolution: int = 200,
    title: str | None = None,
    panel_size: float = 2.6,
    trajectories_on_every_panel: bool = False,
    mode_names: Sequence[str] | None = None,
) -> Path:
    """Write a PNG with one row per :class:`ModeMapRow`: ground truth, then each labelling.

    Each learned panel's title carries its overlap with the ground truth
    (plus the row's ``notes`` for that panel, e.g. the mean over several layouts).
    Rows may have different panel names; columns follow the first row's
    order, then any new names. A legend below names each mode colour
    (``mode_names``, e.g. ``env.unwrapped.task.modes``; default "free space",
    "polygon 1", ...) and the rollouts' success / failure colours; ``title``
    defaults to a generic one.
    """
    path = Path(path)
    if path.suffix != ".png":
        raise ValueError(f"path must end in .png, got {str(path)!r}")
    _check_rows(rows, mode_names)
    names: list[str] = []
    for r in rows:
        names += [n for n in r.panels if n not in names]
    n_cols = 1 + len(names)
    fig = new_figure(max(panel_size * n_cols, 5.0), (panel_size + 0.45) * len(rows) + 1.0)
    axes = fig.subplots(len(rows), n_cols, squeeze=False)
    for row_axes, row in zip(axes, rows, strict=True):
        _draw_row(row_axes, row, names, resolution, trajectories_on_every_panel)
    fig.suptitle(title or "Mode boundaries: ground truth vs learned", fontsize=10)
    handles = _legend_handles(rows, mode_names)
    figure_legend(fig, handles, ncol=min(len(handles), 4))
    return save_figure(fig, path)


def _check_rows(rows: Sequence[ModeMapRow], mode_names: Sequence[str] | None) -> None:
    """Refuse rows (or mode names) :func:`plot_mode_maps` cannot draw."""
    if not rows:
        raise ValueError("rows must not be empty")
    for r in rows:
        if not isinstance(r, ModeMapRow):
            raise TypeError(f"rows must be ModeMapRow objects, got {type(r).__name__}")
        if r.trajectory_success is not None and len(r.trajectory_success) != len(r.trajectories):
            raise ValueError("trajectory_success must have one flag per trajectory")
    if mode_names is not None and (
        isinstance(mode_names, str) or len(mode_names) < max(int(r.model.num_modes) for r in rows)
    ):
        raise ValueError("mode_names must be a sequence with one name per mode")


def _draw_row(
    row_axes: Sequence[Any], row: ModeMapRow, names: Sequence[str], resolution: int, trajectories_everywhere: bool
) -> None:
    """One row of :func:`plot_mode_maps`: the ground truth, then the panel of each of ``names`` (blank if absent)."""
    from matplotlib.colors import ListedColormap

    model = row.model
    k = int(model.num_modes)
    grid = workspace_grid(model.low, model.high, resolution)
    truth = np.asarray(model.mode_of(grid))
    cmap = ListedColormap(list(MODE_COLORS[: max(k, 2)]))
    extent = (model.low[0], model.high[0], model.low[1], model.high[1])
    for col, ax in enumerate(row_axes):
        ax.set_xticks([])
        ax.set_yticks([])
        if col == 0:
            labels, name, overlap = truth, row.title or "ground truth", None
        else:
            name = names[col - 1]
            if name not in row.panels:
                ax.set_axis_off()
                continue
            labels = np.asarray(row.panels[name])
            if labels.shape != truth.shape:
                raise ValueError(f"panel {name!r} has {labels.shape} labels, expected {truth.shape}")
            overlap = mode_overlap(labels, truth)
        img = np.clip(labels, 0, k - 1).reshape(resolution, resolution)
        ax.imshow(img, origin="lower", extent=extent, cmap=cmap, vmin=-0.5, vmax=k - 0.5, interpolation="nearest")
        for v in model.vertices:
            loop = np.vstack([v, v[:1]])
            ax.plot(loop[:, 0], loop[:, 1], color="k", lw=0.6)
        if col == 0 or trajectories_everywhere:
            for i, tr in enumerate(row.trajectories):
                tr = np.asarray(tr)
                ok = True if row.trajectory_success is None else bool(row.trajectory_success[i])
                ax.plot(tr[:, 0], tr[:, 1], color=SUCCESS_COLOR if ok else FAILURE_COLOR, lw=0.7, alpha=0.8)
        text = name if overlap is None else f"{name}\noverlap {overlap:.3f}"
        if col > 0 and row.notes.get(name):
            text += f" ({row.notes[name]})"
        ax.set_title(text, fontsize=8)
        ax.set_aspect("equal")


def _legend_handles(rows: Sequence[ModeMapRow], mode_names: Sequence[str] | None) -> list[Any]:
    """The legend of :func:`plot_mode_maps`: each mode's colour, and the rollouts' when a row has any."""
    k_max = max(int(r.model.num_modes) for r in rows)
    names = list(mode_names) if mode_names is not None else ["free space", *(f"polygon {m}" for m in range(1, k_max))]
    handles = [key_patch(f"mode {m}: {names[m]}", facecolor=MODE_COLORS[m], edgecolor="0.4") for m in range(k_max)]
    if any(len(r.trajectories) for r in rows):
        handles += [
            key_line("rollout, success", color=SUCCESS_COLOR),
            key_line("rollout, failure", color=FAILURE_COLOR),
        ]
    return handles


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
        model: the env's task model (``env.unwrapped.model``).
        predictors: panel title -> object with ``predict(states) -> modes``.
        path: output ``.png`` path.
        resolution: grid side (the overlap metric uses 200).
        trajectories: ``(T_i, 2)`` paths drawn on every panel (e.g. the demos).
        trajectory_success: colours those paths blue (success) / red (failure).
        title: figure title.
    """
    if Path(path).suffix != ".png":
        raise ValueError(f"path must end in .png, got {str(path)!r}")
    if not isinstance(predictors, Mapping):
        raise TypeError(f"predictors must be a mapping name -> predictor, got {type(predictors).__name__}")
    for name, p in predictors.items():
        if not hasattr(p, "predict"):
            raise TypeError(f"predictor {name!r} has no predict(states) method")
    grid = workspace_grid(model.low, model.high, resolution)
    panels = {name: np.asarray(p.predict(grid)) for name, p in predictors.items()}
    row = ModeMapRow(model, panels, "ground truth", trajectories, trajectory_success)
    return plot_mode_maps(
        [row], path, resolution=resolution, title=title, panel_size=panel_size, trajectories_on_every_panel=True
    )


__all__ = [
    "FAILURE_COLOR",
    "MODE_COLORS",
    "SUCCESS_COLOR",
    "ModeMapRow",
    "decode_labels",
    "encode_labels",
    "plot_groundings",
    "plot_mode_maps",
]
