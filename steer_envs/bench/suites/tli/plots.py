"""Figures of the TLI suites: rollouts, cuts and failures per policy (thesis Fig. 3.4 and Fig. 3.6).

* :func:`single_mode_figure_data` recomputes one single-mode trial of
  :func:`~steer_envs.bench.suites.tli.protocol.single_mode_trial` with the
  rollouts kept (same demonstrations, fit, starts and cut loop; a test checks
  that the success rate and the cuts agree) as compact JSON for a record's ``extra``.
* :func:`plot_single_mode` draws, per layout, a grid policy (rows: BC,
  BC+mod, DS, DS+mod) x noise level (columns): the convex mode, the
  demonstrations (black), rollouts (blue: success, red: failure), failures as
  red crosses (the first state outside the mode), the cuts (green lines) and the
  last in-mode states they go through (yellow circles), the attractor (orange),
  all named in a legend below the grid.
* :func:`plot_scoop` draws SoupScoop rollouts of LTL-DS without and with
  modulation under pushes (purple dashed jumps), invariance failures (red crosses)
  and the learned cuts.

Figures come from :func:`steer_envs.bench.plots.new_figure` and are written
with :func:`steer_envs.bench.plots.save_figure`.

>>> plot_scoop(None, [], "unused")  # no record keeps figure data: nothing to draw
[]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.plots import recorded_figures
from steer_envs.utils.plots import figure_legend, key_line, key_patch, new_figure, save_figure

__all__ = [
    "NOISE_LABELS",
    "plot_scoop",
    "plot_single_mode",
    "scoop_figure_data",
    "single_mode_figure_data",
]

#: noise level (start-state sigma, workspace units) -> the thesis's label (% of the workspace).
NOISE_LABELS: Mapping[float, str] = {0.0: "0%", 1.0: "5%", 5.0: "30%"}
_ROW_ORDER = ("bc", "bc+mod", "ds", "ds+mod")
#: colour of a push (red is a failure's)
_PUSH = "#9467bd"


# ---------------------------------------------------------------------- data
def _round(a: np.ndarray, digits: int = 3) -> list[Any]:
    return np.round(np.asarray(a, dtype=np.float64), digits).tolist()


def _trace(policy: Any, model: Any, starts: np.ndarray, n_steps: int, every: int) -> np.ndarray:
    """States ``(N, n_steps // every + 1, 2)`` under ConvexMode's dynamics (as ``single_mode.rollout``), thinned."""
    from steer_envs.baselines.lpv_ds.single_mode import DT, MAX_SPEED

    x = np.asarray(starts, dtype=np.float64).copy()
    out = [x.copy()]
    for t in range(1, n_steps + 1):
        v = np.asarray(policy(x), dtype=np.float64)
        speed = np.linalg.norm(v, axis=1, keepdims=True)
        v = v * np.minimum(1.0, MAX_SPEED / np.maximum(speed, 1e-300))
        x = np.clip(x + DT * v, model.low, model.high)
        if t % every == 0:
            out.append(x.copy())
    return np.stack(out, axis=1)


def single_mode_figure_data(
    layout_seed: int,
    noise_sigma: float,
    policy_kind: str,
    n_demos: int,
    *,
    n_starts: int = 100,
    seed: int = 0,
    bc_epochs: int = 4000,
    max_cuts: int = 4,
    demos: str = "drawn",
    n_paths: int = 40,
    every: int = 20,
) -> dict[str, Any]:
    """The rollouts of one single-mode trial (``cut_sigma=None``) as JSON-able plot data.

    Mirrors :func:`~steer_envs.bench.suites.tli.protocol.single_mode_trial`: the
    same demonstrations, policy fit, start states and cut loop. Keeps the first
    ``n_paths`` rollouts, subsampled every ``every`` steps (3 decimals).

    Keys: ``vertices``, ``attractor``, ``demos``, ``paths``, ``success`` and
    ``left`` (per kept path), ``failures`` (first state outside, per failed kept
    path), ``cuts`` (``point``, ``normal``), ``cut_points`` (last in-mode states
    of the cut failures), ``success_rate`` (over all starts), ``num_cuts``.
    """
    from steer_envs.baselines.lpv_ds.single_mode import N_STEPS, cut_loop, fitted_policy, rollout, sample_starts
    from steer_envs.bench.suites.tli.protocol import POLICY_KINDS

    if policy_kind not in POLICY_KINDS:
        raise ValueError(f"policy_kind must be one of {POLICY_KINDS}, got {policy_kind!r}")
    policy, model, xs = fitted_policy(
        int(layout_seed), int(n_demos), policy_kind.split("+")[0], int(bc_epochs), int(seed), demos
    )
    demo_points = np.concatenate(xs)
    rng = np.random.default_rng([int(seed), int(layout_seed), 1])
    starts = sample_starts(model, demo_points, float(noise_sigma), n_starts, rng)
    loop = cut_loop(policy, model, starts, max_cuts=max_cuts if policy_kind.endswith("+mod") else None)
    acting, cuts, failures = loop.policy, loop.cuts, loop.failures
    res = loop.last_rollout if loop.last_rollout is not None else rollout(acting, model, starts, N_STEPS)
    keep = slice(0, min(n_paths, n_starts))
    paths = _trace(acting, model, starts[keep], N_STEPS, every)
    failed = res["left"][keep]
    return {
        "vertices": _round(model.vertices),
        "attractor": _round(model.attractor),
        "demos": [_round(x[::5]) for x in xs],
        "paths": _round(paths),
        "success": res["success"][keep].astype(int).tolist(),
        "left": failed.astype(int).tolist(),
        "failures": _round(res["first_out"][keep][failed].reshape(-1, 2)),
        "cuts": [{"point": _round(c.point), "normal": _round(c.normal, 6)} for c in cuts.cuts],
        "cut_points": _round(np.array([fr.last_in_mode for fr in failures]).reshape(-1, 2)),
        "success_rate": float(res["success"].mean()),
        "num_cuts": len(cuts),
    }


def scoop_figure_data(result: Mapping[str, Any], every: int = 5) -> dict[str, Any]:
    """Compact plot data from a ``scoop_trial(..., record=True)`` result (trajectory subsampled every ``every``)."""
    segments = [np.asarray(s, dtype=np.float64) for s in result["trajectory"]]
    thin = [_round(np.concatenate([s[::every], s[-1:]])) for s in segments if len(s)]
    return {
        "segments": thin,
        "pushes": [{"from": _round(p["from"]), "to": _round(p["to"])} for p in result["push_log"]],
        "cuts": {
            m: [{"point": _round(c["point"]), "normal": _round(c["normal"], 6)} for c in cs]
            for m, cs in result["cuts"].items()
        },
        "attractors": {m: _round(a) for m, a in result["attractors"].items()},
        "failures": [_round(e["before"]) for e in result["events"] if e["kind"] == "failure"],
        "success": bool(result["success"]),
        "invariance_failures": int(result["invariance_failures"]),
    }


# -------------------------------------------------------------------- drawing
def _draw_cut(ax: Any, point: Sequence[float], normal: Sequence[float], half: float, **style: Any) -> None:
    p, n = np.asarray(point, dtype=np.float64), np.asarray(normal, dtype=np.float64)
    t = np.array([-n[1], n[0]])
    seg = np.stack([p - half * t, p + half * t])
    ax.plot(seg[:, 0], seg[:, 1], **style)


def _draw_single_panel(ax: Any, data: Mapping[str, Any], title: str) -> None:
    from matplotlib.patches import Polygon

    verts = np.asarray(data["vertices"])
    ax.add_patch(Polygon(verts, closed=True, facecolor="#eeeeee", edgecolor="0.3", linewidth=1.0, zorder=0))
    for path, ok in zip(data["paths"], data["success"], strict=True):
        p = np.asarray(path)
        ax.plot(p[:, 0], p[:, 1], color="#1f5fbf" if ok else "#d62728", linewidth=0.6, alpha=0.7, zorder=2)
    for demo in data["demos"]:
        d = np.asarray(demo)
        ax.plot(d[:, 0], d[:, 1], color="black", linewidth=1.6, zorder=3)
    fails = np.asarray(data["failures"]).reshape(-1, 2)
    if len(fails):
        ax.plot(fails[:, 0], fails[:, 1], "x", color="#d62728", markersize=5, zorder=4)
    span = float(np.ptp(verts, axis=0).max())
    for cut in data["cuts"]:
        _draw_cut(ax, cut["point"], cut["normal"], 0.6 * span, color="#2ca02c", linewidth=1.6, zorder=5)
    pts = np.asarray(data["cut_points"]).reshape(-1, 2)
    if len(pts):
        ax.plot(pts[:, 0], pts[:, 1], "o", markerfacecolor="#ffd700", markeredgecolor="black", markersize=5, zorder=6)
    att = np.asarray(data["attractor"])
    ax.plot(att[0], att[1], "*", color="#ff8c00", markersize=12, markeredgecolor="black", zorder=7)
    lo, hi = verts.min(axis=0) - 1.0, verts.max(axis=0) + 1.0
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=8)


