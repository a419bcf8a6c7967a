"""Suites, trials and the suite registry of steer-bench.

A :class:`Suite` is declared in code: which envs and methods it compares, the
metrics a trial reports, how to turn a request (envs x methods x seeds x
params) into :class:`Trial` objects, the function that runs one trial and,
where the suite reproduces a thesis table, the thesis's numbers
(:class:`Reference`). A trial is a pure function of its config and seed, so
any executor (in-process, process pool, Ray) gives the same metrics.

Suites register themselves with :func:`register_suite` when their module is
imported. Built-in suite modules are listed in :data:`BUILTIN_SUITE_MODULES`;
other modules are loaded with :func:`load_plugins` (``--plugin`` on the
command line, or the ``STEER_BENCH_PLUGINS`` environment variable holding
comma-separated module names).
"""

from __future__ import annotations

import hashlib
import importlib
import json
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

#: modules whose import registers the built-in suites (later domains append theirs)
BUILTIN_SUITE_MODULES: tuple[str, ...] = (
    "steer_envs.bench.suites.selftest",
    "steer_envs.bench.suites.smoke",
    "steer_envs.bench.suites.quick",
    "steer_envs.bench.suites.itps.suite",
    "steer_envs.bench.suites.ltl",
    "steer_envs.bench.suites.tli.suite",
    "steer_envs.bench.suites.glide.suite",
)
#: environment variable with extra comma-separated suite modules to import
PLUGINS_ENV_VAR = "STEER_BENCH_PLUGINS"

MetricKind = Literal["value", "timing"]


@dataclass(frozen=True)
class Metric:
    """One number a trial reports.

    ``kind="value"`` metrics are deterministic functions of the trial config
    and seed (identical under every executor); ``kind="timing"`` metrics
    (throughput, latency) depend on the machine and its load.
    ``goal`` is an acceptance threshold (e.g. a speed-up of 20), checked in
    the direction given by ``higher_is_better``.
    """

    name: str
    description: str = ""
    kind: MetricKind = "value"
    higher_is_better: bool = True
    fmt: str = ".3g"
    goal: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"Metric.name must be an identifier string, got {self.name!r}")
        if self.kind not in ("value", "timing"):
            raise ValueError(f"Metric.kind must be 'value' or 'timing', got {self.kind!r}")
        format(1.0, self.fmt)  # raises ValueError on a bad format spec

    def meets_goal(self, value: float) -> bool | None:
        """Whether ``value`` reaches :attr:`goal` (``None`` without a goal)."""
        if self.goal is None:
            return None
        return value >= self.goal if self.higher_is_better else value <= self.goal


@dataclass(frozen=True)
class Reference:
    """A published number for one metric of one (env, method) cell.

    ``env`` / ``method`` ``None`` match any env / method. ``source`` names
    where the number comes from (e.g. ``"thesis Table 3.1"``).
    """

    metric: str
    value: float
    env: str | None = None
    method: str | None = None
    source: str = ""

    def matches(self, env: str | None, method: str | None) -> bool:
        """Whether this reference applies to the cell ``(env, method)``."""
        return (self.env is None or self.env == env) and (self.method is None or self.method == method)


@dataclass(frozen=True)
class Trial:
    """One unit of work: a pure function of (suite, env, method, seed, params).

    ``fn`` is the ``"module:function"`` path of the function that runs the
    trial; it is resolved by import in whichever process runs it, so trials
    can be shipped to process pools and Ray workers.
    """

    suite: str
    env: str | None
    method: str | None
    seed: int
    params: Mapping[str, Any]
    fn: str

    def __post_init__(self) -> None:
        if not isinstance(self.seed, int) or isinstance(self.seed, bool):
            raise TypeError(f"Trial.seed must be an int, got {type(self.seed).__name__}")
        if ":" not in self.fn:
            raise ValueError(f"Trial.fn must be 'module:function', got {self.fn!r}")
        try:
            canonical = json.dumps(dict(self.params), sort_keys=True, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"Trial.params must be JSON-serialisable with finite numbers: {exc}") from None
        object.__setattr__(self, "params", json.loads(canonical))

    @property
    def config(self) -> dict[str, Any]:
        """Everything that identifies the trial except the seed."""
        return {"suite": self.suite, "env": self.env, "method": self.method, "params": dict(self.params)}

    @property
    def key(self) -> str:
        """Stable id of the trial (hash of config + seed; ``fn`` excluded so code can move)."""
        blob = json.dumps({**self.config, "seed": self.seed}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:20]

    @property
    def label(self) -> str:
        """Short human-readable name for progress bars and error messages."""
        parts = [self.suite, self.env or "-", self.method or "-", f"seed={self.seed}"]
        return " ".join(parts)


