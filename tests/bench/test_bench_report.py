"""Aggregation and rendering of records: statistics, references and differences, goals, formats, plots."""

from __future__ import annotations

import json
import statistics

import pytest

from steer_envs.bench.plots import metric_bar_chart, write_plots
from steer_envs.bench.report import goal_lines, render, render_markdown, summarize


def _rec(suite, env, method, seed, metrics, params=None):
    return {"config": {"suite": suite, "env": env, "method": method, "params": params or {}}, "seed": seed,
            "metrics": metrics, "key": f"{suite}-{env}-{method}-{seed}-{json.dumps(params)}"}  # fmt: skip


def test_statistics_references_and_differences(toy_suite):
    values = [0.5, 1.0, 2.5]
    records = [_rec("toy", "toy/B-v0", "b", s, {"value": v, "flag": None}) for s, v in enumerate(values)]
    (table,) = summarize(records)
    (row,) = table.rows
    stat = row.stats["value"]
    assert (stat.n, stat.mean, stat.min, stat.max) == (3, pytest.approx(4 / 3), 0.5, 2.5)
    assert stat.std == pytest.approx(statistics.stdev(values))
    assert row.stats["flag"] is None
    assert row.references["value"].value == 1.5 and row.diff("value") == pytest.approx(4 / 3 - 1.5)
    md = render_markdown([table])
    header = [c.strip() for c in md.splitlines()[4].strip("|").split("|")]
    assert header == ["env", "method", "n", "value", "value (ref)", "Δ value", "flag"]
    assert "1.333 ± 1.041" in md and "1.500" in md and "-0.167" in md and "toy ref Bb" in md


def test_goal_lines_name_the_failing_cells():
    records = [
        _rec("smoke", "steer_envs/A-v0", "expert", 0, {"vec_speedup": 35.0}),
        _rec("smoke", "steer_envs/B-v0", "expert", 0, {"vec_speedup": 12.0}),
        _rec("smoke", "steer_envs/C-v0", "expert", 0, {"vec_speedup": None}),
    ]
    (table,) = summarize(records)
    assert goal_lines(table) == ["goal vec_speedup >= 20: 1/2 cells pass (below: B-v0 / expert)"]


def test_unregistered_suite_and_varying_params():
    records = [
        _rec("elsewhere", None, "m", 0, {"z": 1.0, "a": 2.0}, {"k": 1}),
        _rec("elsewhere", None, "m", 1, {"z": 3.0, "a": 2.0}, {"k": 1}),
        _rec("elsewhere", None, "m", 0, {"z": 5.0, "a": 2.0}, {"k": 2}),
    ]
    (table,) = summarize(records)
    assert [m.name for m in table.metrics] == ["a", "z"] and table.varying_params == ["k"]
    assert [(r.params["k"], r.trials, r.stats["z"].mean) for r in table.rows] == [(1, 2, 2.0), (2, 1, 5.0)]
    assert "| k |" in render_markdown([table]).replace("  ", " ")
    rows = json.loads(render([table], "json"))["rows"]
    assert {(r["params"]["k"], r["metric"]) for r in rows} == {(1, "a"), (1, "z"), (2, "a"), (2, "z")}
    with pytest.raises(ValueError, match="format must be one of"):
        render([table], "xml")


def test_bar_chart_marks_references(tmp_path, toy_suite):
    pytest.importorskip("matplotlib")
    records = [_rec("toy", e, m, s, {"value": s + (m == "b"), "flag": None})
               for e in ("toy/A-v0", "toy/B-v0") for m in "ab" for s in range(2)]  # fmt: skip
    (table,) = summarize(records)
    path = metric_bar_chart(table, "value", tmp_path / "v.png")
    assert path is not None and path.read_bytes()[:4] == b"\x89PNG"
    assert metric_bar_chart(table, "flag", tmp_path / "f.png") is None  # no values: no figure
    with pytest.raises(ValueError, match="no metric"):
        metric_bar_chart(table, "nope", tmp_path / "n.png")
    assert [p.name for p in write_plots(records, tmp_path / "all")] == ["toy_value.png"]


def test_stat_of_values_at_the_top_of_the_float_range() -> None:
    """The mean of three max floats is the max float (a plain fsum, even of value / n, overflows)."""
    import sys

    from steer_envs.bench.report import Stat

    top = sys.float_info.max
    stat = Stat.of([top, top, top])
    assert stat.mean == top and stat.std == 0.0
    assert Stat.of([top, -top, 5e-324]).mean == 0.0


def test_a_quick_tour_run_is_not_judged() -> None:
    """A table at the quick tour's reduced settings prints its verdicts as not judged, saying why."""
    from steer_envs.bench.report import Row, Table, finding_lines, judged, reduced_settings
    from steer_envs.bench.suite import Finding, get_suite

    suite = get_suite("tli-arm-scoop")
    quick = suite.resolve_params({}, base=suite.quick).to_json()
    full = suite.defaults.to_json()
    seeds = list(range(suite.default_seeds))

    def table(params: dict) -> Table:
        rows = [Row("steer_envs/ArmScoop-v0", "ltl-ds+mod", params, len(seeds), seeds, {}, {})]
        out = Table(suite.name, "", [], rows, [], default_seeds=suite.default_seeds)
        out.reduced = reduced_settings(suite, rows)
        out.findings = [Finding("a claim", False, "measured")]
        return out

    assert reduced_settings(suite, table(quick).rows) == ["n_episodes=2"] and not judged(table(quick))
    assert finding_lines(table(quick)) == [
        "finding not judged (the quick tour's reduced n_episodes=2; on these it fails): a claim (measured)"
    ]
    assert reduced_settings(suite, table(full).rows) == [] and judged(table(full))
    assert finding_lines(table(full)) == ["finding FAILS: a claim (measured)"]
