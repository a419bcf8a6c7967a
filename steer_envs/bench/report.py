"""Aggregate trial records into tables; render them as markdown, CSV or JSON.

Records are grouped by suite, then by cell (env, method, params); each metric
gets mean, standard deviation (ddof=1), min, max and count over the cell's
seeds. Where the suite declares a :class:`~steer_envs.bench.suite.Reference`
(the thesis's number), the table shows it beside the measured mean together
with the difference ``measured - reference``; metrics with a ``goal`` get a
pass/fail line under the table; a suite's ``findings`` hook adds its
qualitative claims (orderings, "within x of") with a verdict each.

>>> records = [{"config": {"suite": "selftest", "env": None, "method": "mc", "params": {}}, "seed": s,
...             "metrics": {"pi": v}} for s, v in enumerate((3.1, 3.2))]
>>> print(render(summarize(records), "csv").splitlines()[1])
selftest,,mc,{},pi,value,2,2,3.1500000000000004,0.07071067811865482,3.1,3.2,3.141592653589793,0.008407346410207...
"""

from __future__ import annotations

import csv
import io
import json
import math
import statistics
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from steer_envs.bench.records import record_problem
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, get_suite

FORMATS: tuple[str, ...] = ("md", "csv", "json")


@dataclass(frozen=True)
class Stat:
    """Summary of one metric over the seeds of one cell."""

    n: int
    mean: float
    std: float
    min: float
    max: float

    @classmethod
    def of(cls, values: Sequence[float]) -> Stat:
        if not values:
            raise ValueError("Stat.of needs at least one value")
        try:
            mean = statistics.fmean(values)
        except OverflowError:  # a sum beyond the float range: average the values scaled by the largest one
            scale = max(abs(v) for v in values)
            mean = scale * (math.fsum(v / scale for v in values) / len(values))
        try:
            std = statistics.stdev(values) if len(values) > 1 else 0.0
        except OverflowError:  # a spread beyond the float range
            std = math.inf
        return cls(len(values), mean, std, min(values), max(values))


@dataclass
class Row:
    """One cell of a table: an (env, method, params) combination over its seeds."""

    env: str | None
    method: str | None
    params: dict[str, Any]
    trials: int
    seeds: list[int]
    stats: dict[str, Stat | None]
    references: dict[str, Reference]

    def label(self, varying: Sequence[str] = ()) -> str:
        """Short name for plots: env without namespace, method, varying params."""
        parts = [p for p in (_short_env(self.env), self.method) if p]
        parts += [f"{k}={self.params.get(k)}" for k in varying]
        return " / ".join(parts) or "-"

    def diff(self, metric: str) -> float | None:
        """Measured mean minus the reference (``None`` without either)."""
        stat, ref = self.stats.get(metric), self.references.get(metric)
        if stat is None or ref is None:
            return None
        return stat.mean - ref.value


@dataclass
class Table:
    """All cells of one suite."""

    suite: str
    description: str
    metrics: list[Metric]
    rows: list[Row] = field(default_factory=list)
    varying_params: list[str] = field(default_factory=list)
    findings: list[Finding] = field(default_factory=list)
    #: the suite's default seed count (the size its findings are meant for); None when unregistered
    default_seeds: int | None = None
    #: ``name=value`` of the quick tour's reduced settings every row ran with (empty: a full-size run)
    reduced: list[str] = field(default_factory=list)

    def referenced_metrics(self) -> list[Metric]:
        """Metrics that have a reference in at least one row."""
        return [m for m in self.metrics if any(m.name in r.references for r in self.rows)]

    def mean(self, metric: str, method: str | None = None, env: str | None = None) -> float | None:
        """Mean of ``metric`` in the one row matching ``method`` / ``env`` (``None`` = any value).

        ``None`` when no row matches or the metric was not measured there;
        ``ValueError`` when several rows match (e.g. a run with varying params).
        """
        rows = [r for r in self.rows if (method is None or r.method == method) and (env is None or r.env == env)]
        if len(rows) > 1:
            raise ValueError(f"{self.suite}: {len(rows)} rows match method={method!r} env={env!r}")
        stat = rows[0].stats.get(metric) if rows else None
        return stat.mean if stat is not None else None

    def means(self, metric: str, methods: Sequence[str], env: str | None = None) -> dict[str, float] | None:
        """``{method: mean of metric}`` for findings; ``None`` unless each method has exactly one measured row."""
        out: dict[str, float] = {}
        for method in methods:
            try:
                value = self.mean(metric, method, env)
            except ValueError:
                return None
            if value is None:
                return None
            out[method] = value
        return out


