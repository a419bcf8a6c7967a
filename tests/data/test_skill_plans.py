"""What both domains' skill plan data sets refuse (:mod:`steer_envs.data.skill_plans`): bad records and settings."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from skill_samples import blockstack_record, kitchen_record

from steer_envs.data import blockstack_plans, kitchen_plans

#: domain -> (its to_plan_dataset, a synthetic record of n steps)
DOMAINS: dict[str, tuple[Callable[..., Any], Callable[[int], Any]]] = {
    "blockstack": (blockstack_plans.to_plan_dataset, blockstack_record),
    "kitchen": (kitchen_plans.to_plan_dataset, kitchen_record),
}
#: the arguments of to_plan_dataset (made with a domain's record factory), the error and what it names
CASES: dict[str, tuple[Callable[[Callable[[int], Any]], dict[str, Any]], type, str]] = {
    "records-not-a-sequence": (lambda record: {"records": "x"}, TypeError, "records"),
    "record-not-a-record": (lambda record: {"records": [1]}, TypeError, r"records\[0\]"),
    "no-records": (lambda record: {"records": []}, ValueError, "no skill"),
    "stride-0": (lambda record: {"records": [record(10)], "stride": 0}, ValueError, "stride"),
    "horizon-float": (lambda record: {"records": [record(10)], "horizon": 1.5}, TypeError, "horizon"),
    "successful-only-str": (
        lambda record: {"records": [record(10)], "successful_only": "yes"},
        TypeError,
        "successful_only",
    ),
}


@pytest.mark.parametrize("domain", DOMAINS)
@pytest.mark.parametrize("case", CASES)
def test_bad_input_is_refused(domain: str, case: str) -> None:
    to_plan_dataset, record = DOMAINS[domain]
    kwargs, error, match = CASES[case]
    with pytest.raises(error, match=match):
        to_plan_dataset(**kwargs(record))
