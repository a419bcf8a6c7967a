"""Helpers the 2D kinematic env tests share: straight-line walks, batched expert rollouts, single-vs-vector steps."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from steer_envs.core.task import TaskSpec
from steer_envs.data.experts import ScriptedExpert, make_expert
from steer_envs.envs.kinematic import sensor_columns


def walk(env: Any, *moves: tuple[float, float]) -> list[dict]:
    """Move from the current state in straight max-speed steps through the waypoints ``moves``; the infos."""
    infos = []
    for target in moves:
        target_xy = np.asarray(target, dtype=np.float64)
        while np.linalg.norm(target_xy - env.state) > 1e-9:
            velocity = (target_xy - env.state) / env.dt  # the env clips the speed to max_speed
            infos.append(env.step(velocity.astype(np.float32))[4])
    return infos


def walk_from(env: Any, start: tuple[float, float] | None, *moves: tuple[float, float]) -> list[dict]:
    """(Reset at ``start`` and) :func:`walk` through ``moves``; the reset's info first."""
    infos = [] if start is None else [env.reset(options={"state": np.asarray(start, dtype=np.float64)})[1]]
    return infos + walk(env, *moves)


def run_expert_batch(
    env_id: str,
    task: TaskSpec,
    make_expert: Callable[[Any], Any],
    starts: np.ndarray,
    *,
    steps: int,
    noise: float = 0.0,
    seed: int = 0,
    sensor_rows: bool = False,
) -> dict:
    """Roll the expert (plus optional action noise) in the vector env from ``starts``; first episode of each.

    ``make_expert`` builds the expert from the single env; ``sensor_rows`` hands it the infos' ``sensors`` as the
    ``(N, k)`` array of :func:`sensor_columns`. Checks that the sensors always label the mode the env reports.
    """
    n = len(starts)
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    obs, info = venv.reset(seed=seed, options={"state": starts})
    expert = make_expert(venv.unwrapped.env)
    rng = np.random.default_rng(seed)
    done = np.zeros(n, dtype=bool)
    out = {"success": np.zeros(n, dtype=bool), "steps": np.zeros(n, dtype=np.int64), "violations": 0, "pairs": set()}
    readings: set[tuple[tuple[bool, ...], int]] = set()
    mode = info["mode"].copy()
    for k in range(steps):
        seen = {**info, "sensors": sensor_columns(info["sensors"], task.sensors)} if sensor_rows else info
        action = expert.act(obs, seen) + rng.normal(0.0, noise, size=(n, 2)).astype(np.float32)
        obs, _, term, trunc, info = venv.step(action)
        live = ~done
        out["violations"] += int((info["constraint_violation"] & live).sum())
        changed = live & (info["mode"] != mode)
        out["pairs"] |= {
            (task.modes[a], task.modes[b]) for a, b in zip(mode[changed], info["mode"][changed], strict=True)
        }
        readings |= {
            (tuple(row), int(m))
            for row, m in zip(
                sensor_columns(info["sensors"], task.sensors)[live].tolist(), info["mode"][live], strict=True
            )
        }
        mode = info["mode"].copy()
        newly = (term | trunc) & live
        out["success"][newly] = info["success"][newly]
        out["steps"][newly] = k + 1
        done |= term | trunc
        if done.all():
            break
    venv.close()
    for row, m in readings:  # the sensors always label the mode the env reports
        assert task.mode_of(dict(zip(task.sensors, row, strict=True))) == task.modes[m]
    return out


def step_singles_like_vector(
    vec: Any, singles: list[Any], actions: np.ndarray, done: np.ndarray
) -> list[tuple[int, bool, bool, dict]]:
    """Step ``vec`` and every single env not ``done`` with the same ``actions``; assert they agree.

    Returns ``(agent, terminated, truncated, info)`` of each single env stepped.
    """
    obs, rewards, terminated, truncated, infos = vec.step(actions)
    stepped = []
    for i, env in enumerate(singles):
        if done[i]:
            continue
        o, r, te, tr, info = env.step(actions[i])
        np.testing.assert_array_equal(o, obs[i])
        assert (r, te, tr) == (rewards[i], terminated[i], truncated[i])
        assert info["mode"] == infos["mode"][i] and info["success"] == infos["success"][i]
        assert info["constraint_violation"] == infos["constraint_violation"][i]
        assert list(info["sensors"].values()) == sensor_columns(infos["sensors"], list(info["sensors"]))[i].tolist()
        stepped.append((i, te, tr, info))
    return stepped