def _short_env(env: str | None) -> str | None:
    return env.split("/", 1)[1] if env and "/" in env else env


def _lookup(name: str) -> Suite | None:
    try:
        return get_suite(name)
    except KeyError:
        return None


def summarize(records: Iterable[Mapping[str, Any]], *, lookup: Callable[[str], Suite | None] = _lookup) -> list[Table]:
    """Tables (one per suite found in ``records``) of per-cell statistics.

    Suites that are not registered in this process still get a table, with
    metric names taken from the records and no references. Each record must
    pass :func:`~steer_envs.bench.records.record_problem` (``key`` not needed);
    ``ValueError`` names the first one that does not.

    >>> rec = {"config": {"suite": "mine", "env": None, "method": "a", "params": {}}, "seed": 0, "metrics": {"x": 2.0}}
    >>> (table,) = summarize([rec])
    >>> table.suite, table.mean("x", "a")
    ('mine', 2.0)
    """
    if isinstance(records, (str, bytes, Mapping)) or not isinstance(records, Iterable):
        raise TypeError(f"records must be an iterable of record mappings, got {type(records).__name__}")
    by_suite: dict[str, list[Mapping[str, Any]]] = {}
    for i, rec in enumerate(records):
        problem = record_problem(rec, require_key=False)
        if problem is not None:
            raise ValueError(f"records[{i}] is not a trial record: {problem}")
        by_suite.setdefault(rec["config"]["suite"], []).append(rec)
    tables: list[Table] = []
    for suite_name in sorted(by_suite):
        recs = by_suite[suite_name]
        suite = lookup(suite_name)
        if suite is not None:
            metrics = list(suite.metrics)
            known = {m.name for m in metrics}
            metrics += [Metric(n) for n in sorted({k for r in recs for k in r["metrics"]} - known)]
        else:
            metrics = [Metric(n) for n in sorted({k for r in recs for k in r["metrics"]})]
        cells: dict[str, list[Mapping[str, Any]]] = {}
        for rec in recs:
            cfg = rec["config"]
            cell_key = json.dumps([cfg["env"], cfg["method"], cfg["params"]], sort_keys=True)
            cells.setdefault(cell_key, []).append(rec)
        rows = []
        for cell_recs in cells.values():
            cfg = cell_recs[0]["config"]
            stats: dict[str, Stat | None] = {}
            for m in metrics:
                values = [float(r["metrics"][m.name]) for r in cell_recs if r["metrics"].get(m.name) is not None]
                stats[m.name] = Stat.of(values) if values else None
            refs = suite.references_for(cfg["env"], cfg["method"]) if suite is not None else {}
            seeds = sorted(int(r["seed"]) for r in cell_recs)
            rows.append(Row(cfg["env"], cfg["method"], dict(cfg["params"]), len(cell_recs), seeds, stats, refs))
        rows.sort(key=lambda r: (_order(suite, "env", r.env), _order(suite, "method", r.method), json.dumps(r.params)))
        all_keys = sorted({k for r in rows for k in r.params})
        varying = [k for k in all_keys if len({json.dumps(r.params.get(k)) for r in rows}) > 1]
        description = suite.description if suite is not None else "(suite not registered in this process)"
        table = Table(
            suite_name, description, metrics, rows, varying, default_seeds=suite.default_seeds if suite else None
        )
        if suite is not None:
            table.reduced = reduced_settings(suite, rows)
        if suite is not None and suite.findings is not None:
            table.findings = _checked_findings(suite, table)
        tables.append(table)
    return tables


def suite_table(suite: Suite, records: Iterable[Mapping[str, Any]]) -> Table | None:
    """The summary table of ``suite`` in ``records`` (``None`` when none of them is its).

    >>> suite_table(get_suite("selftest"), []) is None
    True
    """
    return next((t for t in summarize(records) if t.suite == suite.name), None)


def _checked_findings(suite: Suite, table: Table) -> list[Finding]:
    """The suite's findings on ``table``; a hook that fails on unusual records becomes one unchecked finding."""
    assert suite.findings is not None
    try:
        findings = list(suite.findings(table))
    except Exception as exc:
        detail = " ".join(str(exc).split())[:200]
        return [Finding(f"the findings of {suite.name} could not be checked ({type(exc).__name__}: {detail})", None)]
    return findings


