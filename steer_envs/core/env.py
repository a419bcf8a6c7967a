"""The steer-env contract: what every steer-envs environment offers besides the Gymnasium API.

Steering wrappers, scripted experts and benchmark suites rely on more than
``reset``/``step``: the env's discrete task structure, its state, a way to
push the agent from outside, the interactions it accepts, and the keys its
``info`` carries. This module writes that contract down as structural
``typing.Protocol`` s, so any env with the right members qualifies (no base
class to inherit), and gives library code a typed way in:

* :class:`SteerEnv` - ``task`` (a :class:`~steer_envs.core.task.TaskSpec`),
  ``state``, ``perturb(delta=... | to=...)`` and ``interaction_kinds``;
  :class:`HasTask`, :class:`PerturbableEnv` and :class:`HasInteractionKinds`
  are its parts, for code that needs only one of them.
* :func:`steer_env`, :func:`perturbable_env`, :func:`task_of` - unwrap a
  (possibly wrapped) env and check it, raising a ``TypeError`` that names what
  is missing instead of an ``AttributeError`` deep inside a wrapper.
* The ``info`` keys every ``reset``/``step``/``perturb`` returns, as constants
  (:data:`INFO_KEYS`, :data:`PERTURBED`).
* :class:`ClosableEnv` - the base of the steer envs' classes: after ``close()``
  their ``reset``/``step``/``perturb``/``render`` raise :class:`EnvClosedError`
  naming the env, not an ``AttributeError`` from a simulator that is gone.

The protocols are ``runtime_checkable``: ``isinstance`` checks that the
members exist, not their types or behaviour. :func:`steer_envs.utils.env_checker.check_steer_env`
checks the behaviour.

>>> import gymnasium as gym
>>> import steer_envs
>>> env = gym.make("steer_envs/ConvexMode-v0")
>>> base = steer_env(env)  # the unwrapped env, typed as a SteerEnv
>>> base.task.modes
('inside', 'outside')
>>> _, info = env.reset(seed=0)
>>> sorted(INFO_KEYS) == sorted(k for k in info if k != PERTURBED)
True
>>> base.perturb(delta=[0.1, 0.0])[PERTURBED]
True
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from typing import Any, ClassVar, Protocol, TypeVar, cast, get_args, runtime_checkable

import gymnasium as gym
import numpy as np
from gymnasium.error import ClosedEnvironmentError

from steer_envs.core.interaction import InteractionKind
from steer_envs.core.task import TaskSpec

__all__ = [
    "CONSTRAINT_VIOLATION",
    "INFO_KEYS",
    "INTERACTION_KINDS",
    "IS_SUCCESS",
    "MODE",
    "MODE_NAME",
    "PERTURBED",
    "SENSORS",
    "STEER_ENV_MEMBERS",
    "SUCCESS",
    "ClosableEnv",
    "EnvClosedError",
    "HasInteractionKinds",
    "HasTask",
    "PerturbableEnv",
    "SteerEnv",
    "env_name",
    "perturbable_env",
    "steer_env",
    "task_of",
]

# ------------------------------------------------------------------ info keys
#: ``int``: index of the current mode in ``task.modes``.
MODE = "mode"
#: ``str``: ``task.modes[info["mode"]]``.
MODE_NAME = "mode_name"
#: ``dict[str, bool]``: the reading of every sensor AP in ``task.sensors``.
SENSORS = "sensors"
#: ``bool``: the task is complete (a goal mode was reached).
SUCCESS = "success"
#: ``bool``: the same value as ``info["success"]``, under the name stable-baselines3 reads
#: (``Monitor`` / ``ep_success_buffer``, as ``is_success`` in its episode info).
IS_SUCCESS = "is_success"
#: ``bool``: the step broke a task constraint (an invalid mode transition, a spill, a wall contact).
CONSTRAINT_VIOLATION = "constraint_violation"
#: ``bool``: the info came from :meth:`PerturbableEnv.perturb` (True there); optional elsewhere.
PERTURBED = "perturbed"
#: keys every ``reset``, ``step`` and ``perturb`` info carries.
INFO_KEYS: tuple[str, ...] = (MODE, MODE_NAME, SENSORS, SUCCESS, IS_SUCCESS, CONSTRAINT_VIOLATION)
#: every interaction kind an env may accept (see :mod:`steer_envs.core.interaction`).
INTERACTION_KINDS: tuple[InteractionKind, ...] = get_args(InteractionKind)
#: the members a :class:`SteerEnv` has.
STEER_ENV_MEMBERS: tuple[str, ...] = ("task", "state", "perturb", "interaction_kinds")


# ------------------------------------------------------------------ protocols
@runtime_checkable
class HasTask(Protocol):
    """An env that declares its discrete task structure (modes, sensor APs, transitions)."""

    @property
    def task(self) -> TaskSpec:
        """The task; ``info["mode"]`` indexes ``task.modes``, ``info["sensors"]`` has ``task.sensors`` as keys."""
        ...


@runtime_checkable
class PerturbableEnv(Protocol):
    """An env whose agent state can be read and pushed from outside."""

    @property
    def state(self) -> np.ndarray:
        """The agent's state (a float64 copy; for the 2D envs, its xy)."""
        ...

    def perturb(self, delta: Any = None, *, to: Any = None) -> dict[str, Any]:
        """Displace the agent by ``delta`` or move it ``to`` a state: a push that is not the policy's doing.

        Exactly one of ``delta`` and ``to`` is given (``ValueError`` otherwise);
        non-numeric input raises ``TypeError``, a wrong shape or NaN ``ValueError``.
        The push itself is no constraint violation. Returns the new ``info``
        (every key of :data:`INFO_KEYS`, and ``info["perturbed"] is True``).
        """
        ...


