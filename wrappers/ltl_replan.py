"""LTLReplanWrapper: automaton tracking and mode replanning from sensor readings (TLI, thesis ch. 3).

Each step the wrapper reads ``info["sensors"]``, advances the task automaton
of a GR(1) spec (:class:`steer_envs.ltl.replanner.ModeReplanner`) and adds the
planned next mode to the observation, so any policy (a mode-conditioned BC
policy, one DS per mode as in LTL-DS, an SB3 agent) can act on it:

- observation: ``{"observation": <the env's observation>, "next_mode": int}``
  (``next_mode`` indexes ``wrapper.modes``, the spec's mode APs);
- ``info["plan"]``: the planned mode sequence (mode names) from the current mode;
- ``info["ltl_mode"]``, ``info["next_mode_name"]``: current and next mode names;
- ``info["ltl_unexpected"]``: the latest transition was not an automaton edge
  (a perturbation); the plan was recomputed from where the system is;
- ``info["ltl_unknown_reading"]``: the reading fits no mode of the spec (the
  automaton keeps its state and plan);
- ``info["ltl_stuck"]``: no mode sequence can meet the goals from here.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from steer_envs.core.env import HasTask, task_of
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import sensor_reading
from steer_envs.ltl.gr1 import GR1Spec
from steer_envs.ltl.replanner import ModeReplanner, UnknownSensorReading
from steer_envs.wrappers.constructor_args import record_constructor_args

__all__ = ["LTLReplanWrapper"]


class LTLReplanWrapper(gym.Wrapper[dict[str, Any], Any, Any, Any], gym.utils.RecordConstructorArgs):
    """Adds the LTL-planned next mode to the observation and the plan to ``info``.

    Args:
        env: an env whose ``info`` carries ``"sensors"`` (AP -> bool), as every
            steer-envs env does.
        spec: a :class:`GR1Spec`, the name of a variant attached to the env
            (``"phi_cc"`` for Cooking-v0, see :func:`steer_envs.ltl.specs.variants`),
            or ``None`` for the env's default spec.
        task: the :class:`TaskSpec` giving the sensor APs (default:
            ``env.unwrapped.task``; when the env has a task, both must name the same sensors).

    Unknown variant names, specs over APs the task does not define and a
    ``task`` whose sensors the env does not report are refused here. Every
    reading (``info["sensors"]`` of ``reset``, ``step`` and :meth:`sync`) must
    name exactly the task's sensor APs with real bools (see :func:`~steer_envs.core.validation.sensor_reading`).

    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import steer_envs
    >>> env = LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"))
    >>> obs, info = env.reset(seed=0)
    >>> info["plan"], env.modes[obs["next_mode"]]
    (['a', 'b', 'c', 'd'], 'b')
    >>> env.spec.additional_wrappers[0].kwargs
    {'spec': None, 'task': None}
    """

    def __init__(
        self, env: gym.Env[Any, Any], spec: GR1Spec | str | None = None, *, task: TaskSpec | None = None
    ) -> None:
        record_constructor_args(self, locals())
        gym.Wrapper.__init__(self, env)
        if task is None:
            task = task_of(env, who="LTLReplanWrapper (or pass `task=`)")
        elif not isinstance(task, TaskSpec):
            raise TypeError(f"LTLReplanWrapper: `task` must be a TaskSpec, got {type(task).__name__}")
        if spec is None or isinstance(spec, str):
            from steer_envs.ltl.specs import for_env

            spec = for_env(env, spec)
        elif not isinstance(spec, GR1Spec):
            raise TypeError(
                f"LTLReplanWrapper: `spec` must be a GR1Spec, a variant name or None, got {type(spec).__name__}"
            )
        own = env.unwrapped.task if isinstance(env.unwrapped, HasTask) else None
        if isinstance(own, TaskSpec) and own is not task and set(task.sensors) != set(own.sensors):
            raise ValueError(
                f"LTLReplanWrapper: `task` reads sensors {list(task.sensors)}, but the env reports "
                f"{list(own.sensors)}; the readings could never match"
            )
        self.ltl_spec = spec
        self.replanner = ModeReplanner(task, spec)
        self.modes: tuple[str, ...] = self.replanner.modes
        self.observation_space = spaces.Dict(
            {"observation": env.observation_space, "next_mode": spaces.Discrete(len(self.modes))}
        )
        self._plan: list[str] = []

    def _sensors(self, info: dict[str, Any]) -> dict[str, bool]:
        return sensor_reading(info, self.replanner.automaton.sensors, owner="LTLReplanWrapper")

    def _update(self, obs: Any, info: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
        """Feed ``info``'s reading to the replanner (an unknown one keeps the plan) and augment ``obs`` / ``info``."""
        unknown = False
        try:
            self.replanner.update(self._sensors(info))
        except UnknownSensorReading:
            unknown = True
        return self._augment(obs, info, unknown)

    def _augment(self, obs: Any, info: dict[str, Any], unknown: bool) -> tuple[dict[str, Any], dict[str, Any]]:
        rp = self.replanner
        if not unknown or not self._plan:
            self._plan = rp.plan()
        nxt = self._plan[1] if len(self._plan) > 1 else self._plan[0]
        info = dict(info)
        info["plan"] = list(self._plan)
        info["ltl_mode"] = rp.current_mode
        info["next_mode_name"] = nxt
        info["ltl_unexpected"] = rp.last_unexpected and not unknown
        info["ltl_unknown_reading"] = unknown
        info["ltl_stuck"] = rp.stuck
        return {"observation": obs, "next_mode": np.int64(self.modes.index(nxt))}, info

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self._plan = []
        self.replanner.reset(self._sensors(info))
        return self._augment(obs, info, unknown=False)

    def step(self, action: Any) -> tuple[dict[str, Any], SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        obs_out, info = self._update(obs, info)
        return obs_out, reward, terminated, truncated, info

    def sync(self, info: dict[str, Any]) -> dict[str, Any]:
        """Feed an out-of-band reading, e.g. the ``info`` that ``env.unwrapped.perturb(...)`` returns.

        ``step`` would catch the jump at the next step anyway; this updates the
        plan at once. Returns ``{"next_mode": int}`` plus the LTL keys of ``info``.
        """
        obs, out = self._update(None, info)
        keys = ("plan", "ltl_mode", "next_mode_name", "ltl_unexpected", "ltl_unknown_reading", "ltl_stuck")
        return {"next_mode": obs["next_mode"], **{k: out[k] for k in keys}}
