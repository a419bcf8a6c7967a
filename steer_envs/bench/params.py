"""Typed suite parameters: one frozen dataclass per suite.

A suite declares its parameters as the fields of a frozen dataclass that
derives from :class:`SuiteParams`; the field defaults are the suite's
defaults. The class does three jobs, so a suite author writes it once:

* :meth:`SuiteParams.from_json` turns a JSON mapping (``--param KEY=VALUE``
  values, a stored ``Trial.params``) into the typed object, coercing each value
  to its field's type (an int given for a float becomes a float, so equal
  configs hash equally) and naming the suite and parameter on bad input;
* ``__post_init__`` checks the values (ranges, choices) with the
  :meth:`SuiteParams.require` helpers, so a bad value fails when the run is
  planned, not in a worker;
* :meth:`SuiteParams.to_json` gives the JSON stored in ``Trial.params``
  (tuples become lists), whose hash is part of the trial key.

A parameter that names code, such as a policy loader, is typed
:data:`PolicyLoader` (``Annotated[str, NamesCallable(kind)]``): its value is a
registered name (``"pretrained"``) or the path it stands for, stored as the
path (:func:`steer_envs.utils.imports.named_callable`). ``steer-bench run``
takes no other value from ``--param`` unless ``--allow-import`` is given
(:func:`check_callable_params`).

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class PiParams(SuiteParams):
...     suite_name: ClassVar[str] = "pi"
...     samples: int = 100
...     radius: float = 1.0
...
...     def __post_init__(self) -> None:
...         self.require_at_least(1, "samples")
>>> PiParams.from_json({"samples": 5.0, "radius": 2})
PiParams(samples=5, radius=2.0)
>>> PiParams().to_json()
{'samples': 100, 'radius': 1.0}
>>> PiParams.from_json({"samples": 0})
Traceback (most recent call last):
ValueError: pi: parameter 'samples' must be >= 1, got 0
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import types
import typing
from collections.abc import Collection, Mapping
from typing import Annotated, Any, ClassVar, Self

from steer_envs.utils.imports import POLICY_LOADER, named_callable, registered_callables

__all__ = [
    "NamesCallable",
    "NoParams",
    "PolicyLoader",
    "SuiteParams",
    "check_callable_params",
    "check_suite_params",
    "params_from_defaults",
]


@dataclasses.dataclass(frozen=True)
class NamesCallable:
    """Marks a ``str`` parameter that names a registered callable of ``kind``: ``Annotated[str, NamesCallable(kind)]``.

    Coercion turns a registered name into its ``"module:qualname"`` path
    (so ``loader="pretrained"`` and the default path hash equally);
    :func:`check_callable_params` refuses unregistered paths from the command line.
    """

    kind: str


#: the type of a policy-loader parameter: ``"pretrained"``, a registered loader's path, or (opted in) any path
PolicyLoader = Annotated[str, NamesCallable(POLICY_LOADER)]


class SuiteParams:
    """Base class of a suite's parameter dataclass (declare it ``@dataclass(frozen=True)``).

    Supported field types: ``bool``, ``int``, ``float``, ``str``, ``X | None``,
    ``tuple[X, ...]``, ``list`` and ``Any`` (taken as is). Set the class
    variable ``suite_name`` so validation errors name the suite. Parameter
    names must not shadow this class's methods (``replace``, ``require``, ...).

    >>> NoParams().to_json()
    {}
    """

    #: the suite named in validation errors (the class name when empty)
    suite_name: ClassVar[str] = ""

    @classmethod
    def _suite_label(cls) -> str:
        """The name validation errors start with: :attr:`suite_name`, else the class name."""
        return cls.suite_name or cls.__name__

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The parameter names, in declaration order."""
        return tuple(_field_types(cls))

    @classmethod
    def callable_params(cls) -> dict[str, str]:
        """Parameter name -> the kind of callable it names, for the parameters typed ``NamesCallable``.

        >>> from steer_envs.bench.suites.itps_kitchen.suite import SteerParams
        >>> SteerParams.callable_params()
        {'loader': 'policy loader'}
        """
        return {name: marker.kind for name, hint in _field_types(cls).items() if (marker := _names(hint)) is not None}

    @classmethod
    def from_json(cls, values: Mapping[str, Any], *, suite: str | None = None) -> Self:
        """The typed parameters for ``values`` (missing names keep their defaults).

        ``suite`` names the suite in errors (default: :attr:`suite_name`). Raises
        ``ValueError`` for an unknown name or a value of the wrong type.
        """
        if not isinstance(values, Mapping):
            raise TypeError(f"values must be a mapping of parameter names to values, got {type(values).__name__}")
        label = suite or cls._suite_label()
        hints = _field_types(cls)
        for name in values:
            if name not in hints:
                raise ValueError(f"suite {label!r} has no parameter {name!r}; parameters: {sorted(hints)}")
        return cls(**{name: _coerce(label, name, value, hints[name]) for name, value in values.items()})

    def to_json(self) -> dict[str, Any]:
        """The parameters as a JSON-compatible dict (``Trial.params``): tuples as lists."""
        return {f.name: _jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}  # type: ignore[arg-type]

    def replace(self, **changes: Any) -> Self:
        """A copy with ``changes`` applied, coerced and validated like :meth:`from_json`."""
        return type(self).from_json({**self.to_json(), **changes})

    def kwargs(self, *, without: Collection[str] = ()) -> dict[str, Any]:
        """The parameters as keyword arguments (typed values), but for those named in ``without``.

        For a trial function whose protocol takes the suite's parameters by their names.

        >>> from steer_envs.bench.suites.selftest import SelftestParams
        >>> SelftestParams(samples=10).kwargs(without=("fail_seeds",))
        {'samples': 10, 'sleep': 0.0}
        """
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name not in without}  # type: ignore[arg-type]

    # ------------------------------------------------------------ validation helpers
    def require(self, name: str, ok: bool, expected: str) -> None:
        """``ValueError`` naming the suite and parameter ``name`` unless ``ok``; ``expected`` says what it must be."""
        if not ok:
            label = self._suite_label()
            raise ValueError(f"{label}: parameter {name!r} must be {expected}, got {getattr(self, name)!r}")

    def require_at_least(self, low: float, *names: str) -> None:
        """Each parameter in ``names`` must be ``>= low``."""
        for name in names:
            self.require(name, getattr(self, name) >= low, f">= {low}")

    def require_at_most(self, high: float, *names: str) -> None:
        """Each parameter in ``names`` must be ``<= high`` (a bound on counts that would exhaust memory or time)."""
        for name in names:
            self.require(name, getattr(self, name) <= high, f"<= {high}")

    def require_between(self, low: float, high: float, *names: str) -> None:
        """Each parameter in ``names`` must be ``>= low`` and ``<= high`` (:meth:`require_at_least`, then at most)."""
        self.require_at_least(low, *names)
        self.require_at_most(high, *names)

    def require_in(self, name: str, choices: Collection[Any]) -> None:
        """Parameter ``name`` must be one of ``choices``."""
        self.require(name, getattr(self, name) in choices, f"one of {tuple(choices)}")


