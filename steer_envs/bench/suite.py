"""Suites, trials and the suite registry of steer-bench.

A :class:`Suite` is declared in code: which envs and methods it compares, the
metrics a trial reports, its parameters (a frozen dataclass, see
:mod:`steer_envs.bench.params`), how to turn a request (envs x methods x seeds
x params) into :class:`Trial` objects, the function that runs one trial and,
where the suite reproduces a thesis table, the thesis's numbers
(:class:`Reference`). A trial is a pure function of its config and seed, so
any executor (in-process, process pool, Ray) gives the same metrics.

Suites register themselves with :func:`register_suite` when their module is
imported. Built-in suite modules are listed in :data:`BUILTIN_SUITE_MODULES`;
other modules are loaded with :func:`load_plugins` (``--plugin`` on the
command line, or the ``STEER_BENCH_PLUGINS`` environment variable holding
comma-separated module names).

>>> get_suite("selftest").method_list()
['mc', 'stratified']
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

from steer_envs.bench.params import NoParams, SuiteParams, check_suite_params
from steer_envs.core.validation import describe
from steer_envs.utils.imports import resolve_function

#: modules whose import registers the built-in suites (later domains append theirs)
BUILTIN_SUITE_MODULES: tuple[str, ...] = (
    "steer_envs.bench.suites.selftest",
    "steer_envs.bench.suites.smoke",
    "steer_envs.bench.suites.quick",
    "steer_envs.bench.suites.itps.suite",
    "steer_envs.bench.suites.itps.scaling",
    "steer_envs.bench.suites.ltl",
    "steer_envs.bench.suites.tli.suite",
    "steer_envs.bench.suites.glide.suite",
    "steer_envs.bench.suites.glide_robosuite.suite",
    "steer_envs.bench.suites.itps_blockstack.suite",
    "steer_envs.bench.suites.itps_kitchen.suite",
    "steer_envs.bench.suites.itps_flow.suite",
    "steer_envs.bench.suites.itps_latency.suite",
    "steer_envs.bench.suites.tli_cooking.suite",
    "steer_envs.bench.suites.tli_inspection.suite",
    "steer_envs.bench.suites.tli_color_tracing.suite",
    "steer_envs.bench.suites.tli_arm_scoop.suite",
    "steer_envs.bench.suites.ui.suite",
    "steer_envs.bench.suites.sb3.suite",
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

    >>> m = Metric("speedup", "vectorized / single steps per second", kind="timing", goal=20.0)
    >>> m.meets_goal(25.0), m.meets_goal(3.0)
    (True, False)
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

    >>> Reference("collision", 0.01, method="DP-SS", source="thesis Table 2.1").matches("any/Env-v0", "DP-SS")
    True
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
    can be shipped to process pools and Ray workers. ``params`` is the JSON
    form of the suite's parameters (:meth:`SuiteParams.to_json`); suites build
    trials with :meth:`Suite.trial`, and trial functions read the typed
    parameters back with ``TheirParams.from_json(trial.params)``.

    >>> t = Trial("selftest", None, "mc", 0, {"samples": 100, "sleep": 0.0, "fail_seeds": []},
    ...           "steer_envs.bench.suites.selftest:run_selftest_trial")
    >>> t.label, len(t.key)
    ('selftest - mc seed=0', 20)
    """

    suite: str
    env: str | None
    method: str | None
    seed: int
    params: Mapping[str, Any]
    fn: str

    def __post_init__(self) -> None:
        if not isinstance(self.suite, str):
            raise TypeError(f"Trial.suite must be a str, got {describe(self.suite)}")
        if not self.suite:
            raise ValueError("Trial.suite must not be empty")
        for name in ("env", "method"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, str):
                raise TypeError(f"Trial.{name} must be a str or None, got {describe(value)}")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool):
            raise TypeError(f"Trial.seed must be an int, got {type(self.seed).__name__}")
        if not isinstance(self.fn, str):
            raise TypeError(f"Trial.fn must be a 'module:function' str, got {describe(self.fn)}")
        if ":" not in self.fn:
            raise ValueError(f"Trial.fn must be 'module:function', got {self.fn!r}")
        if not isinstance(self.params, Mapping):
            raise TypeError(f"Trial.params must be a mapping of parameter names to values, got {describe(self.params)}")
        try:
            canonical = json.dumps(dict(self.params), sort_keys=True, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"Trial.params must be JSON-serialisable with finite numbers: {exc}") from None
        except RecursionError:
            raise ValueError("Trial.params is nested too deeply") from None
        object.__setattr__(self, "params", json.loads(canonical))

    @property
    def config(self) -> dict[str, Any]:
        """Everything that identifies the trial except the seed."""
        return {"suite": self.suite, "env": self.env, "method": self.method, "params": dict(self.params)}

    @property
    def key(self) -> str:
        """Stable id of the trial (:func:`trial_key` of config + seed; ``fn`` excluded so code can move)."""
        return trial_key(self.config, self.seed)

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

    >>> TrialResult({"success": 1.0}, extra={"path": [[0.0, 0.0], [1.0, 0.5]]}).metrics
    {'success': 1.0}
    """

    metrics: Mapping[str, float | None]
    extra: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TrialRequest:
    """What the user asked for (``steer-bench run`` options), envs/methods already validated.

    ``seeds=None`` and ``trials=None`` mean "the suite's default";
    ``params`` holds only the user's overrides (``--param KEY=VALUE``);
    ``base`` holds overrides applied to the defaults before ``params`` (the
    ``quick`` tour passes each suite's :attr:`Suite.quick` settings there).

    >>> TrialRequest(envs=(None,), methods=("mc",), seeds=(0, 1), params={"samples": 500}).trials is None
    True
    """

    envs: tuple[str | None, ...]
    methods: tuple[str | None, ...]
    seeds: tuple[int, ...] | None = None
    params: Mapping[str, Any] = field(default_factory=dict)
    trials: int | None = None
    base: Mapping[str, Any] | None = None


@dataclass(frozen=True)
class TrialPlan:
    """The trials a suite generated plus notes for the user (e.g. skipped envs).

    >>> TrialPlan((), notes=("skipped steer_envs/Foo-v0: module missing",)).notes[0]
    'skipped steer_envs/Foo-v0: module missing'
    """

    trials: tuple[Trial, ...]
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Finding:
    """One qualitative claim of the thesis, checked on a run's summary table.

    ``holds`` is ``None`` when the run lacks the cells the claim needs (e.g. a
    ``--method`` subset); ``detail`` gives the measured numbers behind the verdict.

    >>> Finding("SS beats GD on Min L2", True, "SS 0.10, GD 0.11").holds
    True
    """

    claim: str
    holds: bool | None
    detail: str = ""


def trial_key(config: Mapping[str, Any], seed: int) -> str:
    """The key of the trial with ``config`` and ``seed``: the first 20 hex digits of a SHA-256 of both.

    >>> trial_key({"suite": "selftest", "env": None, "method": "mc", "params": {}}, 0)
    '399724341019f45b6202'
    """
    blob = json.dumps({**config, "seed": seed}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


TrialGenerator = Callable[["Suite", TrialRequest], "TrialPlan | Iterable[Trial]"]
PlotHook = Callable[["Suite", Sequence[Mapping[str, Any]], str], Sequence[str]]
#: ``report.Table -> findings`` (typed ``Any`` here: report.py imports this module)
FindingsHook = Callable[[Any], Sequence[Finding]]


@dataclass(frozen=True)
class Suite:
    """A benchmark: envs x methods x seeds, the metrics and the reference numbers.

    A suite module declares the suite's parameters as one frozen dataclass
    deriving from :class:`~steer_envs.bench.params.SuiteParams` (field
    defaults = the suite's defaults, value checks in ``__post_init__``), a
    module-level trial function that reads them back typed, and the suite::

        @dataclass(frozen=True)
        class CoinParams(SuiteParams):
            suite_name: ClassVar[str] = "coin"
            flips: int = 100

            def __post_init__(self) -> None:
                self.require_at_least(1, "flips")

        def run_coin_trial(trial: Trial) -> dict[str, float]:
            p = CoinParams.from_json(trial.params)
            heads = np.random.default_rng(trial.seed).integers(0, 2, p.flips).sum()
            return {"heads": heads / p.flips}

        COIN = register_suite(Suite("coin", "fair coin", (Metric("heads"),), run_coin_trial,
                                    params=CoinParams(), trials_param="flips"))

    ``--param KEY=VALUE`` and ``--trials N`` then work, are coerced to the
    field types and checked before any trial runs; ``Trial.params`` holds
    :meth:`SuiteParams.to_json` of the resolved parameters. A plain mapping of
    defaults is accepted too (each value typed by its default).

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
        params: the default parameters, a frozen :class:`SuiteParams`
            dataclass instance (``--param KEY=VALUE`` overrides its fields).
        trials_param: the parameter ``--trials N`` sets (e.g. episodes per trial).
        default_seeds: seeds ``0..N-1`` when ``--seeds`` is not given.
        generate: custom trial generator; the default is the full product
            envs x methods x seeds with the resolved parameters.
        references: the thesis's numbers the report prints beside the measured ones.
        quick: parameter overrides that make this suite part of the ``quick``
            tour (``None``: not part of it); ``quick_seeds`` seeds there.
        plot: optional hook ``(suite, records, out_dir) -> written paths`` for suite-specific
            figures (``steer-bench report --plots``, :meth:`figures`), or its ``"module:function"``
            path, imported only when drawing (declaring a suite imports no plotting code).
        findings: optional hook ``report.Table -> [Finding]``: the thesis's
            qualitative claims (orderings, "within x of"), checked on the
            summary and listed under the table.
        members: for a suite without ``run_trial`` whose ``generate`` builds
            other suites' trials (a tour), the names of those suites: records
            of any other registered suite do not belong in its directory
            (see :meth:`accepts_records_of`).

    >>> from steer_envs.bench.suites.selftest import SelftestParams, run_selftest_trial
    >>> demo = Suite("pi-demo", "pi by sampling", (Metric("pi"),), run_selftest_trial,
    ...              methods=("mc",), params=SelftestParams(samples=100), trials_param="samples")
    >>> demo.resolve_params({"sleep": 0}, trials=50)
    SelftestParams(samples=50, sleep=0.0, fail_seeds=())
    >>> [t.label for t in demo.plan(TrialRequest(envs=(None,), methods=("mc",), seeds=(0, 1))).trials]
    ['pi-demo - mc seed=0', 'pi-demo - mc seed=1']
    """

    name: str
    description: str
    metrics: tuple[Metric, ...]
    run_trial: Callable[[Trial], Mapping[str, Any] | TrialResult] | None = None
    envs: Sequence[str | None] | Callable[[], Sequence[str | None]] = (None,)
    methods: Sequence[str | None] | Callable[[], Sequence[str | None]] = (None,)
    params: SuiteParams | Mapping[str, Any] = field(default_factory=NoParams)
    trials_param: str | None = None
    default_seeds: int = 3
    generate: TrialGenerator | None = None
    references: tuple[Reference, ...] = ()
    quick: Mapping[str, Any] | None = None
    quick_seeds: int = 1
    plot: PlotHook | str | None = None
    findings: FindingsHook | None = None
    members: Callable[[], Iterable[str]] | None = None

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
        object.__setattr__(self, "params", check_suite_params(self.name, self.params))
        if self.trials_param is not None and self.trials_param not in self.param_names:
            raise ValueError(f"Suite {self.name!r}: trials_param {self.trials_param!r} is not one of its params")
        if self.default_seeds < 1 or self.quick_seeds < 1:
            raise ValueError(f"Suite {self.name!r}: default_seeds and quick_seeds must be >= 1")
        if self.quick is not None:
            unknown = set(self.quick) - set(self.param_names)
            if unknown:
                raise ValueError(f"Suite {self.name!r}: quick overrides unknown params {sorted(unknown)}")
            self.resolve_params({}, base=self.quick)  # the tour's values must pass the suite's checks
        if self.run_trial is None and self.generate is None:
            raise ValueError(f"Suite {self.name!r} needs run_trial (or a generate that builds trials of other suites)")
        if self.run_trial is not None:
            function_path(self.run_trial)  # must be importable by workers
        if isinstance(self.plot, str) and self.plot.count(":") != 1:
            raise ValueError(f"Suite {self.name!r}: plot must be a hook or a 'module:function' path, got {self.plot!r}")

    @property
    def defaults(self) -> SuiteParams:
        """The default parameters (typed)."""
        assert isinstance(self.params, SuiteParams)  # a mapping is converted in __post_init__
        return self.params

    @property
    def param_names(self) -> tuple[str, ...]:
        """The names ``--param`` accepts, in declaration order."""
        return type(self.defaults).field_names()

    @property
    def fn(self) -> str:
        """``"module:function"`` of :attr:`run_trial`."""
        if self.run_trial is None:
            raise ValueError(f"suite {self.name!r} has no run_trial")
        return function_path(self.run_trial)

    def figures(self, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
        """The suite's own figures of ``records``, written to ``out_dir`` by :attr:`plot` (none without it)."""
        if self.plot is None:
            return []
        hook = resolve_function(self.plot) if isinstance(self.plot, str) else self.plot
        return list(hook(self, records, out_dir))

    def accepts_records_of(self, suite: str) -> bool:
        """Whether a record of ``suite`` belongs in a results directory of this suite.

        A suite with ``run_trial`` holds only its own records; a tour holds
        those of its :attr:`members` (any suite when it declares none) and of
        suites not registered in this process (which cannot be judged here).

        >>> get_suite("selftest").accepts_records_of("selftest"), get_suite("selftest").accepts_records_of("smoke")
        (True, False)
        >>> get_suite("quick").accepts_records_of("smoke"), get_suite("quick").accepts_records_of("selftest")
        (True, False)
        """
        if suite == self.name:
            return True
        if self.run_trial is not None:
            return False
        if self.members is None:
            return True
        return suite in set(self.members()) or suite not in _SUITES

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
    ) -> Any:
        """The defaults updated with ``base``, then ``overrides`` and ``--trials``: coerced and checked.

        Returns the suite's params dataclass (typed ``Any`` so a suite's own
        code reads its fields without a cast). A value is coerced to its
        field's type (an int given for a float parameter becomes a float, so
        equal configs hash equally); unknown names and bad values raise
        ``ValueError`` naming the suite and the parameter.
        """
        names = self.param_names
        values = self.defaults.to_json()
        for source in (base or {}, overrides):
            for name, value in source.items():
                if name not in names:
                    raise ValueError(f"suite {self.name!r} has no parameter {name!r}; parameters: {sorted(names)}")
                values[name] = value
        if trials is not None:
            if self.trials_param is None:
                raise ValueError(f"suite {self.name!r} has no per-trial count; --trials does not apply")
            values[self.trials_param] = trials
        return type(self.defaults).from_json(values, suite=self.name)

    def trial(self, env: str | None, method: str | None, seed: int, params: SuiteParams) -> Trial:
        """The :class:`Trial` of this suite for one cell and seed (``params`` stored as JSON)."""
        if not isinstance(params, type(self.defaults)):
            raise TypeError(
                f"suite {self.name!r}: params must be {type(self.defaults).__name__}, got {type(params).__name__}"
            )
        return Trial(self.name, env, method, seed, params.to_json(), self.fn)

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
        return TrialPlan(self.every_trial(request))

    def every_trial(self, request: TrialRequest) -> tuple[Trial, ...]:
        """Every env x method x seed of ``request`` with its resolved parameters (the default plan; a
        ``generate`` hook that only adds notes starts from it)."""
        params = self.resolve_params(request.params, request.trials, base=request.base)
        return tuple(
            self.trial(env, method, seed, params)
            for env in request.envs
            for method in request.methods
            for seed in self.seed_list(request)
        )


def function_path(fn: Callable[..., Any]) -> str:
    """``"module:qualname"`` of a module-level function, checked to resolve back to ``fn``.

    >>> from steer_envs.bench.suites.selftest import run_selftest_trial
    >>> function_path(run_selftest_trial)
    'steer_envs.bench.suites.selftest:run_selftest_trial'
    """
    module, qualname = getattr(fn, "__module__", None), getattr(fn, "__qualname__", "")
    if not module or not qualname or "<" in qualname:
        raise ValueError(f"run_trial must be a module-level function, got {fn!r}")
    path = f"{module}:{qualname}"
    if resolve_function(path) is not fn:
        raise ValueError(f"run_trial {path!r} does not resolve back to the same object; define it at module level")
    return path


# ------------------------------------------------------------------ registry
_SUITES: dict[str, Suite] = {}
_loaded_builtins = False


def register_suite(suite: Suite, *, replace: bool = False) -> Suite:
    """Add ``suite`` to the registry (``replace=True`` to redefine a name); returns it.

    Call it at import time of the suite's module, so ``get_suite`` (and worker
    processes) find the suite by name.

    >>> selftest = get_suite("selftest")
    >>> register_suite(selftest) is selftest  # registering the same object again is a no-op
    True
    """
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

    Returns the module names imported. A module that cannot be imported
    (missing, a syntax error, an exception at import, a suite it registers
    that is invalid) raises ``ImportError`` naming it and the cause.

    >>> load_plugins(["steer_envs.bench.suites.selftest"])[-1]
    'steer_envs.bench.suites.selftest'
    """
    names = [m.strip() for m in os.environ.get(PLUGINS_ENV_VAR, "").split(",") if m.strip()]
    if isinstance(modules, (str, bytes)):
        raise TypeError(f"modules must be a list of module names, not a single {type(modules).__name__}")
    names += [m for m in modules if m not in names]
    for name in names:
        if not isinstance(name, str) or not name:
            raise TypeError(f"plugin module names must be non-empty strs, got {describe(name)}")
        try:
            importlib.import_module(name)
        except Exception as exc:  # a plugin that fails in any way is one clear error, not a traceback
            detail = " ".join(str(exc).split()) or type(exc).__name__
            raise ImportError(
                f"cannot import steer-bench plugin module {name!r}: {type(exc).__name__}: {detail}"
            ) from exc
    return names


def get_suite(name: str) -> Suite:
    """The registered suite ``name`` (``KeyError`` listing the known names).

    >>> get_suite("selftest").default_seeds
    4
    """
    if not isinstance(name, str):
        raise TypeError(f"suite name must be a str, got {describe(name)}")
    _load_builtins()
    if name not in _SUITES:
        raise KeyError(f"unknown suite {name!r}; known suites: {', '.join(sorted(_SUITES))}")
    return _SUITES[name]


def suites() -> list[Suite]:
    """Every registered suite, sorted by name.

    >>> "smoke" in [s.name for s in suites()]
    True
    """
    _load_builtins()
    return [_SUITES[n] for n in sorted(_SUITES)]
