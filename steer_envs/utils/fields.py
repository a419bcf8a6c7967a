"""Forwarding settings by name: the keyword arguments a class or function takes from another object's fields.

Suite parameters, command-line namespaces and settings dataclasses often
describe the same knobs under the same names; :func:`same_named` reads them
across once, so a new field needs no new forwarding line and a renamed one
cannot be forwarded half-way.

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Setup:
...     epochs: int = 10
...     heads: int = 1
>>> @dataclass(frozen=True)
... class Params:
...     epochs: int = 50
...     heads: int = 5
...     plot_seeds: int = 1
>>> build_from(Setup, Params(), heads=2)
Setup(epochs=50, heads=2)
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable
from typing import Any, TypeVar

__all__ = ["build_from", "same_named"]

T = TypeVar("T")


def _accepted(target: Callable[..., Any]) -> list[str]:
    """The names ``target`` takes by keyword: a dataclass's init fields, else a callable's keyword-only parameters."""
    if isinstance(target, type) and dataclasses.is_dataclass(target):
        return [f.name for f in dataclasses.fields(target) if f.init]
    params = inspect.signature(target).parameters.values()
    return [p.name for p in params if p.kind is inspect.Parameter.KEYWORD_ONLY]


def _values(source: Any) -> dict[str, Any]:
    """``source``'s own values: a dataclass instance's fields, else its instance attributes (``vars``)."""
    if dataclasses.is_dataclass(source) and not isinstance(source, type):
        return {f.name: getattr(source, f.name) for f in dataclasses.fields(source)}
    return dict(vars(source))


def same_named(target: Callable[..., Any], source: Any, /, **overrides: Any) -> dict[str, Any]:
    """Keyword arguments for ``target`` from the same-named values of ``source``, then ``overrides``.

    ``target`` is a dataclass (its init fields count) or a function (its
    keyword-only parameters count); ``source`` is a dataclass instance (its
    fields) or any object with attributes (e.g. an ``argparse.Namespace``).
    Names ``source`` lacks are left to ``target``'s defaults.

    >>> import argparse
    >>> def serve(*, host: str = "localhost", port: int = 80) -> None: ...
    >>> same_named(serve, argparse.Namespace(port=8765, verbose=True))
    {'port': 8765}
    """
    values = _values(source)
    return {**{name: values[name] for name in _accepted(target) if name in values}, **overrides}


def build_from(cls: Callable[..., T], source: Any, /, **overrides: Any) -> T:
    """``cls(**same_named(cls, source, **overrides))``: a settings object from the same-named values of ``source``."""
    return cls(**same_named(cls, source, **overrides))
