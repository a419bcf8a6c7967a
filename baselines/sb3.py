"""Train stable-baselines3 agents on steer-envs ids, evaluating along the way, checkpointing and resuming.

:func:`train_and_evaluate` trains one of :data:`METHODS`, each with every SB3
default: ``"sac"`` (``SAC("MlpPolicy", env)``) and ``"ppo"``
(``PPO("MlpPolicy", env)``) on the dense ``...Dense-v0`` ids, ``"sac-her"``
(SAC with SB3's ``HerReplayBuffer``) on the goal-conditioned ids. The env is
the id as registered (the dense ids carry their RL options, see
:mod:`steer_envs.envs.registry`); an option of :class:`Sb3Options` set to
True / False is passed on top, ``None`` keeps the id's.

Seeds: the run's ``seed`` (in ``[0, EVAL_SEED_OFFSET)``) seeds the agent
(SB3's ``seed=``), which seeds the training env's first reset with it; its
later episodes continue that env's generator. Evaluation at step 0 and after
every ``eval_every`` training steps: ``eval_episodes`` deterministic episodes,
episode ``i`` from ``reset(seed=EVAL_SEED_OFFSET + i)`` whatever the run's
seed, so every seed and method is evaluated from the same starts and no
training env is ever reset with an evaluation seed; up to
:data:`MAX_EVAL_ENVS` episodes step side by side, success =
``info["is_success"]`` at each episode's end.

Steps: SAC learns exactly ``eval_every`` steps between evaluations. PPO
learns in whole rollouts (SB3's 2048 steps), so it evaluates after the
rollout that crosses each multiple of ``eval_every`` and ends less than one
rollout past the budget (:attr:`Sb3Run.step_unit`).

Checkpoints: with ``checkpoint`` on, the run's folder
``<cache>/<env>-<method>-seed<seed>-<recipe hash>/checkpoint`` is rewritten
atomically (:func:`steer_envs.io.atomic_directory`) after every evaluation
with the SB3 model (``model.zip``), for SAC its replay buffer
(``replay_buffer.pkl``, SB3's pickle: a private cache, not a shipped file)
and ``state.json`` (steps, curve, times, and the sha256 of the other files,
checked before SB3 reads them: a damaged file is a
:class:`~steer_envs.io.CheckpointError` naming it, never unpickled). A run
whose folder holds a checkpoint continues from it, so a killed run loses at
most one evaluation interval. The recipe hash covers what changes the
training or the curve (env, method, seed, the env's registered and passed
options, evaluation settings and seeds), not the budget: a longer
``timesteps`` continues a shorter finished run. A resumed run is
reproducible (its random generators are re-seeded from the seed and the
step, the training env's from ``(seed + step) % EVAL_SEED_OFFSET``), but
differs from an unbroken run of the same seed.

``sac-her``: SB3's ``HerReplayBuffer`` cannot sample before the first
episode ends, so ``learning_starts`` is the env's episode limit (300 on
Maze2D-Umaze) instead of SB3's 100; everything else is SB3's default.

Needs the ``rl`` extra (``pip install "steer-envs[rl]"``).

>>> method_fits("steer_envs/SoupScoopDense-v0", "ppo"), method_fits("steer_envs/SoupScoopDense-v0", "sac-her")
(True, False)
>>> env_options("steer_envs/PolygonNav-3ModeDense-v0", Sb3Settings(timesteps=1000))  # the id as registered
{}
>>> env_options("steer_envs/PolygonNav-3ModeDense-v0", Sb3Settings(timesteps=1000, observe_sensors=False))
{'observe_sensors': False}
>>> train_env_id("steer_envs/Maze2D-UmazeDense-v0", "sac", Sb3Settings(timesteps=1000, maze_goal_obs=True))
'steer_envs/Maze2D-UmazeGoalDense-v0'
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from steer_envs.core.extras import require
from steer_envs.core.validation import boolean, describe, integer, real_scalar
from steer_envs.envs.registry import entry
from steer_envs.io import CheckpointError, atomic_directory, default_cache_dir, file_sha256
from steer_envs.utils.threads import limit_threads

__all__ = [
    "GOAL_ENVS",
    "METHODS",
    "OFF_POLICY",
    "Sb3Options",
    "Sb3Run",
    "Sb3Settings",
    "env_options",
    "evaluate_success",
    "make_env",
    "method_fits",
    "run_folder",
    "step_unit",
    "train_and_evaluate",
    "train_env_id",
]

#: the recipes, each with SB3's defaults: SAC and PPO on the dense ids, SAC + HER on the goal ids
METHODS: tuple[str, ...] = ("sac", "ppo", "sac-her")
#: the methods with a replay buffer (checkpointed beside the model)
OFF_POLICY: tuple[str, ...] = ("sac", "sac-her")
#: the methods with an ``MlpPolicy``: a Dict observation is flattened to a Box for them
_FLAT_METHODS: tuple[str, ...] = ("sac", "ppo")
#: the goal-conditioned ids ``sac-her`` trains on
GOAL_ENVS: tuple[str, ...] = ("steer_envs/Maze2D-UmazeGoal-v0",)
#: at most this many env copies step side by side in an evaluation
MAX_EVAL_ENVS = 10
#: evaluation episode ``i`` starts from ``reset(seed=EVAL_SEED_OFFSET + i)``; training seeds stay below it
EVAL_SEED_OFFSET = 1_000_000
CHECKPOINT = "checkpoint"
#: the files of a checkpoint whose sha256 its ``state.json`` records (PPO's has no replay buffer)
_CHECKED_FILES = ("model.zip", "replay_buffer.pkl")
#: what needs the ``rl`` extra here, as the missing-extra message names it.
RL_FEATURE = "training stable-baselines3 agents (SAC, PPO, SAC + HER)"


def _default_cache() -> Path:
    """``default_cache_dir("sb3")``: ``$XDG_CACHE_HOME/steer-envs/sb3`` (``~/.cache`` when unset)."""
    return default_cache_dir("sb3")


@dataclass(frozen=True)
class Sb3Options:
    """How a run evaluates, builds its env and checkpoints: what :class:`Sb3Settings` and the ``sb3`` suite share.

    ``eval_episodes`` deterministic episodes per evaluation, every
    ``eval_every`` steps (and at step 0). The env options, passed on top of
    the id's registered ones: ``normalize_actions`` (``[-1, 1]`` actions) and
    ``observe_sensors`` (the task's sensor bits in the observation; ignored on
    Maze2D), ``None`` (default) for the id's own (the dense ids register both
    on, see :mod:`steer_envs.envs.registry`); ``maze_goal_obs`` (``sac`` /
    ``ppo`` on a plain Maze2D ``...Dense-v0`` id train on its
    ``...GoalDense-v0`` sibling, flattened, as the first recorded results
    did; off by default: the id as registered), ``maze_relative_actions``,
    ``max_episode_steps`` (0: the id's limit). ``threads``: torch / BLAS
    threads; ``checkpoint``: save and resume; ``stop_success``: end training
    once an evaluation reaches this success (%; 0 = never).
    """

    eval_episodes: int = 20
    eval_every: int = 10_000
    normalize_actions: bool | None = None
    observe_sensors: bool | None = None
    maze_goal_obs: bool = False
    maze_relative_actions: bool = False
    max_episode_steps: int = 0
    threads: int = 1
    checkpoint: bool = True
    stop_success: float = 0.0


@dataclass(frozen=True)
class Sb3Settings(Sb3Options):
    """How a run trains: ``timesteps`` training steps (keyword only), its options, checkpoints under ``cache``.

    >>> Sb3Settings(timesteps=0)
    Traceback (most recent call last):
    ValueError: Sb3Settings.timesteps must be an int in [1, inf], got 0
    """

    timesteps: int = field(kw_only=True)
    cache: Path = field(default_factory=_default_cache)

    def __post_init__(self) -> None:
        name = type(self).__name__
        integer(self.timesteps, f"{name}.timesteps", low=1)
        integer(self.eval_episodes, f"{name}.eval_episodes", low=1)
        integer(self.eval_every, f"{name}.eval_every", low=1)
        integer(self.max_episode_steps, f"{name}.max_episode_steps", low=0)
        integer(self.threads, f"{name}.threads", low=1)
        for flag in ("maze_goal_obs", "maze_relative_actions", "checkpoint"):
            boolean(getattr(self, flag), f"{name}.{flag}")
        for flag in ("normalize_actions", "observe_sensors"):
            value = getattr(self, flag)
            if value is not None and not isinstance(value, bool):
                expected = "None (the id's registered value) or a bool"
                raise TypeError(f"{name}.{flag} must be {expected}, got {describe(value)}")
        real_scalar(self.stop_success, f"{name}.stop_success", low=0.0, high=100.0)
        object.__setattr__(self, "cache", Path(self.cache))


@dataclass(frozen=True)
class Sb3Run:
    """What a run measured: ``curve`` ``[[step, success %], ...]`` and its bookkeeping.

    ``step_unit``: the agent trains in units of this many steps (1 for SAC; PPO's rollout, 2048), so a run of
    budget ``T`` ends at a step in ``[T, T + step_unit)``.

    >>> run = Sb3Run([[0, 0.0], [2048, 50.0], [4096, 90.0]], 4096, 1.0, 1.0, "x", 0, 0, False, "2", step_unit=2048)
    >>> run.steps_to(80.0), run.steps_to(80.0, within=4000), run.steps_to(80.0, within=2000)
    (4096, 4096, None)
    """

    curve: list[list[float]]
    timesteps: int
    train_s: float
    wall_s: float
    train_env: str
    learning_starts: int
    resumed_from: int
    stopped_early: bool
    stable_baselines3: str
    step_unit: int = 1

    @property
    def successes(self) -> list[float]:
        """The success rate (%) of every evaluation, in order."""
        return [s for _, s in self.curve]

    def steps_to(self, target: float, within: int | None = None) -> int | None:
        """The first evaluated step whose success reached ``target`` (%), ``None`` if none did.

        ``within``: only the evaluations a run of that budget makes (steps below ``within + step_unit``).
        """
        limit = None if within is None else within + self.step_unit
        return next((int(n) for n, s in self.curve if s >= target and (limit is None or n < limit)), None)


def method_fits(env: str | None, method: str | None) -> bool:
    """Whether ``method`` runs on ``env``: ``sac`` and ``ppo`` on the dense ids, ``sac-her`` on :data:`GOAL_ENVS`."""
    if env is None or method is None:
        return False
    return env in GOAL_ENVS if method == "sac-her" else method in _FLAT_METHODS and env.endswith("Dense-v0")


def _is_maze(env_id: str) -> bool:
    return "/Maze2D-" in env_id


def train_env_id(env_id: str, method: str, settings: Sb3Settings) -> str:
    """The id a run trains on: ``env_id``, or its ``...GoalDense-v0`` sibling for ``sac`` / ``ppo`` on a plain
    Maze2D dense id with ``maze_goal_obs``."""
    if method in _FLAT_METHODS and _is_maze(env_id) and settings.maze_goal_obs and not env_id.endswith("GoalDense-v0"):
        return env_id.removesuffix("Dense-v0") + "GoalDense-v0"
    return env_id


def env_options(env_id: str, settings: Sb3Settings) -> dict[str, Any]:
    """The options a run passes to ``gym.make`` on top of the id's registered ones (none by default)."""
    options: dict[str, Any] = {}
    if settings.normalize_actions is not None:
        options["normalize_actions"] = settings.normalize_actions
    if not _is_maze(env_id):
        if settings.observe_sensors is not None:
            options["observe_sensors"] = settings.observe_sensors
    elif settings.maze_relative_actions:
        options["relative_actions"] = True
    if settings.max_episode_steps:  # a gym.make argument; only when set, so the default recipes keep their folders
        options["max_episode_steps"] = settings.max_episode_steps
    return options


def make_env(env_id: str, method: str, settings: Sb3Settings) -> Any:
    """The ``Monitor``-wrapped env of a run: a Dict observation (a goal id) is flattened to a Box for ``sac`` /
    ``ppo`` (``MlpPolicy``)."""
    require("stable_baselines3", "rl", RL_FEATURE)
    import gymnasium as gym
    from gymnasium.wrappers import FlattenObservation
    from stable_baselines3.common.monitor import Monitor

    import steer_envs  # noqa: F401  (registers the ids)

    env: Any = gym.make(train_env_id(env_id, method, settings), **env_options(env_id, settings))
    if method in _FLAT_METHODS and isinstance(env.observation_space, gym.spaces.Dict):
        env = FlattenObservation(env)
    return Monitor(env)


def run_folder(env_id: str, method: str, seed: int, settings: Sb3Settings) -> Path:
    """The run's checkpoint folder under ``settings.cache`` (one per recipe, see the module docstring)."""
    train_id = train_env_id(env_id, method, settings)
    recipe = {
        "env": env_id,
        "method": method,
        "seed": seed,
        "train_env": train_id,
        "env_kwargs": {**entry(train_id).kwargs, **env_options(env_id, settings)},
        "eval_episodes": settings.eval_episodes,
        "eval_every": settings.eval_every,
        "eval_seed_offset": EVAL_SEED_OFFSET,  # episode i from reset(seed=offset + i), whatever the run's seed
    }
    digest = hashlib.sha256(json.dumps(recipe, sort_keys=True).encode()).hexdigest()[:10]
    return settings.cache / f"{env_id.split('/')[-1]}-{method}-seed{seed}-{digest}"


def evaluate_success(model: Any, envs: Sequence[Any], episodes: int, first_seed: int = EVAL_SEED_OFFSET) -> float:
    """Success rate (%) of ``model`` acting deterministically over ``episodes`` episodes, episode ``i`` from
    ``reset(seed=first_seed + i)``, up to ``len(envs)`` side by side; success = ``info["is_success"]`` at its end."""
    episodes = integer(episodes, "episodes", low=1, owner="evaluate_success")
    if not envs:
        raise ValueError("evaluate_success: envs must hold at least one env")
    for env in envs:  # an episode without a step limit could run forever
        if env.spec is None or env.spec.max_episode_steps is None:
            raise ValueError(f"evaluate_success: every env needs a step limit (gymnasium.make's), got {env}")
    outcomes: list[bool] = []
    for first in range(0, episodes, len(envs)):
        batch = list(envs[: min(len(envs), episodes - first)])
        obs = [env.reset(seed=first_seed + first + k)[0] for k, env in enumerate(batch)]
        success: list[bool | None] = [None] * len(batch)
        while any(s is None for s in success):
            live = [k for k, s in enumerate(success) if s is None]
            actions, _ = model.predict(_stacked([obs[k] for k in live]), deterministic=True)
            for k, action in zip(live, actions, strict=True):
                obs[k], _, terminated, truncated, info = batch[k].step(action)
                if terminated or truncated:
                    success[k] = bool(info.get("is_success", False))
        outcomes += [bool(s) for s in success]
    return 100.0 * sum(outcomes) / episodes


def _stacked(observations: list[Any]) -> Any:
    """A batch of observations as ``model.predict`` takes it: an array, or a dict of arrays for Dict observations."""
    import numpy as np

    if isinstance(observations[0], dict):
        return {key: np.stack([o[key] for o in observations]) for key in observations[0]}
    return np.stack(observations)


def step_unit(model: Any) -> int:
    """The steps a model trains in: its rollout (``n_steps`` x envs) for an on-policy algorithm (PPO), else 1."""
    from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

    return int(model.n_steps) * int(model.n_envs) if isinstance(model, OnPolicyAlgorithm) else 1


def _train_reset_seed(seed: int, steps: int) -> int:
    """The training env's reset seed after resuming at ``steps``: below :data:`EVAL_SEED_OFFSET`, like ``seed``."""
    return (seed + steps) % EVAL_SEED_OFFSET


def _algorithm(method: str) -> Any:
    from stable_baselines3 import PPO, SAC

    return PPO if method == "ppo" else SAC


def _new_model(env: Any, method: str, seed: int) -> Any:
    from stable_baselines3 import PPO, SAC, HerReplayBuffer

    if method == "sac":
        return SAC("MlpPolicy", env, seed=seed, device="cpu", verbose=0)
    if method == "ppo":
        return PPO("MlpPolicy", env, seed=seed, device="cpu", verbose=0)
    limit = env.spec.max_episode_steps if env.spec is not None else None
    return SAC(
        "MultiInputPolicy",
        env,
        replay_buffer_class=HerReplayBuffer,
        learning_starts=max(100, int(limit or 0)),
        seed=seed,
        device="cpu",
        verbose=0,
    )


def _load_checkpoint(folder: Path, env: Any, method: str, seed: int, total: int) -> tuple[Any, dict[str, Any]] | None:
    """The model (with its replay buffer, off-policy) and state saved in ``folder``; ``None`` without a usable one.

    ``CheckpointError`` naming the file for a ``state.json`` that is not a JSON
    object and for a model or replay buffer whose bytes differ from the
    sha256 the state records (checkpoints written before it was kept are not checked).
    """
    path = folder / CHECKPOINT
    state = _read_state(path / "state.json")
    if state is None:
        return None
    steps = int(state["timesteps"])
    model = _algorithm(method).load(path / "model.zip", env=env, device="cpu")
    if steps >= total + step_unit(model):  # trained past this budget: start over rather than report a longer run
        return None
    if method in OFF_POLICY:
        model.load_replay_buffer(path / "replay_buffer.pkl")
    model.set_random_seed(seed + steps)
    model.get_env().seed(_train_reset_seed(seed, steps))  # never an evaluation seed
    return model, state


def _read_state(src: Path) -> dict[str, Any] | None:
    """A checkpoint's ``state.json`` (``None``: none yet), its files checked against the sha256 it records."""
    if not src.is_file():
        return None
    try:
        state = json.loads(src.read_text(encoding="utf-8"))
        if not isinstance(state, dict):
            raise ValueError(f"a JSON object was expected, got {type(state).__name__}")
        int(state["timesteps"])
        digests = state.get("sha256", {})  # absent in checkpoints written before it was kept
        if not (isinstance(digests, dict) and set(digests) <= set(_CHECKED_FILES)):
            raise ValueError(f"'sha256' must map {list(_CHECKED_FILES)} to checksums, got {digests!r}")
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as err:
        raise CheckpointError(
            f"{src}: not a checkpoint state ({type(err).__name__}: {err}); delete "
            f"{src.parent} to train this run again from the start"
        ) from None
    for name, digest in digests.items():
        if not (src.parent / name).is_file() or file_sha256(src.parent / name) != digest:
            raise CheckpointError(
                f"{src.parent / name}: damaged or missing: its bytes do not match the sha256 in {src.name}, so it "
                f"changed after it was written; delete {src.parent} to train this run again from the start"
            )
    return state


def _save_checkpoint(folder: Path, model: Any, state: dict[str, Any]) -> None:
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

    with atomic_directory(folder / CHECKPOINT, overwrite=True) as tmp:
        model.save(tmp / "model.zip")
        if isinstance(model, OffPolicyAlgorithm):
            model.save_replay_buffer(tmp / "replay_buffer.pkl")
        digests = {name: file_sha256(tmp / name) for name in _CHECKED_FILES if (tmp / name).is_file()}
        (tmp / "state.json").write_text(json.dumps({**state, "sha256": digests}))


def _start(env: Any, method: str, seed: int, settings: Sb3Settings, folder: Path) -> tuple[Any, dict[str, Any]]:
    """The checkpointed model and state when there is one (and ``checkpoint`` is on), else a fresh model."""
    loaded = _load_checkpoint(folder, env, method, seed, settings.timesteps) if settings.checkpoint else None
    if loaded is not None:
        return loaded
    return _new_model(env, method, seed), {"timesteps": 0, "curve": [], "train_s": 0.0, "wall_s": 0.0}


def _learn(
    model: Any,
    settings: Sb3Settings,
    folder: Path,
    evaluate: Callable[[int], float],
    curve: list[list[float]],
    train_s: float,
    wall: tuple[float, float],
) -> tuple[int, float, bool]:
    """Learn in chunks of ``settings.eval_every`` steps, evaluating (and checkpointing) after each, until
    ``settings.timesteps`` or ``settings.stop_success``: the steps, the training seconds and whether it stopped early.

    ``curve``: the evaluations so far (``evaluate`` appends); ``wall``: the wall seconds of the runs
    before this one and this one's ``time.perf_counter()`` at its start (a checkpoint records the sum).
    """
    steps = int(model.num_timesteps)
    stopped = settings.stop_success > 0 and curve[-1][1] >= settings.stop_success
    while steps < settings.timesteps and not stopped:
        chunk = min(settings.eval_every - steps % settings.eval_every, settings.timesteps - steps)
        t0 = time.perf_counter()
        model.learn(total_timesteps=chunk, reset_num_timesteps=False, progress_bar=False)
        train_s += time.perf_counter() - t0
        steps = int(model.num_timesteps)
        success = evaluate(steps)
        stopped = settings.stop_success > 0 and success >= settings.stop_success
        if settings.checkpoint:
            wall_s = wall[0] + time.perf_counter() - wall[1]
            _save_checkpoint(folder, model, {"timesteps": steps, "curve": curve, "train_s": train_s, "wall_s": wall_s})
    return steps, train_s, stopped


def train_and_evaluate(
    env_id: str,
    method: str,
    seed: int,
    settings: Sb3Settings,
    *,
    on_eval: Callable[[int, float], None] | None = None,
) -> Sb3Run:
    """Train ``method`` on ``env_id`` for ``settings.timesteps`` steps (resuming a checkpoint), evaluating.

    ``seed`` seeds the agent and the training env (an int in ``[0, EVAL_SEED_OFFSET)``, see the module
    docstring). ``on_eval(step, success)`` is called after every evaluation (progress
    reports). Raises ``ValueError`` when the method does not fit the env, an ``ImportError`` naming
    ``pip install "steer-envs[rl]"`` without stable-baselines3.
    """
    if not isinstance(settings, Sb3Settings):
        raise TypeError(f"settings must be Sb3Settings, got {type(settings).__name__}")
    seed = integer(seed, "seed", low=0, high=EVAL_SEED_OFFSET - 1, owner="train_and_evaluate")
    if not method_fits(env_id, method):
        raise ValueError(
            f"method {method!r} does not run on env {env_id!r} (sac, ppo: ...Dense-v0 ids; sac-her: {list(GOAL_ENVS)})"
        )
    sb3 = require("stable_baselines3", "rl", RL_FEATURE)

    folder = run_folder(env_id, method, seed, settings)
    start = time.perf_counter()
    with limit_threads(blas_threads=settings.threads, torch_threads=settings.threads):
        env = make_env(env_id, method, settings)
        eval_envs = [make_env(env_id, method, settings) for _ in range(min(settings.eval_episodes, MAX_EVAL_ENVS))]
        model, state = _start(env, method, seed, settings, folder)
        resumed_from = int(state["timesteps"])
        curve: list[list[float]] = [list(p) for p in state["curve"]]
        train_s, wall_before = float(state["train_s"]), float(state["wall_s"])

        def evaluate(step: int) -> float:
            success = evaluate_success(model, eval_envs, settings.eval_episodes)
            curve.append([step, success])
            if on_eval is not None:
                on_eval(step, success)
            return success

        if not curve:
            evaluate(0)
        steps, train_s, stopped = _learn(model, settings, folder, evaluate, curve, train_s, (wall_before, start))
        env.close()
        for e in eval_envs:
            e.close()
    return Sb3Run(
        curve=curve,
        timesteps=steps,
        train_s=train_s,
        wall_s=wall_before + time.perf_counter() - start,
        train_env=train_env_id(env_id, method, settings),
        learning_starts=int(getattr(model, "learning_starts", 0)),
        resumed_from=resumed_from,
        stopped_early=bool(stopped and steps < settings.timesteps),
        stable_baselines3=sb3.__version__,
        step_unit=step_unit(model),
    )
