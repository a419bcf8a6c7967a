"""PolygonNav-{3,4,5}Mode-v0: layout validity, transition rules, determinism, vector path, expert."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
import shapely
from gymnasium.utils.env_checker import check_env
from kinematic_helpers import expert_successes, step_singles_like_vector

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.data.experts import make_expert
from steer_envs.envs.polygon_nav import PolygonNavEnv, PolygonNavModel

IDS = [f"steer_envs/PolygonNav-{k}Mode-v0" for k in (3, 4, 5)]


def _exposed_edge_entry(model: PolygonNavModel, polygon: int, edge: int, outside: float = 0.05) -> np.ndarray:
    """A free-space point ``outside`` in front of the middle of ``edge`` of 1-based ``polygon``."""
    v = model.vertices[polygon - 1]
    mid = 0.5 * (v[edge] + v[(edge + 1) % 4])
    return mid + outside * model.A[polygon - 1, edge]


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_and_sb3_env_checkers(env_id: str) -> None:
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make(env_id, layout_seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # both checkers advise a [-1, 1] action box; GLiDE's step is 0.1
        check_env(env.unwrapped)
        sb3_check_env(env.unwrapped, warn=False)


def test_registered_modes_and_task() -> None:
    for k, env_id in zip((3, 4, 5), IDS, strict=True):
        env = gym.make(env_id)
        task = env.unwrapped.task
        assert task.modes == ("free", *(f"p{j}" for j in range(1, k)))
        assert task.sensors == tuple(f"in_p{j}" for j in range(1, k))
        assert env.unwrapped.model.num_polygons == k - 1
        assert env.spec.max_episode_steps == 500
        i, j = np.indices((k, k))
        expected = (i == j) | (np.abs(i - j) == 1) | (j == 0)
        np.testing.assert_array_equal(task.allowed_matrix(), expected)
        for mode in task.modes:
            assert task.mode_of(task.sensors_of(mode)) == mode


def test_same_seed_same_trajectory_and_layout_seed_controls_geometry() -> None:
    actions = np.random.default_rng(0).uniform(-0.1, 0.1, size=(300, 2)).astype(np.float32)

    def rollout(env: gym.Env, seed: int) -> list:
        obs, info = env.reset(seed=seed)
        out = [obs.copy()]
        for a in actions:
            obs, r, te, tr, info = env.step(a)
            out.append((obs.copy(), r, te, tr, info["mode"]))
            if te or tr:
                break
        return out

    a, b = gym.make(IDS[1], layout_seed=8), gym.make(IDS[1], layout_seed=8)
    ra, rb = rollout(a, 4), rollout(b, 4)
    assert len(ra) == len(rb)
    np.testing.assert_array_equal(ra[0], rb[0])
    for x, y in zip(ra[1:], rb[1:], strict=True):
        np.testing.assert_array_equal(x[0], y[0])
        assert x[1:] == y[1:]
    for va, vb in zip(a.unwrapped.model.vertices, b.unwrapped.model.vertices, strict=True):
        np.testing.assert_array_equal(va, vb)
    c = gym.make(IDS[1], layout_seed=9)
    assert not np.allclose(np.vstack(c.unwrapped.model.vertices), np.vstack(a.unwrapped.model.vertices))
    # the reset seed does not change the geometry
    a.reset(seed=123)
    for va, vb in zip(a.unwrapped.model.vertices, b.unwrapped.model.vertices, strict=True):
        np.testing.assert_array_equal(va, vb)


@pytest.mark.parametrize("num_modes", [3, 4, 5])
@pytest.mark.parametrize("layout_seed", [0, 1, 2, 11, 42])
def test_layout_is_a_valid_chain(num_modes: int, layout_seed: int) -> None:
    m = PolygonNavModel(num_modes, layout_seed)
    polys = m.polygons
    assert len(polys) == num_modes - 1
    workspace = shapely.box(-8, -8, 8, 8).buffer(-m.workspace_margin + 1e-9)
    for v, p in zip(m.vertices, polys, strict=True):
        assert v.shape == (4, 2) and p.is_valid and p.exterior.is_ccw
        assert shapely.MultiPoint(v).convex_hull.symmetric_difference(p).area < 1e-9  # convex
        assert workspace.contains(p) and p.area >= 1.0
    for j in range(len(polys) - 1):
        shared = polys[j].intersection(polys[j + 1])
        assert shared.geom_type == "LineString" and shared.length > 0.1
        assert polys[j].intersection(polys[j + 1]).area < 1e-9
        np.testing.assert_allclose(shared.length, np.linalg.norm(np.diff(m.shared_edges[j], axis=0)))
        # a full edge of both polygons
        np.testing.assert_allclose(shared.length, np.linalg.norm(m.vertices[j][3] - m.vertices[j][2]))
        np.testing.assert_allclose(shared.length, np.linalg.norm(m.vertices[j + 1][1] - m.vertices[j + 1][0]))
    for i in range(len(polys)):
        for j in range(i + 2, len(polys)):
            assert polys[i].disjoint(polys[j]) and polys[i].distance(polys[j]) >= m.min_gap
    # modes agree with shapely point-in-polygon
    pts = np.random.default_rng(layout_seed).uniform(-8, 8, size=(5000, 2))
    expected = np.zeros(len(pts), dtype=np.int64)
    for j, p in enumerate(polys, start=1):
        expected[shapely.contains_xy(p, pts[:, 0], pts[:, 1])] = j
    np.testing.assert_array_equal(m.mode_of(pts), expected)
    assert (expected > 0).any()
    free = shapely.contains_xy(m.free_space, pts[:, 0], pts[:, 1])
    np.testing.assert_array_equal(free, expected == 0)


def test_starts_are_uniform_in_free_space() -> None:
    m = PolygonNavModel(4, 3)
    starts = m.sample_start(np.random.default_rng(0), 4000)
    assert np.all(m.mode_of(starts) == 0)
    assert np.all(np.abs(starts) <= 8)
    # uniform: the fraction in the left half matches the free area there
    left = shapely.box(-8, -8, 0, 8).intersection(m.free_space).area / m.free_space.area
    assert abs(np.mean(starts[:, 0] < 0) - left) < 0.04


def test_skipping_a_polygon_is_a_terminating_violation() -> None:
    env = gym.make(IDS[1], layout_seed=0)  # free, p1, p2, p3
    m = env.unwrapped.model
    start = _exposed_edge_entry(m, 2, 1)  # p2's edge (v1, v2) faces free space
    _, info = env.reset(options={"state": start})
    assert info["mode"] == 0 and not any(info["sensors"].values())
    _, reward, terminated, truncated, info = env.step((-m.A[1, 1] * 0.1).astype(np.float32))
    assert info["mode_name"] == "p2" and info["sensors"]["in_p2"]
    assert info["constraint_violation"] and terminated and not truncated and reward == -1.0 and not info["success"]


def test_free_space_to_last_polygon_is_no_success_even_without_termination() -> None:
    env = PolygonNavEnv(num_modes=3, layout_seed=2, terminate_on_violation=False)
    m = env.model
    env.reset(options={"state": _exposed_edge_entry(m, 2, 1)})
    _, reward, terminated, _, info = env.step((-m.A[1, 1] * 0.1).astype(np.float32))
    assert info["mode_name"] == "p2" and info["constraint_violation"]
    assert not terminated and not info["success"] and reward == -1.0
    # walking on inside the goal polygon stays a failure (the invalid transition is remembered)
    _, _, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert not info["success"] and not info["constraint_violation"] and not terminated


def test_allowed_transitions_are_not_violations() -> None:
    env = gym.make(IDS[2], layout_seed=1)  # free, p1..p4
    m = env.unwrapped.model
    # free -> p1 -> free (polygon 1's first edge is exposed)
    env.reset(options={"state": _exposed_edge_entry(m, 1, 0)})
    step_in = (-m.A[0, 0] * 0.1).astype(np.float32)
    _, _, terminated, _, info = env.step(step_in)
    assert info["mode_name"] == "p1" and not info["constraint_violation"] and not terminated
    _, _, _, _, info = env.step(-step_in)
    assert info["mode_name"] == "free" and not info["constraint_violation"]
    # p3 -> free (any later mode may fall back to free space) and p2 -> p3 -> p2 across the shared edge
    env.reset(options={"state": _exposed_edge_entry(m, 3, 1, outside=-0.05)})
    _, _, terminated, _, info = env.step((m.A[2, 1] * 0.1).astype(np.float32))
    assert info["mode_name"] == "free" and not info["constraint_violation"] and not terminated
    a, b = m.shared_edges[1]
    mid = 0.5 * (a + b)
    env.reset(options={"state": mid - 0.05 * m.A[1, 2]})
    assert env.unwrapped.model.mode_of(env.unwrapped.state[None])[0] == 2
    _, _, _, _, info = env.step((m.A[1, 2] * 0.1).astype(np.float32))
    assert info["mode_name"] == "p3" and not info["constraint_violation"]
    _, _, _, _, info = env.step((-m.A[1, 2] * 0.1).astype(np.float32))
    assert info["mode_name"] == "p2" and not info["constraint_violation"]
    # reaching the last polygon through the chain is a success
    a, b = m.shared_edges[-1]
    env.reset(options={"state": 0.5 * (a + b) - 0.05 * m.A[2, 2]})
    _, reward, terminated, _, info = env.step((m.A[2, 2] * 0.1).astype(np.float32))
    assert info["mode_name"] == "p4" and info["success"] and terminated and reward == 1.0


def test_perturb_is_not_a_transition_and_rejects_bad_arguments() -> None:
    env = PolygonNavEnv(num_modes=4, layout_seed=0)
    m = env.model
    env.reset(seed=0)
    info = env.perturb(to=m.polygons[1].representative_point().coords[0])  # free -> p2 by the world
    assert info["perturbed"] and info["mode_name"] == "p2" and not info["constraint_violation"]
    a, b = m.shared_edges[-1]
    env.perturb(to=0.5 * (a + b) - 0.05 * m.A[1, 2])
    _, _, terminated, _, info = env.step((m.A[1, 2] * 0.1).astype(np.float32))
    assert info["success"] and terminated
    for kwargs in ({}, {"delta": np.zeros(2), "to": np.zeros(2)}, {"delta": [1.0]}, {"to": [np.inf, 0.0]}):
        with pytest.raises(ValueError):
            env.perturb(**kwargs)
    with pytest.raises(TypeError):
        env.perturb(delta=object())


def test_bad_constructor_arguments() -> None:
    with pytest.raises(ValueError, match="num_modes"):
        PolygonNavEnv(num_modes=1)
    with pytest.raises(TypeError, match="num_modes"):
        PolygonNavEnv(num_modes=3.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="layout_seed"):
        PolygonNavEnv(layout_seed=-3)
    with pytest.raises(ValueError, match="min_gap"):
        PolygonNavEnv(min_gap=0.0)


def test_advance_does_not_mutate_inputs_and_trajectory_success() -> None:
    m = PolygonNavModel(4, 5)
    rng = np.random.default_rng(0)
    prev = rng.uniform(-8, 8, size=(64, 2))
    pos = rng.uniform(-8, 8, size=(64, 2))
    memory = m.reset_memory(prev)
    copies = (memory.copy(), prev.copy(), pos.copy())
    new_memory, violation = m.advance(memory, prev, pos)
    for before, after in zip(copies, (memory, prev, pos), strict=True):
        np.testing.assert_array_equal(before, after)
    np.testing.assert_array_equal(violation, ~m.allowed[m.mode_of(prev), m.mode_of(pos)])
    np.testing.assert_array_equal(new_memory[:, 0], violation)
    assert violation.any() and not violation.all()

    wrapped = gym.make(IDS[1], layout_seed=5)
    env, expert = wrapped.unwrapped, make_expert(wrapped)
    obs, info = env.reset(seed=1)
    expert.reset(obs, info)
    path = [env.state]
    while not (info["success"] or len(path) > 500):
        obs, _, _, _, info = env.step(expert.act(obs, info))
        path.append(env.state)
    path = np.array(path)
    assert m.trajectory_success(path)
    skip = np.vstack([path[:1], m.polygons[1].representative_point().coords[0], path[1:]])
    assert not m.trajectory_success(skip)
    assert not m.trajectory_success(path[:-1])


@pytest.mark.parametrize("env_id", [IDS[0], IDS[2]])
def test_vector_env_agrees_with_single_envs(env_id: str) -> None:
    n = 8
    vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", layout_seed=4)
    singles = [gym.make(env_id, layout_seed=4).unwrapped for _ in range(n)]
    model = singles[0].model
    # half the agents start next to polygon 2 so that some invalid transitions happen
    starts = model.sample_start(np.random.default_rng(0), n)
    starts[: n // 2] = _exposed_edge_entry(model, 2, 1, outside=0.3)
    obs, _ = vec.reset(seed=0, options={"state": starts})
    for i, env in enumerate(singles):
        o, info = env.reset(options={"state": starts[i]})
        np.testing.assert_array_equal(o, obs[i])
    rng = np.random.default_rng(1)
    drift = rng.normal(0, 0.1, size=(n, 2))
    drift[: n // 2] = -model.A[1, 1] * 0.08
    done = np.zeros(n, dtype=bool)
    violations = 0
    for _ in range(120):
        actions = (drift + rng.normal(0, 0.05, size=(n, 2))).astype(np.float32)
        for i, te, tr, info in step_singles_like_vector(vec, singles, actions, done):
            violations += info["constraint_violation"]
            done[i] = te or tr
    assert violations >= 1 and done.any()


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("layout_seed", [0, 6])
def test_expert_succeeds(env_id: str, layout_seed: int) -> None:
    env = gym.make(env_id, layout_seed=layout_seed)
    assert expert_successes(env, range(100)) >= 99


def test_expert_recovers_from_glide_perturbations() -> None:
    """GLiDE evaluation pushes: after the first mode change, teleport to a uniform free-space point."""
    env = gym.make(IDS[2], layout_seed=3, max_episode_steps=1500)
    expert = make_expert(env)
    m = env.unwrapped.model
    rng = np.random.default_rng(0)
    successes, pushes = 0, 0
    for seed in range(15):
        obs, info = env.reset(seed=seed)
        expert.reset(obs, info)
        last_push, episode_pushes = -100, 0
        for t in range(1500):
            if info["mode"] > 0 and episode_pushes < 3 and t - last_push >= 50 and rng.random() < 0.05:
                info = env.unwrapped.perturb(to=m.sample_start(rng, 1)[0])
                last_push, episode_pushes = t, episode_pushes + 1
            obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
            if terminated or truncated:
                break
        successes += info["success"]
        pushes += episode_pushes
    assert pushes >= 10
    assert successes == 15


@pytest.mark.parametrize("env_id", IDS)
def test_render_rgb_array(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array", render_size=96)
    env.reset(seed=0)
    env.step(np.array([0.1, 0.0], dtype=np.float32))
    image = env.render()
    assert image.shape == (96, 96, 3) and image.dtype == np.uint8
    # free space, one colour per polygon, outlines and the agent
    assert len(np.unique(image.reshape(-1, 3), axis=0)) >= env.unwrapped.model.num_modes + 1


def test_sample_in_mode_draws_inside_the_asked_region() -> None:
    """Free space is what ``sample_start`` draws; a polygon mode samples inside that polygon only."""
    env = gym.make("steer_envs/PolygonNav-4Mode-v0", layout_seed=0)
    model = env.unwrapped.model
    for mode in range(4):
        pts = model.sample_in_mode(np.random.default_rng(mode), 200, mode)
        assert pts.shape == (200, 2) and np.all(model.mode_of(pts) == mode)
    np.testing.assert_array_equal(
        model.sample_start(np.random.default_rng(3), 50), model.sample_in_mode(np.random.default_rng(3), 50, 0)
    )
    with pytest.raises(ValueError, match="mode"):
        model.sample_in_mode(np.random.default_rng(0), 5, 4)
    env.close()