def _order(suite: Suite | None, axis: str, value: str | None) -> tuple[int, str]:
    if suite is not None:
        try:
            items = suite.env_list() if axis == "env" else suite.method_list()
        except Exception:  # a lazy axis that cannot be evaluated here
            items = []
        if value in items:
            return (items.index(value), "")
    return (1 << 30, str(value))


def _fmt(value: float | None, spec: str, *, signed: bool = False) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    text = format(value, spec)
    return f"+{text}" if signed and value >= 0 and not text.startswith("+") else text


def _cell(stat: Stat | None, metric: Metric) -> str:
    if stat is None:
        return "—"
    text = _fmt(stat.mean, metric.fmt)
    if stat.n > 1:
        text += f" ± {_fmt(stat.std, metric.fmt)}"
    return text


def _md_table(header: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(header)]
    lines = ["| " + " | ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)) + " |"]
    lines.append("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    lines += ["| " + " | ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) + " |" for r in rows]
    return "\n".join(lines)


def goal_lines(table: Table) -> list[str]:
    """``goal: metric >= x: k/n cells pass`` lines (naming failing cells)."""
    lines = []
    for m in table.metrics:
        if m.goal is None:
            continue
        checked = [(r, r.stats.get(m.name)) for r in table.rows if r.stats.get(m.name) is not None]
        if not checked:
            continue
        failing = [r.label(table.varying_params) for r, s in checked if not m.meets_goal(s.mean)]  # type: ignore[union-attr]
        op = ">=" if m.higher_is_better else "<="
        line = f"goal {m.name} {op} {m.goal:g}: {len(checked) - len(failing)}/{len(checked)} cells pass"
        lines.append(line + (f" (below: {', '.join(failing)})" if failing else ""))
    return lines


def reduced_settings(suite: Suite, rows: Sequence[Row]) -> list[str]:
    """``name=value`` of the quick-tour overrides (those off the suite's defaults) that every row ran with.

    Such a run (``steer-bench run quick``) is a smoke test of the pipeline,
    too small for claims about full-size runs; empty for any other run.

    >>> reduced_settings(get_suite("tli-arm-scoop"), [])
    []
    """
    if not suite.quick or not rows:
        return []
    defaults = suite.defaults.to_json()
    quick = suite.resolve_params({}, base=suite.quick).to_json()
    # plot_* parameters only change figures, not the experiment
    changed = {
        k: v for k, v in quick.items() if k in suite.quick and defaults.get(k) != v and not k.startswith("plot_")
    }
    if not changed or not all(all(r.params.get(k) == v for k, v in changed.items()) for r in rows):
        return []
    return [f"{k}={v}" for k, v in changed.items()]


def seeds_run(table: Table) -> int:
    """The most seeds any row of ``table`` ran (0 for an empty table)."""
    return max((len(r.seeds) for r in table.rows), default=0)


def judged(table: Table) -> bool:
    """Whether ``table`` is a run its suite's findings are meant for: the default seeds, not the quick settings."""
    enough = table.default_seeds is None or seeds_run(table) >= table.default_seeds
    return enough and not table.reduced


def finding_lines(table: Table) -> list[str]:
    """``finding holds|FAILS|not checked|not judged: claim (detail)`` lines.

    A run on fewer seeds than the suite's default, or at the quick tour's
    reduced settings, cannot judge a claim made about the full run: its
    verdicts print as ``not judged``, saying why and the verdict this run
    leans to, never as a failure.
    """
    verdict = {True: "holds", False: "FAILS", None: "not checked"}
    seeds, enough = seeds_run(table), judged(table)
    lines = []
    for f in table.findings:
        detail = f" ({f.detail})" if f.detail else ""
        if f.holds is None or enough:
            lines.append(f"finding {verdict[f.holds]}: {f.claim}{detail}")
        else:
            lean = "holds" if f.holds else "fails"
            why = []
            if table.default_seeds is not None and seeds < table.default_seeds:
                why.append(f"{seeds} of the {table.default_seeds} seeds it needs")
            if table.reduced:
                why.append(f"the quick tour's reduced {', '.join(table.reduced)}")
            lines.append(f"finding not judged ({'; '.join(why)}; on these it {lean}): {f.claim}{detail}")
    return lines


