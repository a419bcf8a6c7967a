"""Objects named by ``"module:qualname"`` strings: how suites, executors and loaders refer to code."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

__all__ = ["resolve_function"]


def resolve_function(path: str) -> Callable[..., Any]:
    """Import ``"module:qualname"`` and return the object.

    >>> resolve_function("math:sqrt")(9.0)
    3.0
    """
    if not isinstance(path, str) or path.count(":") != 1:
        raise ValueError(f"function path must be 'module:qualname', got {path!r}")
    module_name, qualname = path.split(":")
    obj: Any = importlib.import_module(module_name)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj
