"""``check_steer_env``: check that an env follows the steer-env contract (:mod:`steer_envs.core.env`).

Gymnasium's :func:`gymnasium.utils.env_checker.check_env` checks the Gymnasium
API; this checks what the steering wrappers, the scripted experts and the
benchmark suites rely on on top of it. Run it on an env you wrote before
plugging it into them. Each convention has a name (the keys of
:data:`CONVENTIONS`); the first one broken raises a :class:`SteerEnvCheckError`
that names it and the env.

>>> import gymnasium as gym
>>> import steer_envs
>>> check_steer_env(gym.make("steer_envs/ConvexMode-v0"))  # passes silently
>>> try:
...     check_steer_env(gym.make("CartPole-v1"))
... except SteerEnvCheckError as err:
...     print(err.convention)
members
"""

from __future__ import annotations

import copy
import re
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env as gymnasium_check_env
from gymnasium.utils.env_checker import data_equivalence

from steer_envs.core import env as contract
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import integer

__all__ = ["CONVENTIONS", "SteerEnvCheckError", "check_steer_env"]

#: every convention :func:`check_steer_env` checks, name -> what it asks of the env.
CONVENTIONS: Mapping[str, str] = {
    "members": "the unwrapped env has `task` (a TaskSpec), `state`, `perturb` and `interaction_kinds`",
    "interaction_kinds": "`interaction_kinds` is a non-empty tuple of distinct kinds from 'point', 'sketch', 'nudge'",
    "gymnasium_api": "the unwrapped env passes gymnasium.utils.env_checker.check_env",
    "info_keys": "every reset/step/perturb info carries mode, mode_name, sensors, success, is_success, "
    "constraint_violation",
    "mode": "info['mode'] is an int in [0, task.num_modes) and info['mode_name'] is task.modes[info['mode']]",
    "sensors": "info['sensors'] maps exactly the APs of task.sensors to bool",
    "sensor_labelling": "where task.sensor_modes is given, task.mode_of(info['sensors']) == info['mode_name']",
    "flags": "info['success'] and info['constraint_violation'] are bool; info['perturbed'], if present, is False",
    "is_success": "info['is_success'] (the key stable-baselines3's Monitor reads) is the bool info['success']",
    "determinism": "the same seed (reset and action space) gives the same trajectory, another seed another one",
    "state": "`state` is a finite float 1-D array, returned as a copy",
    "perturb": "perturb(to=x) moves the agent to a reachable x, perturb(delta=d) equals perturb(to=state + d), "
    "and the returned info has every info key, perturbed=True and no constraint violation",
    "perturb_arguments": "perturb rejects a call without or with both arguments (ValueError), a NaN or wrongly "
    "shaped delta (ValueError naming `delta`) and a non-numeric `to` (TypeError naming `to`), "
    "and a rejected push leaves the state alone",
    "action_arguments": "step rejects a wrongly shaped Box action with a ValueError naming `action`, and a "
    "non-numeric one (strings) with a TypeError or ValueError; a rejected action leaves the state alone",
}


class SteerEnvCheckError(AssertionError):
    """An env broke a steer-env convention.

    Attributes:
        env: the env's name (its registered id or class name).
        convention: the broken convention, a key of :data:`CONVENTIONS`.
        detail: what was observed.
    """

    def __init__(self, env: str, convention: str, detail: str) -> None:
        super().__init__(f"{env} breaks the steer-env convention {convention!r} ({CONVENTIONS[convention]}): {detail}")
        self.env = env
        self.convention = convention
        self.detail = detail


class _Checker:
    def __init__(self, env: gym.Env[Any, Any], seed: int, steps: int) -> None:
        self.env = env
        self.name = contract.env_name(env)
        self.seed = seed
        self.steps = steps
        try:
            self.base: contract.SteerEnv = contract.steer_env(env, who="check_steer_env")
        except TypeError as err:
            raise SteerEnvCheckError(self.name, "members", str(err)) from None
        self.task: TaskSpec = self.base.task

    def fail(self, convention: str, detail: str) -> SteerEnvCheckError:
        return SteerEnvCheckError(self.name, convention, detail)

    def guarded(self, convention: str, check: Callable[[], None]) -> None:
        """Run ``check``; an unexpected exception is reported as a break of ``convention``."""
        try:
            check()
        except SteerEnvCheckError:
            raise
        except Exception as err:
            raise self.fail(convention, f"raised {type(err).__name__}: {err}") from err

    def refused(
        self,
        convention: str,
        call: str,
        fn: Callable[[], Any],
        expected: tuple[type[Exception], ...],
        argument: str | None,
        accepted: str,
    ) -> None:
        """``fn()`` (written ``call``) must raise one of ``expected``, naming ``argument`` where given.

        ``accepted``: the failure's detail when it raises nothing.
        """
        try:
            fn()
        except expected as err:
            if argument is not None and not re.search(rf"\b{argument}\b", str(err)):
                raise self.fail(convention, f"{call} raised {err!r}, which does not name `{argument}`") from err
        except Exception as err:
            names = " or ".join(e.__name__ for e in expected)
            raise self.fail(convention, f"{call} raised {type(err).__name__} (expected {names}): {err}") from err
        else:
            raise self.fail(convention, accepted)

    # ------------------------------------------------------------ static members
    def interaction_kinds(self) -> None:
        kinds = self.base.interaction_kinds
        if not isinstance(kinds, tuple) or not kinds:
            raise self.fail("interaction_kinds", f"got {kinds!r}")
        unknown = [k for k in kinds if k not in contract.INTERACTION_KINDS]
        if unknown or len(set(kinds)) != len(kinds):
            raise self.fail("interaction_kinds", f"got {kinds!r}")

    def gymnasium_api(self) -> None:
        try:
            gymnasium_check_env(self.env.unwrapped, skip_render_check=True)
        except Exception as err:
            raise self.fail("gymnasium_api", f"{type(err).__name__}: {err}") from err

    # ------------------------------------------------------------------- infos
    def info(self, info: Any, where: str, *, perturbed: bool = False) -> None:
        if not isinstance(info, Mapping):
            raise self.fail("info_keys", f"the {where} info is a {type(info).__name__}, not a dict")
        missing = [k for k in contract.INFO_KEYS if k not in info]
        if missing:
            raise self.fail("info_keys", f"the {where} info lacks {missing} (it has {sorted(info)})")
        task = self.task
        mode = info[contract.MODE]
        if isinstance(mode, bool) or not isinstance(mode, int) or not 0 <= mode < task.num_modes:
            raise self.fail("mode", f"{where}: info['mode'] = {mode!r} ({type(mode).__name__}), {task.num_modes} modes")
        if info[contract.MODE_NAME] != task.modes[mode]:
            raise self.fail(
                "mode",
                f"{where}: info['mode_name'] = {info[contract.MODE_NAME]!r}, mode {mode} is {task.modes[mode]!r}",
            )
        sensors = info[contract.SENSORS]
        if not isinstance(sensors, Mapping) or set(sensors) != set(task.sensors):
            keys = sorted(sensors) if isinstance(sensors, Mapping) else type(sensors).__name__
            raise self.fail("sensors", f"{where}: info['sensors'] has {keys}, task.sensors is {list(task.sensors)}")
        not_bool = {ap: type(v).__name__ for ap, v in sensors.items() if not isinstance(v, bool)}
        if not_bool:
            raise self.fail("sensors", f"{where}: readings that are not bool: {not_bool}")
        if task.sensor_modes:
            try:
                labelled = task.mode_of(sensors)
            except ValueError as err:
                raise self.fail("sensor_labelling", f"{where}: {err}") from None
            if labelled != info[contract.MODE_NAME]:
                raise self.fail(
                    "sensor_labelling",
                    f"{where}: sensors {dict(sensors)} label {labelled!r}, mode is {info[contract.MODE_NAME]!r}",
                )
        for key in (contract.SUCCESS, contract.CONSTRAINT_VIOLATION):
            if not isinstance(info[key], bool):
                raise self.fail("flags", f"{where}: info[{key!r}] = {info[key]!r} ({type(info[key]).__name__})")
        if not isinstance(info[contract.IS_SUCCESS], bool) or info[contract.IS_SUCCESS] != info[contract.SUCCESS]:
            raise self.fail(
                "is_success",
                f"{where}: info['is_success'] = {info[contract.IS_SUCCESS]!r} "
                f"({type(info[contract.IS_SUCCESS]).__name__}), "
                f"info['success'] = {info[contract.SUCCESS]!r}",
            )
        if perturbed:
            if info.get(contract.PERTURBED) is not True:
                raise self.fail("perturb", f"perturb returned info['perturbed'] = {info.get(contract.PERTURBED)!r}")
            if info[contract.CONSTRAINT_VIOLATION]:
                raise self.fail("perturb", "perturb reported a constraint violation (a push is not the policy's)")
        elif contract.PERTURBED in info and info[contract.PERTURBED] is not False:
            raise self.fail("flags", f"{where}: info['perturbed'] = {info[contract.PERTURBED]!r} outside perturb")

    # ------------------------------------------------------------- determinism
    def rollout(self, seed: int) -> tuple[list[Any], list[tuple[float, bool, bool, int]]]:
        env = self.env
        obs, info = env.reset(seed=seed)
        self.info(info, "reset")
        env.action_space.seed(seed)
        observations, outcomes = [copy.deepcopy(obs)], []  # arrays or dicts of them (goal-conditioned envs)
        for t in range(self.steps):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            self.info(info, f"step {t}")
            observations.append(copy.deepcopy(obs))
            outcomes.append((float(reward), bool(terminated), bool(truncated), info[contract.MODE]))
            if terminated or truncated:
                obs, info = env.reset()
                self.info(info, f"reset after step {t}")
                observations.append(copy.deepcopy(obs))
        return observations, outcomes

    def determinism(self) -> None:
        obs_a, out_a = self.rollout(self.seed)
        obs_b, out_b = self.rollout(self.seed)
        same = len(obs_a) == len(obs_b) and all(
            data_equivalence(a, b, exact=True) for a, b in zip(obs_a, obs_b, strict=True)
        )
        if not same or out_a != out_b:
            raise self.fail("determinism", f"two rollouts from seed {self.seed} differ")
        obs_c, _ = self.rollout(self.seed + 1)
        if len(obs_a) == len(obs_c) and all(
            data_equivalence(a, c, exact=True) for a, c in zip(obs_a, obs_c, strict=True)
        ):
            raise self.fail("determinism", f"rollouts from seeds {self.seed} and {self.seed + 1} are identical")

    # ------------------------------------------------------------------ perturb
    def state(self) -> np.ndarray:
        state = self.base.state
        if not isinstance(state, np.ndarray) or state.ndim != 1 or state.dtype.kind != "f":
            shape = getattr(state, "shape", None)
            raise self.fail(
                "state", f"got {type(state).__name__} of shape {shape} and dtype {getattr(state, 'dtype', None)}"
            )
        if not np.all(np.isfinite(state)):
            raise self.fail("state", f"got {state.tolist()}")
        return state

    def state_is_a_copy(self) -> None:
        state = self.state()
        before = state.copy()
        if state.flags.writeable:
            state += 1.0
        if not np.array_equal(self.state(), before):
            raise self.fail("state", "writing to the returned array changed the env's state (return a copy)")

    def perturb(self) -> None:
        base = self.base
        self.env.reset(seed=self.seed + 1)
        target = self.state()
        self.env.reset(seed=self.seed)
        info = base.perturb(to=target)
        self.info(info, "perturb(to=...)", perturbed=True)
        if not np.allclose(self.state(), target, atol=1e-6):
            raise self.fail("perturb", f"perturb(to={target.tolist()}) left the agent at {self.state().tolist()}")
        before = self.state()
        delta = np.full(before.shape, 1e-2)
        info = base.perturb(delta=delta)
        self.info(info, "perturb(delta=...)", perturbed=True)
        by_delta = self.state()
        base.perturb(to=before)
        base.perturb(to=before + delta)
        if not np.allclose(by_delta, self.state(), atol=1e-6):
            raise self.fail(
                "perturb",
                f"from {before.tolist()}, perturb(delta={delta.tolist()}) gave {by_delta.tolist()} but "
                f"perturb(to=state + delta) gave {self.state().tolist()}",
            )
        _, _, _, _, info = self.env.step(self.env.action_space.sample())
        self.info(info, "step after perturb")

    def perturb_arguments(self) -> None:
        base = self.base
        before = self.state()
        d = before.shape[0]
        bad: list[tuple[str, Callable[[], Any], type[Exception], str | None]] = [
            ("perturb()", lambda: base.perturb(), ValueError, None),
            ("perturb(delta=..., to=...)", lambda: base.perturb(np.zeros(d), to=before), ValueError, None),
            ("perturb(delta=[nan, ...])", lambda: base.perturb(delta=np.full(d, np.nan)), ValueError, "delta"),
            (f"perturb(delta=<{d + 1} numbers>)", lambda: base.perturb(delta=np.zeros(d + 1)), ValueError, "delta"),
            ("perturb(to='left')", lambda: base.perturb(to="left"), TypeError, "to"),
        ]
        for call, fn, expected, argument in bad:
            self.refused("perturb_arguments", call, fn, (expected,), argument, f"{call} raised no {expected.__name__}")
            if not np.array_equal(self.state(), before):
                raise self.fail("perturb_arguments", f"the rejected {call} moved the agent")

    def action_arguments(self) -> None:
        space = self.env.action_space
        if not isinstance(space, spaces.Box) or len(space.shape) != 1:
            return
        before = self.state()
        bad = np.zeros(space.shape[0] + 1, dtype=space.dtype)
        call, accepted = f"step(<{bad.size} numbers>)", f"step accepted an action of shape {bad.shape} for {space}"
        self.refused("action_arguments", call, lambda: self.env.step(bad), (ValueError,), "action", accepted)
        # words, not numbers: any clean refusal will do (envs may word it their way), silence will not
        words = np.array(["left"] * space.shape[0])
        call = f"step({words.tolist()!r})"
        accepted = f"{call} was accepted as an action for {space}"
        self.refused("action_arguments", call, lambda: self.env.step(words), (TypeError, ValueError), None, accepted)
        if not np.array_equal(self.state(), before):
            raise self.fail("action_arguments", "a rejected action moved the agent")