def render_markdown(tables: Sequence[Table], *, title: str | None = None, notes: Sequence[str] = ()) -> str:
    """Markdown: one table per suite; thesis numbers and differences beside measured means."""
    out: list[str] = []
    if title:
        out += [f"# {title}", ""]
    if notes:
        out += [*(f"> note: {n}" for n in notes), ""]
    if not tables:
        out.append("(no finished trials)")
    for table in tables:
        out += [f"## {table.suite}", "", table.description, ""]
        referenced = {m.name for m in table.referenced_metrics()}
        header = ["env", "method", *table.varying_params, "n"]
        for m in table.metrics:
            header.append(m.name)
            if m.name in referenced:
                header += [f"{m.name} (ref)", f"Δ {m.name}"]
        rows = []
        for r in table.rows:
            cells = [_short_env(r.env) or "-", r.method or "-", *(str(r.params.get(k)) for k in table.varying_params)]
            cells.append(str(r.trials))
            for m in table.metrics:
                cells.append(_cell(r.stats.get(m.name), m))
                if m.name in referenced:
                    ref = r.references.get(m.name)
                    cells += [_fmt(ref.value if ref else None, m.fmt), _fmt(r.diff(m.name), m.fmt, signed=True)]
            rows.append(cells)
        out.append(_md_table(header, rows))
        sources = sorted({ref.source for r in table.rows for ref in r.references.values() if ref.source})
        notes = [*goal_lines(table), *finding_lines(table)]
        if sources:
            notes.append("references: " + "; ".join(sources))
        described = [f"`{m.name}`: {m.description}" for m in table.metrics if m.description]
        if described:
            notes.append("metrics: " + "; ".join(described))
        if notes:
            out += [""] + [f"- {n}" for n in notes]
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _long_rows(tables: Sequence[Table]) -> list[dict[str, Any]]:
    rows = []
    for table in tables:
        for r in table.rows:
            for m in table.metrics:
                stat, ref = r.stats.get(m.name), r.references.get(m.name)
                rows.append(
                    {
                        "suite": table.suite,
                        "env": r.env,
                        "method": r.method,
                        "params": r.params,
                        "metric": m.name,
                        "kind": m.kind,
                        "trials": r.trials,
                        "n": stat.n if stat else 0,
                        "mean": stat.mean if stat else None,
                        "std": stat.std if stat else None,
                        "min": stat.min if stat else None,
                        "max": stat.max if stat else None,
                        "reference": ref.value if ref else None,
                        "diff": r.diff(m.name),
                        "source": ref.source if ref else None,
                        "goal": m.goal,
                        "meets_goal": m.meets_goal(stat.mean) if stat else None,
                    }
                )
    return rows


def render_csv(tables: Sequence[Table]) -> str:
    """CSV in long format: one line per (suite, env, method, params, metric)."""
    rows = _long_rows(tables)
    buf = io.StringIO()
    fields = [
        "suite",
        "env",
        "method",
        "params",
        "metric",
        "kind",
        "trials",
        "n",
        "mean",
        "std",
        "min",
        "max",
        "reference",
        "diff",
        "source",
        "goal",
        "meets_goal",
    ]
    writer = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({**row, "params": json.dumps(row["params"], sort_keys=True)})
    return buf.getvalue()


def render_json(tables: Sequence[Table]) -> str:
    """JSON: ``{"rows": [...], "findings": [...]}``; rows in the same long format as the CSV."""
    findings = [{"suite": t.suite, **asdict(f), "judged": judged(t)} for t in tables for f in t.findings]
    return json.dumps({"rows": _long_rows(tables), "findings": findings}, indent=2, sort_keys=True) + "\n"


def render(tables: Sequence[Table], fmt: str = "md", *, title: str | None = None, notes: Sequence[str] = ()) -> str:
    """Render ``tables`` as ``md``, ``csv`` or ``json`` (title and notes: markdown only).

    >>> rec = {"config": {"suite": "mine", "env": None, "method": "a", "params": {}}, "seed": 0, "metrics": {"x": 2.0}}
    >>> print(render(summarize([rec]), "md"))
    ## mine
    <BLANKLINE>
    (suite not registered in this process)
    <BLANKLINE>
    | env | method | n | x |
    |-----|--------|---|---|
    | -   | a      | 1 | 2 |
    <BLANKLINE>
    """
    if fmt == "md":
        return render_markdown(tables, title=title, notes=notes)
    if fmt == "csv":
        return render_csv(tables)
    if fmt == "json":
        return render_json(tables)
    raise ValueError(f"format must be one of {FORMATS}, got {fmt!r}")