@dataclasses.dataclass(frozen=True)
class NoParams(SuiteParams):
    """The parameters of a suite that has none."""


def params_from_defaults(suite: str, defaults: Mapping[str, Any]) -> SuiteParams:
    """A :class:`SuiteParams` instance for a plain mapping of defaults (each typed by its default).

    Lets a suite declared with ``params={...}`` work like a typed one; a
    ``None`` default accepts any value.

    >>> p = params_from_defaults("toy", {"scale": 1.0, "tags": []})
    >>> p.from_json({"scale": 2}).to_json()
    {'scale': 2.0, 'tags': []}
    """
    specs: list[tuple[str, Any, Any]] = []
    for name, value in defaults.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise ValueError(f"suite {suite!r}: parameter names must be identifiers, got {name!r}")
        kind: Any = Any if value is None else type(value)
        default = (
            dataclasses.field(default_factory=functools.partial(type(value), value))
            if isinstance(value, (list, dict))
            else dataclasses.field(default=value)
        )
        specs.append((name, kind, default))
    cls = dataclasses.make_dataclass(
        "Params", specs, bases=(SuiteParams,), frozen=True, namespace={"suite_name": suite}
    )
    instance: SuiteParams = cls()
    return instance


def check_callable_params(
    params_type: type[SuiteParams], values: Mapping[str, Any], *, suite: str, allow_import: bool
) -> dict[str, str]:
    """Check the ``values`` a user gave for parameters that name code (``--param``); returns those it lets import.

    A value of a :meth:`~SuiteParams.callable_params` parameter must be a
    registered name or path (:func:`~steer_envs.utils.imports.named_callable`);
    any other ``"module:function"`` is refused with a ``ValueError`` naming the
    suite and parameter and listing the registered choices, unless
    ``allow_import``. Returns parameter -> path for the values that import
    unregistered code (empty without ``allow_import``). Values of the wrong
    type are left to :meth:`SuiteParams.from_json`.

    >>> from steer_envs.bench.suites.itps_kitchen.suite import SteerParams
    >>> check_callable_params(SteerParams, {"loader": "pretrained"}, suite="itps-kitchen", allow_import=False)
    {}
    >>> check_callable_params(SteerParams, {"loader": "builtins:print"}, suite="itps-kitchen", allow_import=True)
    {'loader': 'builtins:print'}
    """
    kinds = params_type.callable_params()
    imports: dict[str, str] = {}
    for name, value in values.items():
        if name not in kinds or not isinstance(value, str):
            continue
        what = f"suite {suite!r}: parameter {name!r}"
        path = named_callable(value, kinds[name], what=what, allow_import=allow_import, opt_in="--allow-import")
        if path not in registered_callables(kinds[name]).values():
            imports[name] = path
    return imports