@runtime_checkable
class HasInteractionKinds(Protocol):
    """An env that declares which user interactions may steer a policy in it."""

    @property
    def interaction_kinds(self) -> tuple[str, ...]:
        """A non-empty tuple of distinct kinds from :data:`INTERACTION_KINDS`."""
        ...


@runtime_checkable
class SteerEnv(HasTask, PerturbableEnv, HasInteractionKinds, Protocol):
    """The full steer-env contract: a task, a state to push, and the interactions a user may give."""


# ------------------------------------------------------------------- access
def env_name(env: Any) -> str:
    """A readable name for ``env`` in messages: its registered id, else its class name.

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> env_name(gym.make("steer_envs/ConvexMode-v0"))
    'steer_envs/ConvexMode-v0'
    """
    spec = getattr(env, "spec", None)
    if spec is not None and getattr(spec, "id", None):
        return str(spec.id)
    return type(getattr(env, "unwrapped", env)).__name__


def _unwrap(env: Any, members: tuple[str, ...], who: str) -> Any:
    base = getattr(env, "unwrapped", env)
    missing = [m for m in members if not hasattr(base, m)]
    if missing:
        raise TypeError(
            f"{who}: `env` must be a steer env with {', '.join(f'`{m}`' for m in members)}; "
            f"{env_name(env)} ({type(base).__name__}) lacks {', '.join(f'`{m}`' for m in missing)}"
        )
    if "task" in members and not isinstance(base.task, TaskSpec):
        raise TypeError(f"{who}: `env.task` must be a TaskSpec, got {type(base.task).__name__} in {env_name(env)}")
    if "perturb" in members and not callable(base.perturb):
        raise TypeError(f"{who}: `env.perturb` must be callable, got {type(base.perturb).__name__} in {env_name(env)}")
    return base


def steer_env(env: Any, *, who: str = "steer_env") -> SteerEnv:
    """The unwrapped ``env``, checked to have every member of :class:`SteerEnv`.

    Args:
        env: a (possibly wrapped) Gymnasium env, or an unwrapped one.
        who: the caller, named in the error message.

    Raises:
        TypeError: a member is missing (the message lists which) or ``task`` is not a TaskSpec.

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> steer_env(gym.make("steer_envs/Maze2D-Umaze-v0")).interaction_kinds
    ('point', 'sketch', 'nudge')
    >>> steer_env(gym.make("CartPole-v1"))
    Traceback (most recent call last):
    ...
    TypeError: steer_env: ... CartPole-v1 (CartPoleEnv) lacks `task`, `perturb`, `interaction_kinds`
    """
    return cast(SteerEnv, _unwrap(env, STEER_ENV_MEMBERS, who))


