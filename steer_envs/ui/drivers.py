"""The controllers a push domain may name (:attr:`~steer_envs.ui.domains.Domain.controller`), built by name.

Its own module so that each controller's module may build on
:mod:`steer_envs.ui.controllers` while the registry imports them all; the
arm's (robosuite, a trained classifier) is imported only when asked for.

>>> sorted(CONTROLLERS)
['glide-bc-arm', 'glide-planning', 'ltl-ds']
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from steer_envs.core.validation import one_of
from steer_envs.ui.controllers import Controller, GlideController, LTLDSController

__all__ = ["CONTROLLERS", "make_controller"]


def _arm_glide(env: Any, **options: Any) -> Controller:
    from steer_envs.ui.arm_glide import GlideArmController

    return GlideArmController(env, **options)


#: name -> how a push session builds its controller from ``(env, options)``
CONTROLLERS: dict[str, Callable[..., Controller]] = {
    "ltl-ds": lambda env, **options: LTLDSController(env, **options),
    "glide-planning": lambda env, **options: GlideController(env, **options),
    "glide-bc-arm": _arm_glide,
}


def make_controller(name: str, env: Any, **options: Any) -> Controller:
    """The controller ``name`` of :data:`CONTROLLERS` for ``env`` (``options`` go to its constructor)."""
    return CONTROLLERS[one_of(name, "controller", tuple(CONTROLLERS), owner="make_controller")](env, **options)
