"""Demonstrations from the scripted experts.

A :class:`Demonstration` is one expert episode: states, actions and the mode
sensors at every state. TLI fits mode policies from 1-3 of them, GLiDE uses
fewer than 10. A collector tries episodes until it has enough
(:func:`first_demos`).

>>> first_demos(iter(["a", None, "b", "c"]), 2)
['a', 'b']
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import gymnasium as gym
import numpy as np

from steer_envs.core.env import task_of
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import BoundExceeded, boolean, describe, integer
from steer_envs.data.experts import make_expert

#: steps an expert episode may take before success when neither ``max_steps`` nor the env sets a limit.
DEFAULT_MAX_STEPS = 10_000

D = TypeVar("D")


@dataclass(frozen=True)
class Demonstration:
    """One expert episode of ``T`` states and ``T - 1`` actions (see :func:`collect_demonstrations`)."""

    env_id: str
    seed: int
    states: np.ndarray  # (T, d)
    actions: np.ndarray  # (T - 1, a)
    modes: np.ndarray  # (T,) int
    sensors: np.ndarray  # (T, num_aps) bool, columns in task.sensors order
    success: bool

    def __len__(self) -> int:
        return len(self.states)


def rollout_expert(
    env: gym.Env,
    seed: int,
    max_steps: int | None = None,
    *,
    steps_after_success: int = 0,
    expert_kwargs: Mapping[str, Any] | None = None,
    start: Any = None,
) -> Demonstration:
    """Run the scripted expert of ``env`` for one episode from ``reset(seed=seed)``.

    ``start``: None, or a start state passed as ``reset(options={"state": start})``
    (the env checks it).

    By default the demo ends at the first successful state (where the envs end
    the episode). ``steps_after_success > 0`` (opt-in) keeps following the
    expert for at most that many steps after it, stopping early when the expert
    stands still or the episode is truncated: with an expert that walks on
    into the goal region (e.g. ``expert_kwargs={"final_target": "centroid"}``
    for PolygonNav) the demo then shows the goal's interior, which GLiDE's
    classifier cannot otherwise see. ``success`` still reports whether the goal
    was reached; ``max_steps`` bounds the steps before success (default: the
    env's step limit, else :data:`DEFAULT_MAX_STEPS`): an expert that has not
    reached the goal by then gives a demo with ``success=False`` (the
    documented "timed out" result).

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> demo = rollout_expert(gym.make("steer_envs/ConvexMode-v0"), seed=0)
    >>> demo.success, demo.states.shape[1], len(demo.actions) == len(demo) - 1
    (True, 2, True)
    """
    seed = integer(seed, "seed", low=0, owner="rollout_expert")
    steps_after_success = integer(steps_after_success, "steps_after_success", low=0, owner="rollout_expert")
    if max_steps is not None:
        max_steps = integer(max_steps, "max_steps", low=1, owner="rollout_expert")
    if expert_kwargs is not None and not isinstance(expert_kwargs, Mapping):
        raise TypeError(f"rollout_expert: expert_kwargs must be a mapping or None, got {describe(expert_kwargs)}")
    expert = make_expert(env, **dict(expert_kwargs or {}))
    task = task_of(env, who="rollout_expert")
    obs, info = env.reset(seed=int(seed), options=None if start is None else {"state": start})
    expert.reset(obs, info)
    states, actions, modes, sensors = [np.asarray(obs, dtype=np.float64)], [], [info["mode"]], [_sensor_row(task, info)]
    limit = max_steps if max_steps is not None else _step_limit(env)
    success = bool(info["success"])
    steps, extra = 0, int(steps_after_success)  # steps before success, steps left after it
    while (not success and steps < limit) or (success and extra > 0):
        action = np.asarray(expert.act(obs, info))
        if success and not np.any(action):  # the expert stands still in the goal: nothing more to show
            break
        obs, _, terminated, truncated, info = env.step(action)
        states.append(np.asarray(obs, dtype=np.float64))
        actions.append(action.astype(np.float64))
        modes.append(info["mode"])
        sensors.append(_sensor_row(task, info))
        if success:
            extra -= 1
        else:
            steps += 1
            success = bool(info["success"])
        if truncated or (terminated and not success):
            break
    return _demonstration(env, int(seed), task, states, actions, modes, sensors, success)


def _step_limit(env: gym.Env) -> int:
    """The env's step limit, else :data:`DEFAULT_MAX_STEPS`."""
    return (env.spec.max_episode_steps if env.spec else None) or DEFAULT_MAX_STEPS


def _demonstration(
    env: gym.Env,
    seed: int,
    task: TaskSpec,
    states: list[np.ndarray],
    actions: list[np.ndarray],
    modes: list[int],
    sensors: list[list[bool]],
    success: bool,
) -> Demonstration:
    """The :class:`Demonstration` of a rollout's rows (no actions: it began in the goal)."""
    return Demonstration(
        env_id=env.spec.id if env.spec else type(env.unwrapped).__name__,
        seed=seed,
        states=np.asarray(states),
        actions=np.asarray(actions, dtype=np.float64).reshape(len(actions), -1)
        if actions
        else np.zeros((0, int(np.prod(env.action_space.shape or (0,)))), dtype=np.float64),  # began in the goal
        modes=np.asarray(modes, dtype=np.int64),
        sensors=np.asarray(sensors, dtype=bool).reshape(len(states), len(task.sensors)),
        success=success,
    )


def collect_demonstrations(
    env_id: str,
    n: int,
    seed: int = 0,
    *,
    only_successful: bool = True,
    steps_after_success: int = 0,
    expert_kwargs: Mapping[str, Any] | None = None,
    demo_starts: str = "uniform",
    **make_kwargs: Any,
) -> list[Demonstration]:
    """``n`` expert demonstrations of ``env_id`` from seeds ``seed, seed + 1, ...``.

    With ``only_successful`` (default), failed episodes are skipped and more
    seeds are tried (at most ``10 * n``) until ``n`` successes are found;
    :class:`~steer_envs.core.validation.BoundExceeded` (a ``RuntimeError``)
    when fewer succeed.
    ``steps_after_success`` and ``expert_kwargs`` go to :func:`rollout_expert`
    (defaults: demos end on success, the expert's default settings);
    ``make_kwargs`` to ``gymnasium.make``. ``demo_starts``: ``"uniform"`` (the
    env's reset) or, on PolygonNav, ``"spread"``: attempt ``a`` starts at
    :func:`~steer_envs.data.demo_starts.spread_start` ``a`` of ``n`` on a ring
    whose phase is drawn from ``seed`` (:mod:`steer_envs.data.demo_starts`).

    >>> import steer_envs
    >>> demos = collect_demonstrations("steer_envs/PolygonNav-3Mode-v0", n=2, seed=0, layout_seed=0)
    >>> [d.success for d in demos], demos[0].modes[0], demos[0].modes[-1]
    ([True, True], 0, 2)
    """
    n = integer(n, "n", low=1, owner="collect_demonstrations")
    seed = integer(seed, "seed", low=0, owner="collect_demonstrations")
    only_successful = boolean(only_successful, "only_successful", owner="collect_demonstrations")
    if not isinstance(env_id, str):
        raise TypeError(f"collect_demonstrations: env_id must be a str, got {describe(env_id)}")
    starts = _starts(demo_starts, seed, n)
    env = gym.make(env_id, **make_kwargs)
    try:
        episodes = (
            rollout_expert(
                env,
                s,
                steps_after_success=steps_after_success,
                expert_kwargs=expert_kwargs,
                start=None if starts is None else starts(env, s - seed),
            )
            for s in range(int(seed), int(seed) + 10 * int(n))
        )
        demos = first_demos((d if d.success or not only_successful else None for d in episodes), n)
    finally:
        env.close()
    if len(demos) == n:
        return demos
    raise BoundExceeded(
        f"collect_demonstrations: the expert of {env_id} succeeded only {len(demos)} times in {10 * n} episodes "
        f"(the bound: 10 * n episodes of at most max_steps={_episode_limit(env)} steps each)"
    )


def _starts(demo_starts: Any, seed: int, n: int) -> Callable[[gym.Env, int], np.ndarray] | None:
    """The start state of attempt ``a`` on an env for ``demo_starts``; None for the env's own reset."""
    from steer_envs.data.demo_starts import check_demo_starts, spread_phase, spread_start
    from steer_envs.envs.polygon_nav import PolygonNavEnv

    if check_demo_starts(demo_starts, "collect_demonstrations") == "uniform":
        return None
    phase = spread_phase(seed)

    def start(env: gym.Env, attempt: int) -> np.ndarray:
        if not isinstance(env.unwrapped, PolygonNavEnv):
            name = env.spec.id if env.spec else type(env.unwrapped).__name__
            raise ValueError(f"collect_demonstrations: demo_starts='spread' needs a PolygonNav env, got {name}")
        return spread_start(env, attempt, n, phase=phase)

    return start


def first_demos(attempts: Iterable[D | None], n: int) -> list[D]:
    """The first ``n`` demonstrations ``attempts`` yields (None: an attempt that failed), fewer if it runs out.

    No attempt is drawn after the ``n``-th success, so a seeded stream of
    attempts is used up to there and no further.
    """
    demos: list[D] = []
    for demo in attempts:
        if demo is not None:
            demos.append(demo)
            if len(demos) == n:
                break
    return demos


def _episode_limit(env: gym.Env) -> int:
    return (env.spec.max_episode_steps if env.spec else None) or DEFAULT_MAX_STEPS


def _sensor_row(task: TaskSpec, info: dict[str, Any]) -> list[bool]:
    return [bool(info["sensors"][ap]) for ap in task.sensors]
