"""Table 2.1's qualitative findings (ITPS in Maze2D), judged on a summary table's ``DP-*`` means.

``itps`` judges them on its run, ``itps-maze2d-scaling`` on each pilot and
``itps-flow-safety`` on the flow policy too
(:func:`~steer_envs.bench.findings.on_other_policy`).

>>> len(TABLE_2_1_CLAIMS)
4
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from steer_envs.bench.findings import listing
from steer_envs.bench.suite import Finding

__all__ = ["SAMPLERS", "TABLE_2_1_CLAIMS", "table_2_1_checks", "table_2_1_findings"]

#: the six ITPS samplers, the columns of Table 2.1
SAMPLERS: tuple[str, ...] = ("RS", "PR", "OP", "BI", "GD", "SS")

#: Table 2.1's qualitative findings, in the order :func:`table_2_1_checks` returns their verdicts
TABLE_2_1_CLAIMS: tuple[str, ...] = (
    "SS has the best Min L2 and Avg L2 among the DP samplers",
    "SS's collision rate is within 0.02 of RS's",
    "GD and BI collide more than SS",
    "PR improves Min L2 over RS but not Avg L2",
)


def table_2_1_checks(
    min_l2: Mapping[str, float] | None, avg_l2: Mapping[str, float] | None, collision: Mapping[str, float] | None
) -> list[bool | None]:
    """The verdicts on :data:`TABLE_2_1_CLAIMS` from per-sampler means keyed ``"RS"``, ``"PR"``, ..., ``"SS"``.

    ``None`` for a claim whose metric is missing. SS's L2 is compared with
    every other sampler in the mapping.

    >>> m = {"RS": 0.3, "PR": 0.2, "BI": 0.1, "GD": 0.1, "SS": 0.05}
    >>> table_2_1_checks(m, m, {"RS": 0.01, "PR": 0.01, "BI": 0.06, "GD": 0.06, "SS": 0.01})
    [True, True, True, False]
    """
    verdicts: list[bool | None] = [None] * 4
    if min_l2 is not None and avg_l2 is not None:
        others = [s for s in min_l2 if s != "SS"]
        best_min = min(min_l2[s] for s in others)
        best_avg = min(avg_l2[s] for s in others)
        verdicts[0] = min_l2["SS"] < best_min and avg_l2["SS"] < best_avg
        verdicts[3] = min_l2["PR"] < min_l2["RS"] and avg_l2["PR"] >= avg_l2["RS"] - 0.005
    if collision is not None:
        verdicts[1] = abs(collision["SS"] - collision["RS"]) <= 0.02
        verdicts[2] = collision["GD"] > collision["SS"] and collision["BI"] > collision["SS"]
    return verdicts


def table_2_1_findings(table: Any) -> list[Finding]:
    """Table 2.1's qualitative findings, checked on a run's summary table."""
    dp = [f"DP-{s}" for s in SAMPLERS]
    min_l2, avg_l2, coll = (table.means(m, dp) for m in ("min_l2", "avg_l2", "collision"))

    def by_sampler(values: Mapping[str, float] | None) -> dict[str, float] | None:
        return None if values is None else {m.removeprefix("DP-"): v for m, v in values.items()}

    def fmt(values: Mapping[str, float] | None, *methods: str) -> str:
        return listing(values, ".3f", strip="DP-", names=methods) if values else ""

    verdicts = table_2_1_checks(by_sampler(min_l2), by_sampler(avg_l2), by_sampler(coll))
    details = ["", fmt(coll, "DP-SS", "DP-RS"), fmt(coll, "DP-GD", "DP-BI", "DP-SS"), ""]
    if min_l2 is not None and avg_l2 is not None:
        others = [m for m in dp if m != "DP-SS"]
        best_min, best_avg = min(others, key=min_l2.__getitem__), min(others, key=avg_l2.__getitem__)
        details[0] = f"Min L2 {fmt(min_l2, 'DP-SS', best_min)}; Avg L2 {fmt(avg_l2, 'DP-SS', best_avg)}"
        details[3] = f"Min L2 {fmt(min_l2, 'DP-PR', 'DP-RS')}; Avg L2 {fmt(avg_l2, 'DP-PR', 'DP-RS')}"
    return [
        Finding(claim, holds) if holds is None else Finding(claim, holds, detail)
        for claim, holds, detail in zip(TABLE_2_1_CLAIMS, verdicts, details, strict=True)
    ]
