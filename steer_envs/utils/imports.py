"""Objects named by ``"module:qualname"`` strings: how suites, executors and loaders refer to code.

A suite's own declarations (its trial function, its plot hook) name code by
path, and :func:`resolve_function` imports it. A *parameter* that names code
(a policy loader) is user input, so it names a *registered* callable:
:func:`register_callable` files a path under a kind and a short name, and
:func:`named_callable` turns a parameter's value (the name, or the path it
stands for) into the path, refusing any other import unless the caller
allows it (``steer-bench run --allow-import``).

>>> named_callable("pretrained", POLICY_LOADER, what="parameter 'loader'")
'steer_envs.baselines.pretrained:load_pretrained'
>>> named_callable("os:system", POLICY_LOADER, what="parameter 'loader'")
Traceback (most recent call last):
ValueError: parameter 'loader' names code: 'os:system' is not a registered policy loader; registered: pretrained (...
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable
from typing import Any

__all__ = ["POLICY_LOADER", "named_callable", "register_callable", "registered_callables", "resolve_function"]

#: the kind of the callables a policy-loader parameter names: ``loader(name)`` returns a TrajectoryPolicy
POLICY_LOADER = "policy loader"

#: kind -> name -> ``"module:qualname"``: the callables a parameter may name without an explicit import opt-in
_REGISTERED: dict[str, dict[str, str]] = {
    POLICY_LOADER: {"pretrained": "steer_envs.baselines.pretrained:load_pretrained"},
}

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
_PATH = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_][\w.]*")


def resolve_function(path: str) -> Callable[..., Any]:
    """Import ``"module:qualname"`` and return the object.

    For the project's own declarations (a suite's trial function and plot
    hook); a user's parameter goes through :func:`named_callable` first.

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


def register_callable(kind: str, name: str, path: str) -> None:
    """File ``path`` (``"module:qualname"``) as ``name`` among the callables of ``kind`` a parameter may name.

    Nothing is imported here. ``name`` is letters, digits, ``_``, ``-`` and
    ``.`` (no ``:``, so it never reads as a path). Registering the same name
    and path again does nothing; another path under a taken name is a
    ``ValueError``. A plugin (``steer-bench --plugin``) registers its own loaders this way.

    >>> register_callable(POLICY_LOADER, "pretrained", "steer_envs.baselines.pretrained:load_pretrained")
    """
    for label, value in (("kind", kind), ("name", name), ("path", path)):
        if not isinstance(value, str) or not value:
            raise TypeError(f"register_callable: `{label}` must be a non-empty str, got {value!r}")
    if not _NAME.fullmatch(name):
        raise ValueError(f"register_callable: `name` must be letters, digits, '_', '-' or '.', got {name!r}")
    if not _PATH.fullmatch(path):
        raise ValueError(f"register_callable: `path` must be 'module:qualname', got {path!r}")
    known = _REGISTERED.setdefault(kind, {})
    if known.get(name, path) != path:
        raise ValueError(f"register_callable: {kind} {name!r} is already registered as {known[name]!r}")
    known[name] = path


def registered_callables(kind: str) -> dict[str, str]:
    """Name -> path of the registered callables of ``kind`` (a copy; empty for an unknown kind).

    >>> registered_callables(POLICY_LOADER)["pretrained"]
    'steer_envs.baselines.pretrained:load_pretrained'
    """
    return dict(_REGISTERED.get(kind, {}))


def named_callable(
    value: str, kind: str, *, what: str, allow_import: bool = False, opt_in: str = "allow_import=True"
) -> str:
    """The ``"module:qualname"`` path that a parameter's ``value`` names, among the callables of ``kind``.

    A registered name gives its path and a registered path is kept. Any other
    ``"module:qualname"`` is taken as is only with ``allow_import=True``;
    without it, and for any value that is neither a name nor a path, a
    ``ValueError`` names ``what`` (e.g. ``"parameter 'loader'"``), lists the
    registered choices and says that ``opt_in`` imports any path.
    """
    if not isinstance(value, str):
        raise TypeError(f"{what} must be a str naming a {kind}, got {type(value).__name__} {value!r}")
    known = registered_callables(kind)
    if value in known:
        return known[value]
    if value in known.values() or (allow_import and _PATH.fullmatch(value)):
        return value
    choices = ", ".join(f"{n} ({p})" for n, p in sorted(known.items())) or "none"
    if _PATH.fullmatch(value):
        raise ValueError(
            f"{what} names code: {value!r} is not a registered {kind}; registered: {choices}. "
            f"{opt_in} imports and runs any module:function"
        )
    raise ValueError(
        f"{what} must name a registered {kind} or a 'module:function' path, got {value!r}; registered: {choices}"
    )
