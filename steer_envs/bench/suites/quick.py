"""``quick``: the few-minute tour the README's main-job command runs.

The tour has no trials of its own: it collects every registered suite that
declares ``Suite.quick`` (its parameter overrides for the tour) and runs that
suite with those settings and ``Suite.quick_seeds`` seeds. A domain joins the
tour by declaring ``quick={...}`` on its suite; nothing here changes.
Records keep their own suite name, so the report prints one table per suite.

>>> "smoke" in [s.name for s in quick_sections()]
True
"""

from __future__ import annotations

from steer_envs.bench.suite import Suite, Trial, TrialPlan, TrialRequest, register_suite, suites

QUICK_NAME = "quick"


def quick_sections() -> list[Suite]:
    """The suites that are part of the tour, by name.

    >>> "selftest" in [s.name for s in quick_sections()]  # selftest declares no quick settings
    False
    """
    return [s for s in suites() if s.quick is not None and s.name != QUICK_NAME]


def _quick_members() -> list[str]:
    return [s.name for s in quick_sections()]


def _union(axis: str) -> list[str | None]:
    seen: list[str | None] = []
    for s in quick_sections():
        for item in s.env_list() if axis == "env" else s.method_list():
            if item not in seen:
                seen.append(item)
    return seen


def _quick_envs() -> list[str | None]:
    return _union("env")


def _quick_methods() -> list[str | None]:
    return _union("method")


def _plan_quick(suite: Suite, request: TrialRequest) -> TrialPlan:
    sections = quick_sections()
    declared = {p for s in sections for p in s.param_names}
    unknown = sorted(set(request.params) - declared)
    if unknown:
        raise ValueError(f"quick: no suite of the tour has parameter(s) {unknown}; parameters: {sorted(declared)}")
    trials: list[Trial] = []
    notes: list[str] = []
    for section in sections:
        envs = tuple(e for e in section.env_list() if e in request.envs)
        methods = tuple(m for m in section.method_list() if m in request.methods)
        if not envs or not methods:
            continue
        sub = TrialRequest(
            envs=envs,
            methods=methods,
            seeds=request.seeds if request.seeds is not None else tuple(range(section.quick_seeds)),
            params={k: v for k, v in request.params.items() if k in section.param_names},
            trials=request.trials if section.trials_param is not None else None,
            base=section.quick,
        )
        plan = section.plan(sub)
        trials += plan.trials
        notes += [f"{section.name}: {n}" for n in plan.notes]
    return TrialPlan(tuple(trials), tuple(notes))


QUICK = register_suite(
    Suite(
        name=QUICK_NAME,
        description="Few-minute tour: every suite that declares quick settings, with those settings.",
        metrics=(),
        envs=_quick_envs,
        methods=_quick_methods,
        default_seeds=1,
        generate=_plan_quick,
        members=_quick_members,
    )
)