def check_suite_params(suite: str, params: SuiteParams | Mapping[str, Any]) -> SuiteParams:
    """A suite's default parameters: a frozen :class:`SuiteParams` dataclass instance (a mapping of defaults is
    converted by :func:`params_from_defaults`), its fields typed and its values JSON with finite numbers.

    >>> check_suite_params("demo", {"episodes": 3})
    Params(episodes=3)
    """
    if isinstance(params, Mapping):
        params = params_from_defaults(suite, params)
    params_type = type(params)
    frozen = dataclasses.is_dataclass(params) and params_type.__dataclass_params__.frozen  # type: ignore[attr-defined]
    if not (isinstance(params, SuiteParams) and frozen):
        raise TypeError(
            f"Suite {suite!r}: params must be an instance of a frozen dataclass deriving from SuiteParams "
            f"(or a mapping of defaults), got {params_type.__name__}"
        )
    params_type.field_names()  # resolves the field types (TypeError on a name that shadows a method)
    try:
        json.dumps(params.to_json(), allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"Suite {suite!r}: default params must be JSON with finite numbers: {exc}") from None
    return params


# ------------------------------------------------------------------ coercion
_FIELD_TYPES: dict[type, dict[str, Any]] = {}


def _field_types(cls: type) -> dict[str, Any]:
    """Field name -> resolved type annotation (cached per class)."""
    if cls not in _FIELD_TYPES:
        if not dataclasses.is_dataclass(cls):
            raise TypeError(f"{cls.__name__} must be a dataclass (decorate it with @dataclass(frozen=True))")
        hints = typing.get_type_hints(cls, include_extras=True)
        for f in dataclasses.fields(cls):
            if hasattr(SuiteParams, f.name):
                raise TypeError(f"{cls.__name__}: parameter {f.name!r} shadows SuiteParams.{f.name}; rename it")
        _FIELD_TYPES[cls] = {f.name: hints.get(f.name, Any) for f in dataclasses.fields(cls)}
    return _FIELD_TYPES[cls]


def _names(annotation: Any) -> NamesCallable | None:
    """The :class:`NamesCallable` marker of an ``Annotated`` type, else None."""
    if typing.get_origin(annotation) is not Annotated:
        return None
    return next((m for m in annotation.__metadata__ if isinstance(m, NamesCallable)), None)


def _type_name(annotation: Any) -> str:
    marker = _names(annotation)
    if marker is not None:
        return f"a registered {marker.kind} or a 'module:function' path"
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is Annotated:
        return _type_name(args[0])
    if origin in (typing.Union, types.UnionType):
        return " or ".join("null" if a is type(None) else _type_name(a) for a in args)
    if origin in (tuple, list):
        return f"a list of {_type_name(args[0])}" if args else "a list"
    if annotation is float:
        return "finite float"
    return getattr(annotation, "__name__", str(annotation))


def _short_repr(value: Any, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _coerce(suite: str, name: str, value: Any, annotation: Any) -> Any:
    """``value`` as an instance of ``annotation`` (``ValueError`` naming suite and parameter otherwise)."""
    try:
        return _convert(value, annotation)
    except (TypeError, ValueError, OverflowError):
        if annotation is bool:
            raise ValueError(
                f"suite {suite!r}: parameter {name!r} must be true/false, got {_short_repr(value)}"
            ) from None
        raise ValueError(
            f"suite {suite!r}: parameter {name!r} must be {_type_name(annotation)}, got {_short_repr(value)}"
        ) from None


def _convert(value: Any, annotation: Any) -> Any:
    if annotation is Any:
        return value
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is Annotated:
        value = _convert(value, args[0])
        marker = _names(annotation)
        if marker is None:
            return value
        # a registered name stands for its path; which paths may be imported is the caller's check
        return named_callable(value, marker.kind, what="value", allow_import=True)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(value, arg)
            except (TypeError, ValueError):
                continue
        raise TypeError(value)
    if origin in (tuple, list) or annotation in (tuple, list):
        if not isinstance(value, (list, tuple)):
            raise TypeError(value)
        item = args[0] if args else Any
        items = [_convert(v, item) for v in value]
        return tuple(items) if (origin or annotation) is tuple else items
    if annotation is bool:
        if isinstance(value, bool):
            return value
        raise TypeError(value)
    if isinstance(value, bool):  # bool is an int subclass: never a number here
        raise TypeError(value)
    if annotation is int:
        if isinstance(value, int):
            return value
        if isinstance(value, float) and value.is_integer():
            return int(value)
        raise TypeError(value)
    if annotation is float:
        if isinstance(value, (int, float)):
            number = float(value)  # OverflowError (an ArithmeticError) for a huge int
            if math.isfinite(number):
                return number
        raise TypeError(value)
    if isinstance(annotation, type):
        if isinstance(value, annotation):
            return value
        raise TypeError(value)
    return value


def _jsonable(value: Any) -> Any:
    if isinstance(value, (tuple, list)):
        return [_jsonable(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _jsonable(v) for k, v in value.items()}
    return value
