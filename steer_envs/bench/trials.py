"""What trial functions share, and the protocols of the robot-experiment suites (thesis ch. 3: TLI / LTL-DS).

A trial function refuses a trial its suite does not plan with
:func:`check_trial`. A robot-experiment suite's trial function runs its
protocol with :func:`run_protocol` (the trial's seed and method, the suite's
parameters, one thread); a protocol builds its env with :func:`trial_env`,
seeds each episode with :func:`reset_seed` and averages the episodes'
outcomes with :func:`episode_means`. The suites' parameters derive from
:class:`ProtocolParams` (pushes per episode, figure seeds), those that count
episodes and cap their steps from :class:`PushedEpisodesParams` (with pushes
after a random dwell: :class:`DwellPushesParams`).

>>> reset_seed(0, 1, 7) == reset_seed(0, 1, 7) != reset_seed(0, 2, 7)
True
>>> episode_means([{"success": True, "steps": 10}, {"success": False, "steps": 20}], ("success", "steps"))
{'success': 0.5, 'steps': 15.0}
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Trial
from steer_envs.utils.threads import single_threaded

__all__ = [
    "DwellPushesParams",
    "ProtocolParams",
    "PushedEpisodesParams",
    "check_trial",
    "episode_means",
    "reset_seed",
    "run_protocol",
    "trial_env",
]


@dataclass(frozen=True)
class ProtocolParams(SuiteParams):
    """What every robot-experiment protocol reads: ``n_pushes`` per episode; the first ``plot_seeds`` record figures."""

    n_pushes: int = 1
    plot_seeds: int = 1

    def __post_init__(self) -> None:
        self.require_at_least(0, "n_pushes", "plot_seeds")


@dataclass(frozen=True)
class PushedEpisodesParams(ProtocolParams):
    """:class:`ProtocolParams` of a protocol that runs ``n_episodes`` per condition of at most ``max_steps`` each.

    >>> PushedEpisodesParams(n_episodes=0)
    Traceback (most recent call last):
    ValueError: PushedEpisodesParams: parameter 'n_episodes' must be >= 1, got 0
    """

    n_episodes: int = 10
    max_steps: int = 3000

    def __post_init__(self) -> None:
        self.require_at_least(1, "n_episodes", "max_steps")
        super().__post_init__()


@dataclass(frozen=True)
class DwellPushesParams(PushedEpisodesParams):
    """:class:`PushedEpisodesParams` of a protocol that pushes after a random ``1..max_dwell`` steps in a mode."""

    max_dwell: int = 20

    def __post_init__(self) -> None:
        super().__post_init__()
        self.require_at_least(1, "max_dwell")


P = TypeVar("P", bound=ProtocolParams)


def check_trial(
    trial: Trial, *, envs: Sequence[str | None] = (), methods: Sequence[str | None] = (), method_word: str = "method"
) -> None:
    """``ValueError`` for a trial whose env is not in ``envs`` or method not in ``methods`` (empty: not checked).

    A trial function's guard against a trial its suite does not plan; ``method_word`` names the method axis
    in the message (e.g. ``"variant"``).

    >>> check_trial(Trial("demo", "a/B-v0", "x", 0, {}, "math:sqrt"), methods=("y", "z"))
    Traceback (most recent call last):
    ValueError: demo: unknown method 'x'; expected one of ('y', 'z')
    """
    for word, value, choices in (("env", trial.env, envs), (method_word, trial.method, methods)):
        if choices and value not in choices:
            expected = repr(choices[0]) if len(choices) == 1 else f"one of {tuple(choices)}"
            raise ValueError(f"{trial.suite}: unknown {word} {value!r}; expected {expected}")


def run_protocol(
    trial: Trial, params_type: type[P], protocol: Callable[..., dict[str, Any]], methods: Sequence[str]
) -> tuple[P, dict[str, Any]]:
    """``protocol(seed, method, params, record=...)`` for ``trial``, single-threaded; the params and its result.

    The trial's method must be one of ``methods``; the protocol reads its
    settings from the suite's parameters, and the first ``plot_seeds`` seeds
    record figure data.
    """
    check_trial(trial, methods=methods)
    params = params_type.from_json(trial.params)
    record = trial.seed < params.plot_seeds
    with single_threaded():
        result = protocol(trial.seed, str(trial.method), params, record=record)
    return params, result


@contextmanager
def trial_env(env_id: str, **kwargs: Any) -> Iterator[tuple[Any, Any]]:
    """``gymnasium.make(env_id, **kwargs)`` and its unwrapped env, closed on exit (ids registered in a fresh worker)."""
    import gymnasium as gym

    import steer_envs  # noqa: F401 - registers the ids

    env = gym.make(env_id, **kwargs)
    try:
        yield env, env.unwrapped
    finally:
        env.close()


def reset_seed(seed: int, episode: int, salt: int) -> int:
    """The reset seed of episode ``episode`` of experiment ``seed``; ``salt`` keeps the protocols' streams apart."""
    return int(np.random.SeedSequence([seed, episode, salt]).generate_state(1)[0] % 2**31)


def episode_means(episodes: Iterable[Mapping[str, Any]], keys: Iterable[str]) -> dict[str, float]:
    """The mean over ``episodes`` of each outcome in ``keys`` (as floats)."""
    episodes = list(episodes)
    return {k: float(np.mean([float(e[k]) for e in episodes])) for k in keys}
