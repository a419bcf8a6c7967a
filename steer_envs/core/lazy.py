"""Lazy package exports: a package names its public objects and imports each one's submodule on first use.

A package whose submodules are slow to import (torch, cvxpy, robosuite) keeps
``import package`` cheap with a module-level ``__getattr__`` (PEP 562) that
imports the submodule when a name is first asked for::

    _EXPORTS = {"Name": "submodule", ...}  # the public name -> the submodule that defines it
    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, MutableMapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str, exports: Mapping[str, str], namespace: MutableMapping[str, Any]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """A package's module-level ``__getattr__`` and ``__dir__`` for names it imports lazily.

    ``exports``: public name -> the submodule of ``package`` that defines it;
    ``namespace``: the package's ``globals()``. ``__getattr__(name)`` imports
    ``package.<exports[name]>``, caches the object in ``namespace`` (so the
    import runs once) and returns it; a name the package does not export
    raises the ``AttributeError`` Python raises for a missing module
    attribute (so ``hasattr`` and ``getattr(..., default)`` work).
    ``__dir__()`` lists the namespace and the exports.

    >>> namespace = {}
    >>> getattr_, dir_ = lazy_exports("os", {"join": "path"}, namespace)
    >>> getattr_("join").__name__, sorted(namespace), dir_()
    ('join', ['join'], ['join'])
    >>> getattr_("split_all")
    Traceback (most recent call last):
    AttributeError: module 'os' has no attribute 'split_all'
    """

    def __getattr__(name: str) -> Any:
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{exports[name]}"), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *exports})

    return __getattr__, __dir__