def perturbable_env(env: Any, *, who: str = "perturbable_env") -> PerturbableEnv:
    """The unwrapped ``env``, checked to have ``state`` and ``perturb`` (:class:`PerturbableEnv`).

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> perturbable_env(gym.make("steer_envs/ConvexMode-v0")).state.shape
    (2,)
    """
    return cast(PerturbableEnv, _unwrap(env, ("state", "perturb"), who))


def task_of(env: Any, *, who: str = "task_of") -> TaskSpec:
    """The :class:`~steer_envs.core.task.TaskSpec` of a (possibly wrapped) env (:class:`HasTask`).

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> task_of(gym.make("steer_envs/SoupScoop-v0")).sensors
    ('r', 's', 't')
    """
    return cast(HasTask, _unwrap(env, ("task",), who)).task


# ------------------------------------------------------------------ lifecycle
ObsT = TypeVar("ObsT")
ActT = TypeVar("ActT")


class EnvClosedError(ClosedEnvironmentError, RuntimeError):
    """A call on a steer env after its ``close()``: its simulator and renderer are gone, make a new env.

    A ``RuntimeError`` and Gymnasium's ``ClosedEnvironmentError``, so either ``except`` catches it.
    """


def _refuse_when_closed(method: Callable[..., Any], call: str) -> Callable[..., Any]:
    @functools.wraps(method)
    def guarded(self: ClosableEnv[Any, Any], *args: Any, **kwargs: Any) -> Any:
        if self._is_closed:
            name = env_name(self)
            raise EnvClosedError(f"{name} is closed: {call}() after close(); make a new env")
        return method(self, *args, **kwargs)

    guarded._closed_guard = True  # type: ignore[attr-defined]
    return guarded


def _close_once(close: Callable[..., Any]) -> Callable[..., Any]:
    @functools.wraps(close)
    def once(self: ClosableEnv[Any, Any], *args: Any, **kwargs: Any) -> Any:
        if self._is_closed:
            return None
        try:
            return close(self, *args, **kwargs)
        finally:
            self._is_closed = True

    once._closed_guard = True  # type: ignore[attr-defined]
    return once


class ClosableEnv(gym.Env[ObsT, ActT]):
    """A Gymnasium env that refuses to be used once closed: the base class of the steer envs.

    After ``close()``, the methods named in :attr:`closed_calls` (``reset``,
    ``step``, ``perturb``, ``render``) raise :class:`EnvClosedError` naming the
    env (its registered id), instead of failing inside a simulator whose
    handles are gone. ``close()`` may be called again (Gymnasium's convention):
    it then does nothing. A subclass's own ``close`` and its own definitions of
    the :attr:`closed_calls` are wrapped when the class is created, so an
    override is checked before its first line runs; a subclass adds methods to
    the check by extending :attr:`closed_calls`.

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> env = gym.make("steer_envs/ConvexMode-v0")
    >>> _ = env.reset(seed=0)
    >>> env.close(); env.close()
    >>> env.unwrapped.closed
    True
    >>> env.step([0.0, 0.0])
    Traceback (most recent call last):
    ...
    steer_envs.core.env.EnvClosedError: steer_envs/ConvexMode-v0 is closed: step() after close(); make a new env
    """

    #: the methods that raise :class:`EnvClosedError` once the env is closed
    closed_calls: ClassVar[tuple[str, ...]] = ("reset", "step", "perturb", "render")
    _is_closed: bool = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        for name in (*cls.closed_calls, "close"):
            method = cls.__dict__.get(name)
            if not inspect.isfunction(method) or getattr(method, "_closed_guard", False):
                continue
            setattr(cls, name, _close_once(method) if name == "close" else _refuse_when_closed(method, name))

    @property
    def closed(self) -> bool:
        """Whether ``close()`` was called (the env then refuses :attr:`closed_calls`)."""
        return self._is_closed

    def close(self) -> None:
        """Release the env's resources; later calls of :attr:`closed_calls` raise :class:`EnvClosedError`."""
        self._is_closed = True
        super().close()