@dataclass(frozen=True)
class TrialResult:
    """What a trial function may return instead of a plain metrics mapping.

    ``extra`` holds JSON-serialisable data kept in the record (e.g. a
    trajectory for a per-suite plot).
    """

    metrics: Mapping[str, float | None]
    extra: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TrialRequest:
    """What the user asked for (``steer-bench run`` options), envs/methods already validated.

    ``seeds=None`` and ``trials=None`` mean "the suite's default";
    ``params`` holds only the user's overrides (``--param KEY=VALUE``).
    """

    envs: tuple[str | None, ...]
    methods: tuple[str | None, ...]
    seeds: tuple[int, ...] | None = None
    params: Mapping[str, Any] = field(default_factory=dict)
    trials: int | None = None
    base: Mapping[str, Any] | None = None  # replaces the suite's defaults (the quick tour's settings)


@dataclass(frozen=True)
class TrialPlan:
    """The trials a suite generated plus notes for the user (e.g. skipped envs)."""

    trials: tuple[Trial, ...]
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Finding:
    """One qualitative claim of the thesis, checked on a run's summary table.

    ``holds`` is ``None`` when the run lacks the cells the claim needs (e.g. a
    ``--method`` subset); ``detail`` gives the measured numbers behind the verdict.
    """

    claim: str
    holds: bool | None
    detail: str = ""


TrialGenerator = Callable[["Suite", TrialRequest], "TrialPlan | Iterable[Trial]"]
PlotHook = Callable[["Suite", Sequence[Mapping[str, Any]], str], Sequence[str]]
#: ``report.Table -> findings`` (typed ``Any`` here: report.py imports this module)
FindingsHook = Callable[[Any], Sequence[Finding]]


