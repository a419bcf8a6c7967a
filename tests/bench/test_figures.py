"""Every figure the suites and examples write has a title, a legend and labelled numeric axes.

Each plot function runs on small synthetic records; every figure it saves is
caught at ``Figure.savefig`` and checked with
:func:`steer_envs.bench.plots.figure_problems` (title, legend, axis labels,
no legend over a bar, no blank bar chart).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("matplotlib")


from bench_helpers import check_figures

from steer_envs.bench.plots import figure_problems, metric_bar_chart, write_plots
from steer_envs.bench.report import summarize
from steer_envs.bench.suite import get_suite
from steer_envs.utils.plots import new_figure

ROOT = Path(__file__).resolve().parents[2]


def _record(suite: str, method: str | None, seed: int, metrics: dict[str, Any], **extra: Any) -> dict[str, Any]:
    env = extra.pop("env", None)
    return {
        "config": {"suite": suite, "env": env, "method": method, "params": {}},
        "seed": seed,
        "metrics": metrics,
        "extra": extra,
    }


# ------------------------------------------------------------------ the checker itself
def test_figure_problems_finds_what_a_reader_would_miss() -> None:
    fig = new_figure(4.0, 3.0)
    ax = fig.add_subplot()
    ax.bar([0, 1, 2], [1.0, 1.0, 1.0], label="a bar")
    ax.legend(loc="center")  # right over the middle bar
    problems = figure_problems(fig)
    assert "no title" in problems and "panel 0: the legend covers 1 bar(s)" in problems
    assert "panel 0: the y axis has numbers but no label" in problems
    assert "panel 0: the x axis has numbers but no label" in problems  # bar positions 0, 1, 2: numbers
    fig = new_figure(4.0, 3.0)
    ax = fig.add_subplot()
    ax.bar(["a", "b"], [0.0, 0.0], label="zero")
    ax.set_title("all zero")
    ax.set_ylabel("value")
    ax.legend()
    assert figure_problems(fig) == ["panel 0: every bar is empty and no value is written"]


# ------------------------------------------------------------------ bench figures
def test_metric_bar_charts_label_every_bar_and_keep_the_legend_off_the_bars(saved: list[Any], tmp_path: Path) -> None:
    records = [
        _record("smoke", "expert", s, {"success": 1.0, "violation": 0.0, "env_sps": 1000.0 + s}, env=f"steer_envs/{e}")
        for e in ("ConvexMode-v0", "SoupScoop-v0", "Cooking-v0")
        for s in range(2)
    ]
    (table,) = summarize(records)
    metric_bar_chart(table, "violation", tmp_path / "violation.png")  # an all-zero metric still shows
    metric_bar_chart(table, "success", tmp_path / "success.png")  # bars up to the goal line: no legend on top
    check_figures(saved, 2)
    (violation,) = saved[0].axes
    assert "0" in [t.get_text() for t in violation.texts]  # the value is written on the empty bar


def test_smoke_throughput_figure(saved: list[Any], tmp_path: Path) -> None:
    records = [
        _record("smoke", "expert", s, {"env_sps": 1000.0 + s, "vec_sps": vec}, env=f"steer_envs/{name}")
        for name, vec in (("ConvexMode-v0", 50_000.0), ("Maze2D-Umaze-v0", None))
        for s in range(2)
    ]
    assert len(get_suite("smoke").figures(records, str(tmp_path))) == 1
    check_figures(saved, 1)


def test_write_plots_every_figure_of_a_report(saved: list[Any], tmp_path: Path) -> None:
    records = [
        _record("selftest", m, 0, {"pi": v, "abs_error": abs(v - np.pi)}) for m, v in (("mc", 3.1), ("qmc", 3.14))
    ]
    assert len(write_plots(records, tmp_path)) == 2
    check_figures(saved, 2)


def test_itps_figures(saved: list[Any], tmp_path: Path) -> None:
    from steer_envs.bench.suites.itps.plots import plot_itps

    rng = np.random.default_rng(0)
    records = []
    for method in ("DP-RS", "DP-SS", "ACT-OP"):
        plans = np.cumsum(rng.normal(0.0, 0.2, size=(4, 8, 2)), axis=1) + np.array([3.0, 3.0])
        extra = {
            "plans": plans.tolist(),
            "collides": [False, True, False, False],
            "distances": rng.uniform(0.1, 0.5, size=4).tolist(),
            "sketch": (np.linspace([3.0, 3.0], [5.0, 6.0], 6)).tolist(),
            "start": [3.0, 3.0],
            "perturbed_state": [3.5, 3.2] if method == "ACT-OP" else None,
        }
        metrics = {"avg_l2": 0.2, "min_l2": 0.1, "collision": 0.05}
        records.append(_record("itps-maze2d", method, 0, metrics, env="steer_envs/Maze2D-Large-v0", **extra))
    assert len(plot_itps(get_suite("itps-maze2d"), records, str(tmp_path))) == 2
    check_figures(saved, 2)


def test_itps_scaling_figure(saved: list[Any], tmp_path: Path) -> None:
    from steer_envs.bench.suites.itps.scaling import _plot

    records = [
        _record("itps-maze2d-scaling", m, 0, {"collision_RS": c, "collision_SS": c / 2})
        for m, c in {"w16@0.5M": 0.6, "w16@1M": 0.4}.items()
    ]
    assert len(_plot(get_suite("itps-maze2d-scaling"), records, str(tmp_path))) == 1
    check_figures(saved, 1)


def test_itps_blockstack_figures(saved: list[Any], tmp_path: Path) -> None:
    from steer_envs.bench.suites.itps_blockstack.plots import plot_blockstack

    rng = np.random.default_rng(0)
    records = []
    for method in ("DP-RS", "DP-SS"):
        plans = rng.uniform(-0.1, 0.1, size=(3, 6, 4))
        plans[:, 3:, 3] = 1.0  # the gripper closes half way
        item = {
            "cube_pos": rng.uniform(-0.1, 0.1, size=(4, 3)).tolist(),
            "plans": plans.tolist(),
            "chosen": 1,
            "aligned": method == "DP-SS",
            "success": True,
            "sketch": rng.uniform(-0.1, 0.1, size=(5, 3)).tolist(),
            "eef": [0.0, 0.0, 0.1],
            "intended": "pick_1",
        }
        metrics = {"TA": 0.5, "CS": 0.5, "AS": 0.4, "AF": 0.1, "MS": 0.3, "MF": 0.2}
        records.append(_record("itps-blockstack", method, 0, metrics, plans=[item]))
    assert len(plot_blockstack(get_suite("itps-blockstack"), records, str(tmp_path))) == 2
    check_figures(saved, 2)


def _cut() -> dict[str, Any]:
    return {"point": [0.0, 0.0], "normal": [1.0, 0.0]}


def test_tli_figures(saved: list[Any], tmp_path: Path) -> None:
    from steer_envs.bench.suites.tli.plots import plot_scoop, plot_single_mode

    square = [[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]]
    panel = {
        "vertices": square,
        "attractor": [0.0, 0.0],
        "demos": [[[-1.5, -1.5], [0.0, 0.0]]],
        "paths": [[[-1.0, 1.0], [0.0, 0.0]], [[1.0, 1.0], [2.5, 2.5]]],
        "success": [1, 0],
        "left": [0, 1],
        "failures": [[2.1, 2.1]],
        "cuts": [_cut()],
        "cut_points": [[1.9, 1.9]],
        "success_rate": 0.5,
        "num_cuts": 1,
    }
    single = [_record("tli-single-mode", m, 0, {}, figure={"0.0": panel, "5.0": panel}) for m in ("ds", "ds+mod")]
    assert len(plot_single_mode(get_suite("tli-single-mode"), single, str(tmp_path))) == 1
    scoop_panel = {
        "segments": [[[2.0, 2.0], [5.0, 5.0]], [[6.0, 5.0], [8.0, 8.0]]],
        "pushes": [{"from": [5.0, 5.0], "to": [6.0, 5.0]}],
        "cuts": {"a": [_cut()]},
        "attractors": {"a": [8.0, 8.0]},
        "failures": [[6.0, 5.0]],
        "success": True,
        "invariance_failures": 1,
    }
    scoop = [_record("tli-scoop", m, 0, {}, figure=scoop_panel) for m in ("ltl-ds", "ltl-ds+mod")]
    assert len(plot_scoop(get_suite("tli-scoop"), scoop, str(tmp_path))) == 1
    check_figures(saved, 2)


def test_tli_task_figures(saved: list[Any], tmp_path: Path) -> None:
    from steer_envs.bench.suites.tli_cooking.plots import plot_cooking
    from steer_envs.bench.suites.tli_inspection.plots import plot_inspection

    episode = {
        "trace": [[[-5.0, -5.0], [0.0, 0.0]], [[1.0, 0.0], [5.0, 5.0]]],
        "pushes": [{"from": [0.0, 0.0], "to": [1.0, 0.0]}],
        "success": True,
        "mode_path": ["w0", "y0", "dc"],
    }
    cooking = [
        _record("tli-cooking", m, 0, {}, figure={"clean": episode, "push": episode, "attractors": {"a": [1.0, 1.0]}})
        for m in ("phi_cb", "phi_cc")
    ]
    assert len(plot_cooking(get_suite("tli-cooking"), cooking, str(tmp_path))) == 1
    inspection = [
        _record("tli-inspection", m, 0, {}, figure={"episodes": [episode, {**episode, "success": False}]})
        for m in ("vanilla-ds", "ltl-ds")
    ]
    assert len(plot_inspection(get_suite("tli-inspection"), inspection, str(tmp_path))) == 1
    check_figures(saved, 2)


def test_glide_mode_maps_keep_red_for_failures(saved: list[Any], tmp_path: Path) -> None:
    import gymnasium as gym
    from matplotlib.colors import to_rgb

    import steer_envs  # noqa: F401
    from steer_envs.baselines.glide import workspace_grid
    from steer_envs.bench.suites.glide.plots import FAILURE_COLOR, MODE_COLORS, ModeMapRow, plot_mode_maps

    env = gym.make("steer_envs/PolygonNav-4Mode-v0", layout_seed=0)
    model, modes = env.unwrapped.model, env.unwrapped.task.modes  # type: ignore[attr-defined]
    env.close()
    learned = np.asarray(model.mode_of(workspace_grid(model.low, model.high, 40)))
    paths = [np.linspace(model.low, model.high, 5), np.linspace(model.high, model.low, 5)]
    row = ModeMapRow(model, {"learned": learned}, "layout 0", paths, [True, False])
    plot_mode_maps([row], tmp_path / "modes.png", resolution=40, mode_names=modes)
    check_figures(saved, 1)
    labels = [t.get_text() for t in saved[0].legends[0].get_texts()]
    assert labels[:4] == [f"mode {m}: {name}" for m, name in enumerate(modes)] and "rollout, failure" in labels
    red = np.array(to_rgb(FAILURE_COLOR))
    assert all(np.abs(np.array(to_rgb(c)) - red).sum() > 0.5 for c in MODE_COLORS)  # no mode is drawn red
    with pytest.raises(ValueError, match="mode_names"):
        plot_mode_maps([row], tmp_path / "modes.png", resolution=40, mode_names=["free"])


def test_glide_robosuite_mode_strips(saved: list[Any], tmp_path: Path) -> None:
    from steer_envs.bench.suites.glide_robosuite.plots import save_mode_strips

    demo = {"pred": [0, 0, 1, 1, 2], "true": [0, 1, 1, 2, 2]}
    save_mode_strips({"full": [demo, demo]}, "lift", "Lift", tmp_path / "strips.png")
    check_figures(saved, 1)


# ------------------------------------------------------------------ example figures
def _example(name: str) -> Any:
    spec = importlib.util.spec_from_file_location(f"example_{name}", ROOT / "examples" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_envs_tour_frame_has_a_title_mode_names_and_the_push(saved: list[Any], tmp_path: Path) -> None:
    tour = _example("envs_tour")
    episode = tour.run_episode("steer_envs/PolygonNav-3Mode-v0", 0)
    assert episode.push is not None
    fig = tour.tour_figure("steer_envs/PolygonNav-3Mode-v0", episode)
    assert figure_problems(fig) == []
    (ax,) = fig.axes
    assert " -> ".join(episode.modes) in ax.get_title() and "PolygonNav-3Mode-v0" in fig._suptitle.get_text()
    assert any("push" in t.get_text() for t in fig.legends[0].get_texts())


def test_steer_maze2d_figure_explains_its_colours(saved: list[Any]) -> None:
    steer = _example("steer_maze2d")
    image = np.zeros((40, 40, 3), dtype=np.uint8)
    fig = steer.steering_figure(image, image, "Maze2D-Large, DP steered with SS (seed 0)")
    assert figure_problems(fig) == []
    labels = " ".join(t.get_text() for t in fig.legends[0].get_texts())
    for word in ("sketch", "sampled plan", "collision", "rollout", "agent", "wall"):
        assert word in labels
