"""Figure helpers: a headless matplotlib figure, atomic PNG writing, legend entries and a shared legend.

Every figure of the package is made by :func:`new_figure` (matplotlib's
object API on the Agg canvas: no pyplot state, no display needed) and written
by :func:`save_figure` (PNG, atomically, so a killed process leaves no torn
file). :func:`key_line` and :func:`key_patch` make legend entries for marks
drawn without labels; :func:`figure_legend` puts one legend below a grid of panels.

>>> import tempfile
>>> from pathlib import Path
>>> fig = new_figure(3.0, 2.0)
>>> _ = fig.add_subplot().plot([0, 1], [1, 0])
>>> with tempfile.TemporaryDirectory() as tmp:
...     save_figure(fig, Path(tmp) / "line.png").read_bytes()[:4]
b'\x89PNG'
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

from steer_envs.io import atomic_write_bytes

__all__ = ["FigureLayout", "figure_legend", "key_line", "key_patch", "new_figure", "save_figure"]

#: matplotlib layout engines :func:`new_figure` accepts (``None``: place axes by hand)
FigureLayout = Literal["constrained", "tight"] | None


def new_figure(width: float = 7.0, height: float = 4.0, *, layout: FigureLayout = "constrained") -> Any:
    """A matplotlib ``Figure`` (100 dpi) on an Agg canvas, safe in headless worker processes.

    ``layout`` is matplotlib's layout engine: ``"constrained"`` (default),
    ``"tight"`` (for grids of image panels) or ``None``.

    >>> new_figure(4.0, 3.0).get_size_inches().tolist()
    [4.0, 3.0]
    """
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
            raise ValueError(f"{name} must be a positive number of inches, got {value!r}")
    if layout not in ("constrained", "tight", None):
        raise ValueError(f"layout must be 'constrained', 'tight' or None, got {layout!r}")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=100, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Any, path: str | os.PathLike[str]) -> Path:
    """Render ``fig`` to PNG and write it atomically to ``path`` (parent folders created); returns the path.

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     save_figure(new_figure(1.0, 1.0), Path(tmp) / "sub" / "empty.png").name
    'empty.png'
    """
    if Path(path).suffix.lower() != ".png":
        raise ValueError(f"path must end in .png, got {str(path)!r}")
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def key_line(label: str, **style: Any) -> Any:
    """A legend entry drawn as a line or marker (``Line2D`` keywords: ``color``, ``ls``, ``marker``, ...).

    >>> key_line("sketch", color="magenta", lw=2).get_label()
    'sketch'
    """
    from matplotlib.lines import Line2D

    return Line2D([], [], label=label, **style)


def key_patch(label: str, **style: Any) -> Any:
    """A legend entry drawn as a filled box (``Patch`` keywords: ``facecolor``, ``edgecolor``, ...)."""
    from matplotlib.patches import Patch

    return Patch(label=label, **style)


def figure_legend(fig: Any, handles: Sequence[Any], *, ncol: int | None = None, fontsize: float = 7) -> Any:
    """One legend for a grid of panels, below them (outside every panel, so it covers no data).

    ``handles``: artists with labels, e.g. from :func:`key_line` / :func:`key_patch`.
    Needs the ``"constrained"`` layout of :func:`new_figure` (it makes room).
    """
    if not handles:
        raise ValueError("handles must not be empty")
    renderer = fig.canvas.get_renderer()
    cols = ncol if ncol is not None else min(len(handles), 4)
    while True:  # fewer columns until the legend fits the figure's width
        legend = fig.legend(
            handles=list(handles), loc="outside lower center", ncol=cols, fontsize=fontsize, frameon=False
        )
        if cols == 1 or legend.get_window_extent(renderer).width <= 0.98 * fig.bbox.width:
            return legend
        legend.remove()
        cols -= 1