@dataclass(frozen=True)
class Suite:
    """A benchmark: envs x methods x seeds, the metrics and the reference numbers.

    Attributes:
        name: registry name (``steer-bench run NAME``).
        description: one line shown by ``steer-bench list``.
        metrics: what every trial reports (trials may report ``None`` for a
            metric that does not apply, e.g. the vector speed-up of a MuJoCo env).
        run_trial: module-level function ``Trial -> Mapping | TrialResult``
            (``None`` for a suite whose ``generate`` builds other suites' trials).
        envs / methods: the axes; a callable is evaluated lazily (e.g. "every
            registered env with an expert"). ``(None,)`` for a suite without
            that axis.
        params: defaults of the suite's parameters (``--param KEY=VALUE``).
        trials_param: the parameter ``--trials N`` sets (e.g. episodes per trial).
        default_seeds: seeds ``0..N-1`` when ``--seeds`` is not given.
        generate: custom trial generator; the default is the full product
            envs x methods x seeds with ``params``.
        references: the thesis's numbers the report prints beside the measured ones.
        quick: parameter overrides that make this suite part of the ``quick``
            tour (``None``: not part of it); ``quick_seeds`` seeds there.
        plot: optional hook ``(suite, records, out_dir) -> written paths`` for
            suite-specific figures (``steer-bench report --plots``).
        findings: optional hook ``report.Table -> [Finding]``: the thesis's
            qualitative claims (orderings, "within x of"), checked on the
            summary and listed under the table.
    """

    name: str
    description: str
    metrics: tuple[Metric, ...]
    run_trial: Callable[[Trial], Mapping[str, Any] | TrialResult] | None = None
    envs: Sequence[str | None] | Callable[[], Sequence[str | None]] = (None,)
    methods: Sequence[str | None] | Callable[[], Sequence[str | None]] = (None,)
    params: Mapping[str, Any] = field(default_factory=dict)
    trials_param: str | None = None
    default_seeds: int = 3
    generate: TrialGenerator | None = None
    references: tuple[Reference, ...] = ()
    quick: Mapping[str, Any] | None = None
    quick_seeds: int = 1
    plot: PlotHook | None = None
    findings: FindingsHook | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or any(c.isspace() for c in self.name):
            raise ValueError(f"Suite.name must be a non-empty string without spaces, got {self.name!r}")
        names = [m.name for m in self.metrics]
        if len(set(names)) != len(names):
            raise ValueError(f"Suite {self.name!r}: duplicate metric names in {names}")
        for ref in self.references:
            if ref.metric not in names:
                raise ValueError(f"Suite {self.name!r}: reference for unknown metric {ref.metric!r}; metrics: {names}")
            if not math.isfinite(ref.value):
                raise ValueError(f"Suite {self.name!r}: reference value for {ref.metric!r} must be finite")
        if self.trials_param is not None and self.trials_param not in self.params:
            raise ValueError(f"Suite {self.name!r}: trials_param {self.trials_param!r} is not one of its params")
        if self.default_seeds < 1 or self.quick_seeds < 1:
            raise ValueError(f"Suite {self.name!r}: default_seeds and quick_seeds must be >= 1")
        if self.quick is not None:
            unknown = set(self.quick) - set(self.params)
            if unknown:
                raise ValueError(f"Suite {self.name!r}: quick overrides unknown params {sorted(unknown)}")
        if self.run_trial is None and self.generate is None:
            raise ValueError(f"Suite {self.name!r} needs run_trial (or a generate that builds trials of other suites)")
        if self.run_trial is not None:
            function_path(self.run_trial)  # must be importable by workers

    @property
    def fn(self) -> str:
        """``"module:function"`` of :attr:`run_trial`."""
        if self.run_trial is None:
            raise ValueError(f"suite {self.name!r} has no run_trial")
        return function_path(self.run_trial)

    def metric(self, name: str) -> Metric:
        """The metric called ``name``."""
        for m in self.metrics:
            if m.name == name:
                return m
        raise KeyError(f"suite {self.name!r} has no metric {name!r}")

    def env_list(self) -> list[str | None]:
        """The env axis (evaluating a lazy declaration)."""
        return list(self.envs() if callable(self.envs) else self.envs)

    def method_list(self) -> list[str | None]:
        """The method axis (evaluating a lazy declaration)."""
        return list(self.methods() if callable(self.methods) else self.methods)

    def references_for(self, env: str | None, method: str | None) -> dict[str, Reference]:
        """Metric name -> reference for the cell ``(env, method)`` (most specific wins)."""
        found: dict[str, Reference] = {}
        ranked = sorted(self.references, key=lambda r: (r.env is not None) + (r.method is not None))
        for ref in ranked:
            if ref.matches(env, method):
                found[ref.metric] = ref
        return found

    def resolve_params(
        self, overrides: Mapping[str, Any], trials: int | None = None, *, base: Mapping[str, Any] | None = None
    ) -> dict[str, Any]:
        """Defaults (or ``base``) updated with ``overrides`` and ``--trials``, type-checked.

        A value is coerced to the type of the default (an int given for a float
        parameter becomes a float, so equal configs hash equally).
        """
        params = dict(self.params if base is None else base)
        for name, value in overrides.items():
            if name not in self.params:
                raise ValueError(f"suite {self.name!r} has no parameter {name!r}; parameters: {sorted(self.params)}")
            params[name] = _coerce_param(self.name, name, value, self.params[name])
        if trials is not None:
            if self.trials_param is None:
                raise ValueError(f"suite {self.name!r} has no per-trial count; --trials does not apply")
            params[self.trials_param] = _coerce_param(
                self.name, self.trials_param, trials, self.params[self.trials_param]
            )
        return params

    def seed_list(self, request: TrialRequest, default: int | None = None) -> tuple[int, ...]:
        """The request's seeds, or ``0..default-1`` (``default_seeds`` when not given)."""
        if request.seeds is not None:
            return tuple(request.seeds)
        return tuple(range(self.default_seeds if default is None else default))

    def plan(self, request: TrialRequest) -> TrialPlan:
        """The trials of ``request`` (custom generator or envs x methods x seeds)."""
        if self.generate is not None:
            out = self.generate(self, request)
            return out if isinstance(out, TrialPlan) else TrialPlan(tuple(out))
        params = self.resolve_params(request.params, request.trials, base=request.base)
        trials = tuple(
            Trial(self.name, env, method, seed, params, self.fn)
            for env in request.envs
            for method in request.methods
            for seed in self.seed_list(request)
        )
        return TrialPlan(trials)