def check_steer_env(
    env: gym.Env[Any, Any],
    *,
    seed: int = 0,
    steps: int = 20,
    gymnasium_checks: bool = True,
    check_actions: bool = True,
) -> None:
    """Check that ``env`` follows every convention in :data:`CONVENTIONS`; raise on the first one broken.

    The env is reset, stepped with random actions and perturbed (it is left
    in some mid-episode state). ``step`` goes through ``env`` as given (its
    wrappers included), ``perturb`` and ``state`` through ``env.unwrapped``.

    Args:
        env: a (possibly wrapped) Gymnasium env, e.g. ``gymnasium.make("steer_envs/Cooking-v0")``.
        seed: seed of the checked rollouts, an int >= 0 (``seed + 1`` for the "another seed" rollout).
        steps: steps per rollout.
        gymnasium_checks: also run Gymnasium's own ``check_env`` on ``env.unwrapped``.
        check_actions: also check that a wrongly shaped Box action raises a ``ValueError``
            and a non-numeric (string) one a ``TypeError`` or ``ValueError``.

    Raises:
        SteerEnvCheckError: names the env, the convention and what was observed.
        TypeError: ``env`` is not a Gymnasium env, or ``seed`` is not an int.
        ValueError: ``steps`` is not a positive int.

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> check_steer_env(gym.make("steer_envs/SoupScoop-v0"), steps=5)
    """
    if not isinstance(env, gym.Env):
        raise TypeError(f"check_steer_env: `env` must be a gymnasium.Env, got {type(env).__name__}")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"check_steer_env: `steps` must be a positive int, got {steps!r}")
    seed = integer(seed, "seed", low=0, owner="check_steer_env")
    checker = _Checker(env, seed, steps)
    checker.guarded("interaction_kinds", checker.interaction_kinds)
    if gymnasium_checks:
        checker.gymnasium_api()
    checker.determinism()
    checker.guarded("state", checker.state_is_a_copy)
    checker.guarded("perturb", checker.perturb)
    checker.guarded("perturb_arguments", checker.perturb_arguments)
    if check_actions:
        checker.guarded("action_arguments", checker.action_arguments)