def plot_single_mode(suite: Any, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """The Fig. 3.4-style grid per plotted layout (records with ``extra["figure"]``); returns the PNG paths."""
    by_layout: dict[int, dict[str, Mapping[str, Any]]] = {}
    for (layout, method), fig_data in recorded_figures(records).items():
        by_layout.setdefault(layout, {})[method] = fig_data
    written = []
    for layout, per_method in sorted(by_layout.items()):
        methods = [m for m in _ROW_ORDER if m in per_method] + sorted(set(per_method) - set(_ROW_ORDER))
        noises = sorted({k for m in methods for k in per_method[m]}, key=float)
        fig = new_figure(2.6 * len(noises), 2.5 * len(methods))
        axes = fig.subplots(len(methods), len(noises), squeeze=False)
        for i, method in enumerate(methods):
            for j, noise in enumerate(noises):
                data = per_method[method].get(noise)
                ax = axes[i][j]
                if data is None:
                    ax.set_axis_off()
                    continue
                label = NOISE_LABELS.get(float(noise), f"sigma {noise}")
                cuts = f", {data['num_cuts']} cuts" if method.endswith("+mod") else ""
                _draw_single_panel(ax, data, f"{method}, noise {label}: {100 * data['success_rate']:.0f}%{cuts}")
        fig.suptitle(
            f"{getattr(suite, 'name', 'tli-single-mode')}: layout {layout}, rollouts per policy and start noise",
            fontsize=9,
        )
        figure_legend(
            fig,
            [
                key_patch("mode (convex region)", facecolor="#eeeeee", edgecolor="0.3"),
                key_line("demonstration", color="black", lw=1.6),
                key_line("rollout, success", color="#1f5fbf", lw=1),
                key_line("rollout, failure", color="#d62728", lw=1),
                key_line("first state outside", color="#d62728", marker="x", ls="none"),
                key_line("cut (learned boundary)", color="#2ca02c", lw=1.6),
                key_line("last in-mode state", marker="o", markerfacecolor="#ffd700", color="black", ls="none"),
                key_line("attractor", marker="*", color="#ff8c00", markeredgecolor="black", ls="none", markersize=10),
            ],
            ncol=4,
        )
        name = f"{getattr(suite, 'name', 'tli-single-mode')}_rollouts_layout{layout}.png"
        written.append(str(save_figure(fig, Path(out_dir) / name)))
    return written


def _draw_scoop_regions(ax: Any) -> None:
    from matplotlib.patches import Circle, Rectangle

    from steer_envs.envs.soup_scoop import SoupScoopModel

    model = SoupScoopModel()
    colors = {"yellow": "#fff3a0", "pink": "#f7c6d9", "green": "#c8f0c0"}
    for name, (x0, y0, x1, y1) in model.rects.items():
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor=colors[name], edgecolor="0.5", zorder=0))
    for att in model.region_attractors.values():
        ax.add_patch(
            Circle(
                (float(att[0]), float(att[1])),
                model.attractor_radius,
                facecolor="none",
                edgecolor="0.5",
                linestyle=":",
                zorder=1,
            )
        )
    ax.set_xlim(model.low[0], model.high[0])
    ax.set_ylim(model.low[1], model.high[1])
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def plot_scoop(suite: Any, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """SoupScoop rollouts of LTL-DS (columns: methods, rows: plotted experiments); returns the PNG path."""
    cells = recorded_figures(records)
    if not cells:
        return []
    seeds = sorted({s for s, _ in cells})
    methods = sorted({m for _, m in cells}, key=lambda m: (m.endswith("+mod"), m))
    fig = new_figure(3.2 * len(methods), 3.2 * len(seeds))
    axes = fig.subplots(len(seeds), len(methods), squeeze=False)
    for i, seed in enumerate(seeds):
        for j, method in enumerate(methods):
            ax = axes[i][j]
            data = cells.get((seed, method))
            if data is None:
                ax.set_axis_off()
                continue
            _draw_scoop_regions(ax)
            for seg in data["segments"]:
                s = np.asarray(seg).reshape(-1, 2)
                ax.plot(s[:, 0], s[:, 1], color="black", linewidth=0.8, zorder=3)
            for push in data["pushes"]:
                a, b = np.asarray(push["from"]), np.asarray(push["to"])
                ax.plot([a[0], b[0]], [a[1], b[1]], color=_PUSH, linestyle="--", linewidth=0.9, zorder=4)
                ax.plot(b[0], b[1], "o", color=_PUSH, markersize=3, zorder=4)
            fails = np.asarray(data["failures"]).reshape(-1, 2)
            if len(fails):
                ax.plot(fails[:, 0], fails[:, 1], "x", color="#d62728", markersize=5, zorder=5)
            for cuts in data["cuts"].values():
                for cut in cuts:
                    _draw_cut(ax, cut["point"], cut["normal"], 1.5, color="#1f5fbf", linewidth=1.4, zorder=6)
            for att in {tuple(a) for a in data["attractors"].values()}:
                ax.plot(att[0], att[1], "*", color="#ff8c00", markersize=9, markeredgecolor="black", zorder=7)
            verdict = "success" if data["success"] else "FAILED (cap)"
            ax.set_title(f"{method}, experiment {seed}: {verdict}, {data['invariance_failures']} loops", fontsize=8)
    fig.suptitle(f"{getattr(suite, 'name', 'tli-scoop')}: SoupScoop rollouts under pushes", fontsize=9)
    figure_legend(
        fig,
        [
            key_patch("region yellow", facecolor="#fff3a0", edgecolor="0.5"),
            key_patch("region pink", facecolor="#f7c6d9", edgecolor="0.5"),
            key_patch("region green", facecolor="#c8f0c0", edgecolor="0.5"),
            key_line("rollout", color="black", lw=0.8),
            key_line("push (to the dot)", color=_PUSH, ls="--", marker="o", markersize=3),
            key_line("invariance failure", color="#d62728", marker="x", ls="none"),
            key_line("cut (learned boundary)", color="#1f5fbf", lw=1.4),
            key_line("attractor", marker="*", color="#ff8c00", markeredgecolor="black", ls="none", markersize=9),
        ],
        ncol=4,
    )
    return [str(save_figure(fig, Path(out_dir) / f"{getattr(suite, 'name', 'tli-scoop')}_rollouts.png"))]