def _coerce_param(suite: str, name: str, value: Any, default: Any) -> Any:
    """``value`` converted to the type of ``default`` (ValueError naming the parameter otherwise)."""
    same_boolness = isinstance(value, bool) == isinstance(default, bool)
    if default is None or (isinstance(value, type(default)) and same_boolness):
        return value
    if isinstance(default, bool):
        raise ValueError(f"suite {suite!r}: parameter {name!r} must be true/false, got {value!r}")
    if isinstance(default, int) and isinstance(value, float) and value.is_integer():
        return int(value)
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    raise ValueError(f"suite {suite!r}: parameter {name!r} must be {type(default).__name__}, got {value!r}")


def function_path(fn: Callable[..., Any]) -> str:
    """``"module:qualname"`` of a module-level function, checked to resolve back to ``fn``."""
    module, qualname = getattr(fn, "__module__", None), getattr(fn, "__qualname__", "")
    if not module or not qualname or "<" in qualname:
        raise ValueError(f"run_trial must be a module-level function, got {fn!r}")
    path = f"{module}:{qualname}"
    if resolve_function(path) is not fn:
        raise ValueError(f"run_trial {path!r} does not resolve back to the same object; define it at module level")
    return path


def resolve_function(path: str) -> Callable[..., Any]:
    """Import ``"module:qualname"`` and return the object."""
    if not isinstance(path, str) or path.count(":") != 1:
        raise ValueError(f"function path must be 'module:qualname', got {path!r}")
    module_name, qualname = path.split(":")
    obj: Any = importlib.import_module(module_name)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


# ------------------------------------------------------------------ registry
_SUITES: dict[str, Suite] = {}
_loaded_builtins = False


def register_suite(suite: Suite, *, replace: bool = False) -> Suite:
    """Add ``suite`` to the registry (``replace=True`` to redefine a name)."""
    if not isinstance(suite, Suite):
        raise TypeError(f"suite must be a Suite, got {type(suite).__name__}")
    if suite.name in _SUITES and not replace and _SUITES[suite.name] is not suite:
        raise ValueError(f"a suite named {suite.name!r} is already registered")
    _SUITES[suite.name] = suite
    return suite


def _load_builtins() -> None:
    global _loaded_builtins
    if not _loaded_builtins:
        _loaded_builtins = True
        for module in BUILTIN_SUITE_MODULES:
            importlib.import_module(module)
        load_plugins(())


def load_plugins(modules: Iterable[str]) -> list[str]:
    """Import suite modules: ``modules`` plus those in ``$STEER_BENCH_PLUGINS``.

    Returns the module names imported. An unimportable module raises
    ``ImportError`` naming it.
    """
    names = [m.strip() for m in os.environ.get(PLUGINS_ENV_VAR, "").split(",") if m.strip()]
    names += [m for m in modules if m not in names]
    for name in names:
        try:
            importlib.import_module(name)
        except ImportError as exc:
            raise ImportError(f"cannot import steer-bench plugin module {name!r}: {exc}") from exc
    return names


def get_suite(name: str) -> Suite:
    """The registered suite ``name`` (``KeyError`` listing the known names)."""
    _load_builtins()
    if name not in _SUITES:
        raise KeyError(f"unknown suite {name!r}; known suites: {', '.join(sorted(_SUITES))}")
    return _SUITES[name]


def suites() -> list[Suite]:
    """Every registered suite, sorted by name."""
    _load_builtins()
    return [_SUITES[n] for n in sorted(_SUITES)]
