"""One ``sb3`` trial: train SAC (or SAC + HER) with SB3's defaults, evaluate along the way, checkpoint, resume.

The trial evaluates at step 0 and after every ``eval_every`` training steps:
``eval_episodes`` deterministic episodes on a ``DummyVecEnv`` of up to 10
``Monitor``-wrapped copies of the env, seeded the same way at every
evaluation (so the curve compares the same starts), success =
``info["is_success"]`` at each episode's end.

Checkpoints: with ``checkpoint`` on, the trial's folder
``<cache_dir>/<env>-<method>-seed<seed>-<recipe hash>/checkpoint`` is
rewritten atomically (:func:`steer_envs.io.atomic_directory`) after every
evaluation with the SB3 model (``model.zip``), its replay buffer
(``replay_buffer.pkl``, SB3's pickle: a private cache, not a shipped file)
and ``state.json`` (steps, curve, times). A trial whose folder holds a
checkpoint continues from it, so a killed ``steer-bench run`` loses at most
one evaluation interval. The recipe hash covers what changes the training
or the curve (env, method, seed, the env's registered and passed options,
evaluation settings), not the budget: a longer ``timesteps`` continues a
shorter finished trial. A
resumed trial is reproducible (its random generators are re-seeded from
the seed and the step), but differs from an unbroken run of the same seed.

``sac-her``: SB3's ``HerReplayBuffer`` cannot sample before the first
episode ends, so ``learning_starts`` is the env's episode limit (300 on
Maze2D-Umaze) instead of SB3's 100; everything else is SB3's default.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from steer_envs.bench.suite import TrialResult
from steer_envs.bench.suites.sb3.suite import TARGET_SUCCESS, Sb3Params, method_fits
from steer_envs.envs.registry import entry
from steer_envs.io import atomic_directory
from steer_envs.utils.threads import limit_threads

__all__ = ["env_options", "evaluate_success", "make_env", "run_folder", "train_and_evaluate"]

#: at most this many env copies step side by side in an evaluation
MAX_EVAL_ENVS = 10
#: evaluation seeds start here (away from the training seeds)
EVAL_SEED_OFFSET = 1_000_000
CHECKPOINT = "checkpoint"


def _is_maze(env_id: str) -> bool:
    return "/Maze2D-" in env_id


def train_env_id(env_id: str, method: str, params: Sb3Params) -> str:
    """The id a trial trains on: the ``...GoalDense-v0`` sibling for ``sac`` on Maze2D with ``maze_goal_obs``.

    >>> train_env_id("steer_envs/Maze2D-UmazeDense-v0", "sac", Sb3Params())
    'steer_envs/Maze2D-UmazeGoalDense-v0'
    """
    if method == "sac" and _is_maze(env_id) and params.maze_goal_obs and not env_id.endswith("GoalDense-v0"):
        return env_id.removesuffix("Dense-v0") + "GoalDense-v0"
    return env_id


def env_options(env_id: str, params: Sb3Params) -> dict[str, Any]:
    """The options a trial passes to ``gym.make`` on top of the id's registered ones."""
    options: dict[str, Any] = {"normalize_actions": params.normalize_actions}
    if not _is_maze(env_id):
        options["observe_sensors"] = params.observe_sensors
    elif params.maze_relative_actions:
        options["relative_actions"] = True
    if params.max_episode_steps:  # a gym.make argument; only when set, so the default recipes keep their folders
        options["max_episode_steps"] = params.max_episode_steps
    return options


def make_env(env_id: str, method: str, params: Sb3Params) -> Any:
    """The ``Monitor``-wrapped env of a trial (flattened to a Box when ``sac`` trains on a goal id)."""
    import gymnasium as gym
    from gymnasium.wrappers import FlattenObservation
    from stable_baselines3.common.monitor import Monitor

    import steer_envs  # noqa: F401  (registers the ids)

    train_id = train_env_id(env_id, method, params)
    env: Any = gym.make(train_id, **env_options(env_id, params))
    if method == "sac" and train_id != env_id:
        env = FlattenObservation(env)
    return Monitor(env)


def run_folder(env_id: str, method: str, seed: int, params: Sb3Params) -> Path:
    """The trial's checkpoint folder under ``params.cache`` (one per recipe, see the module docstring)."""
    train_id = train_env_id(env_id, method, params)
    recipe = {
        "env": env_id,
        "method": method,
        "seed": seed,
        "train_env": train_id,
        "env_kwargs": {**entry(train_id).kwargs, **env_options(env_id, params)},
        "eval_episodes": params.eval_episodes,
        "eval_every": params.eval_every,
    }
    digest = hashlib.sha256(json.dumps(recipe, sort_keys=True).encode()).hexdigest()[:10]
    return params.cache / f"{env_id.split('/')[-1]}-{method}-seed{seed}-{digest}"


def evaluate_success(model: Any, vec_env: Any, episodes: int, seed: int) -> float:
    """Success rate (%) of ``model`` acting deterministically over ``episodes`` episodes of ``vec_env``."""
    from stable_baselines3.common.evaluation import evaluate_policy

    outcomes: list[bool] = []

    def record(local: dict[str, Any], _: dict[str, Any]) -> None:
        if local["done"] and "episode" in local["info"]:  # Monitor's true episode end
            outcomes.append(bool(local["info"].get("is_success", False)))

    vec_env.seed(seed)
    evaluate_policy(model, vec_env, n_eval_episodes=episodes, deterministic=True, callback=record, warn=False)
    if len(outcomes) != episodes:
        raise RuntimeError(f"evaluation finished {len(outcomes)} episodes, expected {episodes}")
    return 100.0 * sum(outcomes) / episodes


