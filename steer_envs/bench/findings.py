"""Building blocks of a suite's ``findings`` hook: claims judged on the means of a run's summary table.

Most claims have one shape: read a few means off the table (one per method,
or one per metric of a cell), give no verdict while one of them is missing
(a ``--method`` subset, a metric not measured), else judge them and show the
numbers behind the verdict. :func:`judge` is that shape;
:func:`cell_means` and ``Table.means`` read the numbers, :func:`listing`
writes them, :func:`full` is the "in every episode" test on a percentage.

>>> means = {"DP-SS": 0.71, "DP-RS": 0.38}
>>> judge("SS aligns more than RS", means, lambda m: m["DP-SS"] > m["DP-RS"], lambda m: listing(m, ".2f", strip="DP-"))
Finding(claim='SS aligns more than RS', holds=True, detail='SS 0.71, RS 0.38')
>>> judge("SS aligns more than RS", None, lambda m: m["DP-SS"] > m["DP-RS"])
Finding(claim='SS aligns more than RS', holds=None, detail='')
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any, TypeVar

from steer_envs.bench.suite import Finding

if TYPE_CHECKING:
    from steer_envs.bench.report import Table

__all__ = ["all_full", "cell_means", "full", "judge", "listing", "missing", "on_other_policy"]

V = TypeVar("V")


def missing(values: Any) -> bool:
    """Whether ``values`` (a mean, a mapping or a tuple of them) lacks a number: it, or one of its items, is ``None``.

    >>> missing({"a": 1.0, "b": None}), missing((1.0, 2.0)), missing(None)
    (True, False, True)
    """
    if values is None:
        return True
    if isinstance(values, Mapping):
        return any(missing(v) for v in values.values())
    if isinstance(values, tuple):
        return any(missing(v) for v in values)
    return False


def judge(
    claim: str, values: V | None, holds: Callable[[V], bool], detail: Callable[[V], str] | str | None = None
) -> Finding:
    """The :class:`~steer_envs.bench.suite.Finding` of ``claim`` on ``values``: no verdict while one is :func:`missing`.

    Else ``holds(values)`` is the verdict and ``detail`` the numbers shown beside it: ``detail(values)``,
    or a format string filled from the mapping ``values``.

    >>> judge("done", {"success": 100.0}, lambda c: full(c["success"]), "success {success:.0f} %").detail
    'success 100 %'
    """
    if values is None or missing(values):
        return Finding(claim, None)
    if isinstance(detail, str):
        if not isinstance(values, Mapping):
            raise TypeError(f"a format-string detail needs a mapping of values, got {type(values).__name__}")
        text = detail.format_map(values)
    else:
        text = "" if detail is None else detail(values)
    return Finding(claim, holds(values), text)


def cell_means(table: Table, method: str | None, metrics: Iterable[str], env: str | None = None) -> dict[str, Any]:
    """``{metric: mean}`` of one cell (``None`` for a metric it did not measure); see ``Table.mean``.

    Typed ``dict[str, Any]`` so that a claim judged on it (after :func:`judge` checked for ``None``) reads floats.
    """
    return {name: table.mean(name, method, env) for name in metrics}


def listing(
    values: Mapping[str, float], spec: str, *, unit: str = "", strip: str = "", names: Iterable[str] = ()
) -> str:
    """``"SS 0.71, RS 0.38"``: each name (without the prefix ``strip``) and its value in ``spec``, then ``unit``.

    ``names`` picks and orders the entries (default: all, in order).

    >>> listing({"a": 100.0, "b": 87.5}, ".0f", unit=" %")
    'a 100 %, b 88 %'
    """
    chosen = list(names) or list(values)
    return ", ".join(f"{name.removeprefix(strip)} {values[name]:{spec}}{unit}" for name in chosen)


def full(percent: float) -> bool:
    """Whether a percentage is 100 (up to rounding): "in every episode".

    >>> full(100.0), full(99.9)
    (True, False)
    """
    return percent >= 100.0 - 1e-9


def all_full(table: Table, claim: str, metric: str, methods: Iterable[str]) -> Finding:
    """``claim``: the percentage ``metric`` is 100 for every one of ``methods``; the detail lists each one's."""
    means = table.means(metric, list(methods))
    return judge(claim, means, lambda m: all(full(v) for v in m.values()), lambda m: listing(m, ".0f", unit=" %"))


class _OtherPolicy:
    """A summary table whose ``means`` read ``prefix``'s methods under ``DP-`` names."""

    def __init__(self, table: Any, prefix: str) -> None:
        self.table, self.prefix = table, prefix

    def means(self, metric: str, methods: list[str]) -> dict[str, float] | None:
        values = self.table.means(metric, [m.replace("DP-", self.prefix, 1) for m in methods])
        return None if values is None else {k.replace(self.prefix, "DP-", 1): v for k, v in values.items()}


def on_other_policy(findings: Callable[[Any], list[Finding]], table: Any, prefix: str, label: str) -> list[Finding]:
    """``findings`` (written for ``DP-*`` methods) judged on the methods named ``prefix`` instead, claims labelled.

    How a suite checks the thesis's DP findings on another policy of the same
    samplers (``FLOW-*``) without writing them twice.

    >>> class T:
    ...     def means(self, metric, methods): return {m: {"FLOW-SS": 0.1, "FLOW-RS": 0.3}[m] for m in methods}
    >>> def f(t): return [judge("SS beats RS", t.means("x", ["DP-SS", "DP-RS"]), lambda v: v["DP-SS"] < v["DP-RS"])]
    >>> on_other_policy(f, T(), "FLOW-", "flow")
    [Finding(claim='flow: SS beats RS', holds=True, detail='')]
    """
    return [Finding(f"{label}: {f.claim}", f.holds, f.detail) for f in findings(_OtherPolicy(table, prefix))]
