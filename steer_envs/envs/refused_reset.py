"""A refused ``reset`` changes nothing, in the wrappers ``gymnasium.make`` puts around an env as in the env.

``gymnasium.make`` wraps an env in ``PassiveEnvChecker``, ``OrderEnforcing`` and
``TimeLimit``, and each of them books a ``reset`` before the env has accepted
it. When the env refuses the call (a ``ValueError`` for an unknown option),
the checker has marked its one-time reset check as done without the data
its first ``step`` compares against, so that ``step`` fails with ``TypeError:
cannot unpack non-iterable NoneType object`` even after a valid ``reset``;
``OrderEnforcing`` lets ``step`` through although no reset ever succeeded; and
``TimeLimit`` restarts the step count of an episode that goes on.

The steer envs check every ``reset`` argument before they change anything,
so a refused reset leaves the episode as it was. :func:`install` gives the
three wrappers the same rule: when the ``reset`` they wrap raises, each puts
its own bookkeeping back as it was before the call. While ``reset``
succeeds nothing changes. The bookkeeping is Gymnasium's, so the rule holds
for every env made in the process; ``import steer_envs`` installs it.

>>> import gymnasium as gym
>>> import steer_envs
>>> env = gym.make("steer_envs/SoupScoop-v0")
>>> env.reset(options={"bogus": 1})
Traceback (most recent call last):
ValueError: SoupScoopEnv.reset: unknown reset options ['bogus']; expected some of ['state']
>>> _ = env.reset(seed=0)
>>> env.step([0.0, 0.0])[2:4]
(False, False)
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker, TimeLimit

__all__ = ["BOOKKEEPING", "install"]

#: wrapper class -> the attributes its ``reset`` sets before the wrapped env's ``reset`` returns
BOOKKEEPING: dict[type, tuple[str, ...]] = {
    PassiveEnvChecker: ("checked_reset", "_previous_data"),
    OrderEnforcing: ("_has_reset",),
    TimeLimit: ("_elapsed_steps",),
}

_MARK = "_steer_envs_keeps_refused_reset"


def _undone_when_refused(reset: Callable[..., Any], names: tuple[str, ...]) -> Callable[..., Any]:
    """``reset`` that, when it raises, restores the wrapper's ``names`` (those it had) before re-raising."""

    @functools.wraps(reset)
    def guarded(self: Any, *args: Any, **kwargs: Any) -> Any:
        before = {name: vars(self)[name] for name in names if name in vars(self)}
        try:
            return reset(self, *args, **kwargs)
        except Exception:
            vars(self).update(before)
            raise

    setattr(guarded, _MARK, True)
    return guarded


def install() -> None:
    """Make each wrapper of :data:`BOOKKEEPING` undo its bookkeeping when the reset it wraps raises (idempotent)."""
    for cls, names in BOOKKEEPING.items():
        reset = cls.__dict__.get("reset")
        if reset is None or getattr(reset, _MARK, False):
            continue
        setattr(cls, "reset", _undone_when_refused(reset, names))  # noqa: B010 - a method replaced on its class