def _new_model(env: Any, method: str, seed: int) -> Any:
    from stable_baselines3 import SAC, HerReplayBuffer

    if method == "sac":
        return SAC("MlpPolicy", env, seed=seed, device="cpu", verbose=0)
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


def _load_checkpoint(folder: Path, env: Any, seed: int, total: int) -> tuple[Any, dict[str, Any]] | None:
    """The model (with its replay buffer) and state saved in ``folder``; ``None`` without a usable one."""
    from stable_baselines3 import SAC

    path = folder / CHECKPOINT
    if not (path / "state.json").is_file():
        return None
    state = json.loads((path / "state.json").read_text())
    if int(state["timesteps"]) > total:  # trained past this budget: start over rather than report a longer run
        return None
    model = SAC.load(path / "model.zip", env=env, device="cpu")
    model.load_replay_buffer(path / "replay_buffer.pkl")
    model.set_random_seed(seed + int(state["timesteps"]))
    return model, state


def _save_checkpoint(folder: Path, model: Any, state: dict[str, Any]) -> None:
    with atomic_directory(folder / CHECKPOINT, overwrite=True) as tmp:
        model.save(tmp / "model.zip")
        model.save_replay_buffer(tmp / "replay_buffer.pkl")
        (tmp / "state.json").write_text(json.dumps(state))


def train_and_evaluate(
    env_id: str, method: str, seed: int, params: Sb3Params, *, on_eval: Callable[[int, float], None] | None = None
) -> TrialResult:
    """Train ``method`` on ``env_id`` for ``params.budget(method)`` steps (resuming a checkpoint), evaluating.

    ``on_eval(step, success)`` is called after every evaluation (progress
    reports). Raises ``ValueError`` when the method does not fit the env.
    """
    import stable_baselines3
    from stable_baselines3.common.vec_env import DummyVecEnv

    if not isinstance(params, Sb3Params):
        raise TypeError(f"params must be Sb3Params, got {type(params).__name__}")
    if not method_fits(env_id, method):
        raise ValueError(f"method {method!r} does not run on env {env_id!r} (sac: ...Dense-v0 ids, sac-her: goal ids)")
    total = params.budget(method)
    folder = run_folder(env_id, method, seed, params)
    start = time.perf_counter()
    with limit_threads(blas_threads=params.threads, torch_threads=params.threads):
        env = make_env(env_id, method, params)
        n_eval = min(params.eval_episodes, MAX_EVAL_ENVS)
        eval_env = DummyVecEnv([lambda: make_env(env_id, method, params) for _ in range(n_eval)])
        loaded = _load_checkpoint(folder, env, seed, total) if params.checkpoint else None
        if loaded is not None:
            model, state = loaded
        else:
            model = _new_model(env, method, seed)
            state = {"timesteps": 0, "curve": [], "train_s": 0.0, "wall_s": 0.0}
        resumed_from = int(state["timesteps"])
        curve: list[list[float]] = [list(p) for p in state["curve"]]
        train_s, wall_before = float(state["train_s"]), float(state["wall_s"])
        eval_seed = seed + EVAL_SEED_OFFSET

        def evaluate(step: int) -> float:
            success = evaluate_success(model, eval_env, params.eval_episodes, eval_seed)
            curve.append([step, success])
            if on_eval is not None:
                on_eval(step, success)
            return success

        if not curve:
            evaluate(0)
        steps = int(model.num_timesteps)
        stopped = params.stop_success > 0 and curve[-1][1] >= params.stop_success
        while steps < total and not stopped:
            chunk = min(params.eval_every - steps % params.eval_every, total - steps)
            t0 = time.perf_counter()
            model.learn(total_timesteps=chunk, reset_num_timesteps=False, progress_bar=False)
            train_s += time.perf_counter() - t0
            steps = int(model.num_timesteps)
            success = evaluate(steps)
            stopped = params.stop_success > 0 and success >= params.stop_success
            if params.checkpoint:
                wall = wall_before + time.perf_counter() - start
                _save_checkpoint(
                    folder, model, {"timesteps": steps, "curve": curve, "train_s": train_s, "wall_s": wall}
                )
        env.close()
        eval_env.close()
    successes = [s for _, s in curve]
    reached = next((int(n) for n, s in curve if s >= TARGET_SUCCESS), None)
    metrics: dict[str, float | None] = {
        "success": successes[-1],
        "steps_to_goal": None if reached is None else float(reached),
        "best_success": max(successes),
        "timesteps": float(steps),
        "steps_per_s": steps / train_s if train_s > 0 else None,
        "wall_min": (wall_before + time.perf_counter() - start) / 60.0,
    }
    extra = {
        "curve": curve,
        "train_env": train_env_id(env_id, method, params),
        "learning_starts": int(model.learning_starts),
        "resumed_from": resumed_from,
        "stopped_early": bool(stopped and steps < total),
        "stable_baselines3": stable_baselines3.__version__,
    }
    return TrialResult(metrics, extra)
