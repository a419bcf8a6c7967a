r"""PNG figures for ``steer-bench report --plots``, and checks of what a figure shows.

One bar chart per (suite, metric): the mean over seeds per cell with the
standard deviation as error bar, the thesis's reference value of each cell
drawn as a red tick across its bar, and the metric's goal as a dashed line.
Suites may add their own figures through ``Suite.plot`` (e.g. throughput of
single vs. vectorized envs, trajectories stored in a record's ``extra``).

Every figure of the package is made by :func:`steer_envs.utils.plots.new_figure`
and written by :func:`steer_envs.utils.plots.save_figure`;
:func:`figure_problems` lists what a reader of a figure would miss.

>>> from steer_envs.utils.plots import new_figure
>>> fig = new_figure(3.0, 2.0)
>>> _ = fig.add_subplot().plot([0, 1], [1, 0])
>>> figure_problems(fig)[:2]
['no title', 'no legend']
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.report import Table, suite_table, summarize
from steer_envs.bench.suite import Suite, get_suite
from steer_envs.utils.plots import figure_legend, new_figure, save_figure


def _numeric_ticks(labels: Sequence[Any]) -> bool:
    """Whether drawn tick labels are numbers (a numeric axis needs a label; category names speak for themselves)."""
    texts = [t.get_text() for t in labels if t.get_visible() and t.get_text()]
    if not texts:
        return False
    for text in texts:
        rest = re.sub(r"\\mathdefault|\\times|[$^{}\s0-9.,+\-\u2212e×%]", "", text)
        if rest or not re.search(r"[0-9]", text):
            return False
    return True


def figure_problems(fig: Any) -> list[str]:
    """What a reader of ``fig`` would miss: a title, a legend, labels of numeric axes, bars hidden or blank.

    Checked (the figure is drawn first): a figure title (``suptitle``, or the
    title of its only panel); a legend (on a panel or the figure), inside the
    figure; an axis
    label on every axis whose tick labels are numbers; no legend inside a
    panel overlapping one of its bars; no bar chart whose bars are all empty
    without their values written on it. Returns one line per problem
    (empty: fine). The figure tests run every figure of the package through it.

    >>> fig = new_figure(3.0, 2.0)
    >>> _ = fig.add_subplot().plot([0, 1], [1, 0])
    >>> for problem in figure_problems(fig):
    ...     print(problem)
    no title
    no legend
    panel 0: the x axis has numbers but no label
    panel 0: the y axis has numbers but no label
    """
    from matplotlib.container import BarContainer

    fig.canvas.draw()
    problems: list[str] = []
    panels = [ax for ax in fig.axes if ax.get_visible()]
    suptitle = fig._suptitle.get_text() if fig._suptitle is not None else ""
    own = [ax.get_title() or ax.get_title(loc="left") for ax in panels if ax.axison or ax.has_data()]
    if not suptitle.strip() and not (len(own) == 1 and own[0].strip()):
        problems.append("no title")
    if not fig.legends and not any(ax.get_legend() is not None for ax in panels):
        problems.append("no legend")
    renderer = fig.canvas.get_renderer()
    legends = [*fig.legends, *(ax.get_legend() for ax in panels if ax.get_legend() is not None)]
    for legend in legends:
        box, page = legend.get_window_extent(renderer), fig.bbox
        if box.x0 < page.x0 - 2 or box.x1 > page.x1 + 2 or box.y0 < page.y0 - 2 or box.y1 > page.y1 + 2:
            problems.append("a legend is cut off at the figure's edge")
    for i, ax in enumerate(panels):
        if not ax.axison or ax.name == "3d":
            continue
        if _numeric_ticks(ax.get_xticklabels()) and not ax.get_xlabel().strip():
            problems.append(f"panel {i}: the x axis has numbers but no label")
        if _numeric_ticks(ax.get_yticklabels()) and not ax.get_ylabel().strip():
            problems.append(f"panel {i}: the y axis has numbers but no label")
        bars = [p for c in ax.containers if isinstance(c, BarContainer) for p in c.patches]
        if bars and all(p.get_height() == 0 and p.get_width() != 0 for p in bars) and not ax.texts:
            problems.append(f"panel {i}: every bar is empty and no value is written")
        legend = ax.get_legend()
        if legend is not None and bars:
            box = legend.get_window_extent(renderer)
            covered = [p for p in bars if p.get_height() != 0 and box.overlaps(p.get_window_extent(renderer))]
            if covered:
                problems.append(f"panel {i}: the legend covers {len(covered)} bar(s)")
    return problems


def recorded_figures(records: Iterable[Mapping[str, Any]]) -> dict[tuple[int, str], Any]:
    """The figure data trials kept (``extra["figure"]``), by ``(seed, method)``, in record order.

    >>> recorded_figures([{"seed": 1, "config": {"method": "a"}, "extra": {"figure": [1]}},
    ...                   {"seed": 0, "config": {"method": "a"}, "extra": {}}])
    {(1, 'a'): [1]}
    """
    figures: dict[tuple[int, str], Any] = {}
    for rec in records:
        data = (rec.get("extra") or {}).get("figure")
        if data:
            figures[(int(rec["seed"]), str(rec["config"]["method"]))] = data
    return figures


def safe_name(text: str) -> str:
    """``text`` reduced to a file-name-safe token.

    >>> safe_name("itps-maze2d / DP-SS")
    'itps-maze2d_DP-SS'
    """
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "plot"


def metric_bar_chart(table: Table, metric: str, path: str | os.PathLike[str]) -> Path | None:
    """Bar chart of ``metric`` across the cells of ``table`` (``None`` when no cell has a value).

    >>> import tempfile
    >>> records = [{"config": {"suite": "selftest", "env": None, "method": m, "params": {}}, "seed": 0,
    ...             "metrics": {"pi": v}} for m, v in (("mc", 3.1), ("stratified", 3.14))]
    >>> (table,) = summarize(records)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     metric_bar_chart(table, "pi", Path(tmp) / "pi.png").name
    'pi.png'
    """
    m = next((x for x in table.metrics if x.name == metric), None)
    if m is None:
        raise ValueError(f"table {table.suite!r} has no metric {metric!r}")
    rows = [r for r in table.rows if r.stats.get(metric) is not None and math.isfinite(r.stats[metric].mean)]  # type: ignore[union-attr]
    if not rows:
        return None
    labels = [r.label(table.varying_params) for r in rows]
    means = [r.stats[metric].mean for r in rows]  # type: ignore[union-attr]
    stds = [s if math.isfinite(s) else 0.0 for s in (r.stats[metric].std for r in rows)]  # type: ignore[union-attr]
    fig = new_figure(max(5.0, 0.9 * len(rows) + 2.5), 4.2)
    ax = fig.add_subplot()
    xs = list(range(len(rows)))
    bars = ax.bar(xs, means, yerr=stds, capsize=3, color="#4C72B0", label="measured (mean ± std over seeds)")
    # the value on every bar: a bar of height 0 (no violation anywhere) is then a "0", not a blank axis
    ax.bar_label(bars, labels=[f"{v:{m.fmt}}" for v in means], fontsize=7, padding=2)
    ref_drawn = False
    for x, r in zip(xs, rows, strict=True):
        ref = r.references.get(metric)
        if ref is not None:
            ax.hlines(
                ref.value,
                x - 0.4,
                x + 0.4,
                colors="#C44E52",
                linewidth=2.5,
                label=None if ref_drawn else f"reference ({ref.source or 'thesis'})",
            )
            ref_drawn = True
    if m.goal is not None:
        ax.axhline(m.goal, color="#55A868", linestyle="--", linewidth=1.5, label=f"goal {m.goal:g}")
    positive = all(v > 0 for v in means)
    if m.kind == "timing" and positive and max(means) / min(means) > 50:
        ax.set_yscale("log")
    ax.set_xticks(xs)
    ax.set_xticklabels(labels, rotation=30 if len(rows) > 3 else 0, ha="right" if len(rows) > 3 else "center")
    if ax.get_yscale() == "linear" and all(v == 0 for v in [*means, *stds]):
        ax.set_ylim(-0.05, 1.0)  # all zero: a visible scale instead of a collapsed one
        ax.text(0.5, 0.6, f"{metric} = 0 in every cell", transform=ax.transAxes, ha="center", fontsize=9)
    ax.set_ylabel(metric)
    ax.set_title(f"{table.suite}: {m.description or metric}", fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    figure_legend(fig, ax.get_legend_handles_labels()[0], ncol=3, fontsize=8)  # below the axes: covers no bar
    return save_figure(fig, path)


def _lookup(name: str) -> Suite | None:
    try:
        return get_suite(name)
    except KeyError:
        return None


def write_plots(
    records: Sequence[Mapping[str, Any]], out_dir: str | os.PathLike[str], *, problems: list[str] | None = None
) -> list[Path]:
    """All figures for ``records``: a bar chart per (suite, metric) plus each suite's own plots.

    A suite's own plot hook that raises does not stop the others: with a
    ``problems`` list, a line naming the suite and the error is added to it
    and the figures go on; without one the error propagates.

    >>> import tempfile
    >>> records = [{"config": {"suite": "selftest", "env": None, "method": "mc", "params": {}}, "seed": 0,
    ...             "metrics": {"pi": 3.1, "abs_error": 0.04}}]
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     sorted(p.name for p in write_plots(records, tmp))
    ['selftest_abs_error.png', 'selftest_pi.png']
    """
    out_dir = Path(out_dir)
    written: list[Path] = []

    def attempt(what: str, draw: Callable[..., Any], *args: Any) -> Any:
        try:
            return draw(*args)
        except Exception as exc:
            if problems is None:
                raise
            detail = " ".join(str(exc).split())[:300]
            problems.append(f"{what} could not be drawn: {type(exc).__name__}: {detail}")
            return None

    for table in summarize(records):
        for m in table.metrics:
            path = out_dir / f"{safe_name(table.suite)}_{safe_name(m.name)}.png"
            drawn = attempt(path.name, metric_bar_chart, table, m.name, path)
            if drawn is not None:
                written.append(drawn)
        suite = _lookup(table.suite)
        if suite is not None and suite.plot is not None:
            suite_records = [r for r in records if r["config"]["suite"] == table.suite]
            paths = attempt(f"the figures of suite {table.suite!r}", suite.figures, suite_records, str(out_dir))
            written += [Path(p) for p in paths or ()]
    return written


_QUADRANTS = (("AS", "tab:green"), ("AF", "tab:olive"), ("MS", "tab:cyan"), ("MF", "tab:gray"))


def quadrant_figure(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> str | None:
    """``<suite>_quadrants.png`` of a skill-steering suite: stacked AS/AF/MS/MF bars per method, thesis TA / CS hollow.

    ``None`` (nothing written) without a measured TA.
    """
    table = suite_table(suite, records)
    rows = [r for r in table.rows if r.stats.get("TA") is not None] if table else []
    if not rows:
        return None
    thesis = {(ref.method, ref.metric): ref.value for ref in suite.references}
    fig = new_figure(1.2 * len(rows) + 2.5, 4.0)
    ax = fig.add_subplot()
    x = np.arange(len(rows))
    bottom = np.zeros(len(rows))
    for name, color in _QUADRANTS:
        values = np.array([(r.stats[name].mean if r.stats.get(name) else 0.0) or 0.0 for r in rows])  # type: ignore[union-attr]
        ax.bar(x, values, bottom=bottom, color=color, label=name, width=0.6)
        bottom += values
    for i, r in enumerate(rows):
        ref_ta, ref_cs = thesis.get((r.method, "TA")), thesis.get((r.method, "CS"))
        if ref_ta is not None and ref_cs is not None:
            ax.scatter([i - 0.15], [ref_ta], facecolors="none", edgecolors="black", marker="o", s=45)
            ax.scatter([i + 0.15], [ref_cs], facecolors="none", edgecolors="black", marker="D", s=40)
    ax.scatter([], [], facecolors="none", edgecolors="black", marker="o", label="thesis TA")
    ax.scatter([], [], facecolors="none", edgecolors="black", marker="D", label="thesis CS")
    ax.set_xticks(x, [r.method or "" for r in rows], fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("share of interactions")
    ax.set_title(f"{suite.name}: aligned / misaligned x success / failure", fontsize=10)
    figure_legend(fig, ax.get_legend_handles_labels()[0], ncol=3)  # below the axes: the stacks reach 1.0
    ax.grid(alpha=0.3, axis="y")
    return str(save_figure(fig, Path(out_dir) / f"{suite.name}_quadrants.png"))