def noisy_expert_vector_parity(
    env_id: str,
    task: TaskSpec,
    make_env: Callable[[], Any],
    make_expert: Callable[[Any], Any],
    *,
    n: int = 8,
    sensor_rows: bool = False,
) -> tuple[np.ndarray, bool]:
    """Drive the vector env and ``n`` single envs with the expert plus growing noise; assert they agree.

    Returns which agents terminated and whether any single env reported a violation.
    """
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    starts = np.random.default_rng(2).uniform(-8, 8, size=(n, 2))
    vobs, vinfo = venv.reset(seed=0, options={"state": starts})
    singles = [make_env() for _ in range(n)]
    for env, s in zip(singles, starts, strict=True):
        env.reset(options={"state": s})
    expert = make_expert(singles[0])
    rng = np.random.default_rng(3)
    sigma = np.linspace(2.0, 20.0, n)[:, None]  # from nearly expert to nearly random
    finished = np.zeros(n, dtype=bool)
    seen_violation = False
    for _ in range(400):
        seen = {**vinfo, "sensors": sensor_columns(vinfo["sensors"], task.sensors)} if sensor_rows else vinfo
        actions = expert.act(vobs, seen) + (sigma * rng.normal(size=(n, 2))).astype(np.float32)
        vobs, vrew, vterm, _, vinfo = venv.step(actions)
        for k, env in enumerate(singles):
            if finished[k]:
                continue
            sobs, srew, sterm, _, sinfo = env.step(actions[k])
            np.testing.assert_allclose(vobs[k], sobs, atol=1e-6)
            assert (vinfo["mode"][k], vrew[k], vterm[k]) == (sinfo["mode"], srew, sterm)
            row = sensor_columns(vinfo["sensors"], task.sensors)[k].tolist()
            assert row == [sinfo["sensors"][ap] for ap in task.sensors]
            assert vinfo["constraint_violation"][k] == sinfo["constraint_violation"]
            seen_violation |= sinfo["constraint_violation"]
            finished[k] = sterm
        if finished.all():
            break
    venv.close()
    return finished, seen_violation


def expert_successes(env: Any, seeds: range, *, forbid_violations: bool = False) -> int:
    """How many episodes from ``reset(seed=s)`` the env's scripted expert ends successfully.

    ``forbid_violations``: assert that no step reports a constraint violation.
    """
    expert = make_expert(env)
    assert isinstance(expert, ScriptedExpert)
    successes = 0
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        expert.reset(obs, info)
        while True:
            obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
            assert not (forbid_violations and info["constraint_violation"])
            if terminated or truncated:
                break
        successes += info["success"]
    return successes


def check_seeded_start(env_id: str, start_mode: str, steps: int = 60) -> None:
    """The same reset seed gives the same random-action trajectory, another seed another one; every episode starts
    in ``start_mode`` on white (region 0)."""

    def rollout(seed: int) -> np.ndarray:
        env = gym.make(env_id)
        obs, info = env.reset(seed=seed)
        assert info["mode_name"] == start_mode and env.unwrapped.model.regions(obs[None])[0] == 0
        env.action_space.seed(seed)
        return np.asarray([obs] + [env.step(env.action_space.sample())[0] for _ in range(steps)])

    np.testing.assert_array_equal(rollout(4), rollout(4))
    assert not np.array_equal(rollout(4), rollout(5))


def run_with_one_push(
    env: Any,
    expert: ScriptedExpert,
    obs: Any,
    info: dict,
    steps: int,
    when: Callable[[Any, dict], bool],
    **push: Any,
) -> tuple[list[str], int | None, str | None, dict]:
    """Run ``expert`` from ``obs`` / ``info`` until the episode ends (at most ``steps``), perturbing the env
    once (``env.unwrapped.perturb(**push)``) at the first step after which ``when(obs, info)`` holds.

    Returns the mode of every step, the number of steps before the push (None: no push), the mode the push
    left, and the last info.
    """
    modes: list[str] = []
    pushed_at, pushed_to = None, None
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
        modes.append(info["mode_name"])
        if pushed_at is None and when(obs, info):
            info = env.unwrapped.perturb(**push)
            obs, pushed_at, pushed_to = env.unwrapped.state.astype(np.float32), len(modes), info["mode_name"]
        if terminated or truncated:
            break
    return modes, pushed_at, pushed_to, info
