"""Optional dependencies: import one, or raise an ``ImportError`` that says which extra installs it.

The bare ``pip install steer-envs`` covers the 2D envs, LTL, the wrappers,
the policies and the benchmark runner. Heavier features sit behind extras
named for the feature (``setup.cfg``; :data:`EXTRAS`):
``arm`` (robosuite: the arm envs), ``rl`` (stable-baselines3), ``minari``
(Minari export), ``ray`` (the Ray executor), ``ui`` (the steer-ui web
server), ``onnx`` / ``openvino`` (faster Diffusion Policy inference),
``human`` (pygame windows), ``robomimic`` (h5py: robomimic HDF5 datasets),
``lerobot`` (LeRobot: its policies and LeRobotDataset); ``all`` is every one
of them but ``lerobot``, whose own pins (torch, diffusers) clash with the
others' (it goes into an environment of its own, see
``scripts/test_interop.sh``).

A feature imports its optional package through :func:`require`, so a user
without the extra gets :class:`MissingExtraError` (an ``ImportError``) naming
the command to run, not a ``ModuleNotFoundError`` from deep inside.

>>> import math
>>> require("math", "arm", "the arm envs") is math
True
>>> require("nope", "arm", "Lift")
Traceback (most recent call last):
steer_envs.core.extras.MissingExtraError: Lift needs nope, which is not installed: pip install "steer-envs[arm]"
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

from gymnasium.error import DependencyNotInstalled

__all__ = ["EXTRAS", "NOT_IN_ALL", "MissingExtraError", "install_command", "missing_modules", "require"]

#: the feature extras of ``setup.cfg`` (``all`` installs every one; ``dev`` and ``docs`` are for contributors).
EXTRAS: tuple[str, ...] = ("arm", "rl", "minari", "ray", "ui", "onnx", "openvino", "human", "robomimic", "lerobot")
#: the feature extras ``all`` leaves out (their pins clash with the rest)
NOT_IN_ALL: tuple[str, ...] = ("lerobot",)


def install_command(extra: str) -> str:
    """The shell command that installs ``extra``, quoted for every shell.

    >>> install_command("rl")
    'pip install "steer-envs[rl]"'
    """
    if extra not in (*EXTRAS, "all", "dev", "docs"):
        raise ValueError(f"unknown steer-envs extra {extra!r}; the extras: {', '.join(EXTRAS)}, all, dev, docs")
    return f'pip install "steer-envs[{extra}]"'


class MissingExtraError(ModuleNotFoundError, DependencyNotInstalled):
    """A feature's optional dependency is not installed; :attr:`extra` names the extra that installs it.

    An ``ImportError`` (a ``ModuleNotFoundError``), and Gymnasium's
    ``DependencyNotInstalled`` too, so code catching either sees it.
    """

    def __init__(self, message: str, *, name: str, extra: str) -> None:
        super().__init__(message, name=name)
        #: the extra that installs the missing package, e.g. ``"arm"``.
        self.extra = extra

    def __reduce__(self) -> tuple[object, ...]:  # picklable (process pools send it back from workers)
        return (_rebuild, (str(self), self.name, self.extra))


def _rebuild(message: str, name: str, extra: str) -> MissingExtraError:
    return MissingExtraError(message, name=name, extra=extra)


def require(module: str, extra: str, feature: str, *, package: str | None = None) -> ModuleType:
    """``importlib.import_module(module)``, or :class:`MissingExtraError` naming ``pip install "steer-envs[extra]"``.

    Args:
        module: the module to import, e.g. ``"robosuite"`` or ``"stable_baselines3.common.monitor"``.
        extra: the extra that installs it (one of :data:`EXTRAS`).
        feature: what needs it, the subject of the message (``"the arm envs (Lift, ...)"``).
        package: the distribution's name in the message (default: the top module, ``_`` -> ``-``).

    A module that is installed but fails to import for another reason than a
    missing module raises its own error unchanged.
    """
    hint = install_command(extra)
    top = module.split(".")[0]
    package = package or top.replace("_", "-")
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name is not None and exc.name.split(".")[0] == top:
            message = f"{feature} needs {package}, which is not installed: {hint}"
        else:  # installed, but one of its own dependencies is missing
            message = f"{feature} needs {package}, whose import failed ({exc}): {hint} installs it and its dependencies"
        raise MissingExtraError(message, name=module, extra=extra) from exc


def missing_modules(*modules: str) -> list[str]:
    """The ones of ``modules`` that are not installed (found without importing them).

    >>> missing_modules("math", "no_such_module_xyz")
    ['no_such_module_xyz']
    """
    out = []
    for name in modules:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # a parent package missing, or ``sys.modules[name] = None``
            found = False
        if not found:
            out.append(name)
    return out
