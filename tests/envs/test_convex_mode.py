"""ConvexMode-v0: geometry, task rules, determinism, vector path and the scripted expert."""

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
from steer_envs.envs.convex_mode import ConvexModeEnv, ConvexModeModel, convex_halfspaces, in_halfspaces

ENV_ID = "steer_envs/ConvexMode-v0"


def _rollout(env: gym.Env, seed: int, actions: np.ndarray) -> list[tuple]:
    obs, info = env.reset(seed=seed)
    out = [(obs.copy(), info["mode"])]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        out.append((obs.copy(), reward, terminated, info["mode"], info["constraint_violation"]))
        if terminated or truncated:
            break
    return out


def test_gymnasium_and_sb3_env_checkers() -> None:
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make(ENV_ID, layout_seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # both checkers advise a [-1, 1] action box; the thesis speed limit is 20
        check_env(env.unwrapped)
        sb3_check_env(env.unwrapped, warn=False)


def test_same_seed_same_trajectory_and_layout_seed_controls_geometry() -> None:
    actions = np.random.default_rng(0).uniform(-20, 20, size=(200, 2)).astype(np.float32)
    a, b = gym.make(ENV_ID, layout_seed=5), gym.make(ENV_ID, layout_seed=5)
    ra, rb = _rollout(a, 11, actions), _rollout(b, 11, actions)
    assert len(ra) == len(rb)
    for x, y in zip(ra, rb, strict=True):
        np.testing.assert_array_equal(x[0], y[0])
        assert x[1:] == y[1:]
    assert not np.array_equal(_rollout(a, 12, actions)[0][0], ra[0][0])  # another reset seed, another start
    np.testing.assert_array_equal(a.unwrapped.model.vertices, b.unwrapped.model.vertices)
    np.testing.assert_array_equal(a.unwrapped.model.attractor, b.unwrapped.model.attractor)
    c = gym.make(ENV_ID, layout_seed=6)
    assert c.unwrapped.model.vertices.shape != a.unwrapped.model.vertices.shape or not np.allclose(
        c.unwrapped.model.vertices, a.unwrapped.model.vertices
    )


@pytest.mark.parametrize("layout_seed", [0, 1, 2, 3, 17])
def test_geometry_matches_tli_construction(layout_seed: int) -> None:
    m = ConvexModeModel(layout_seed=layout_seed)
    assert m.points.shape == (10, 2) and np.all(np.abs(m.points) <= 6)
    hull = shapely.MultiPoint(m.points).convex_hull
    assert hull.symmetric_difference(m.polygon).area < 1e-9
    assert m.polygon.exterior.is_ccw
    assert np.all(np.abs(m.vertices) <= 6)
    # attractor: strictly inside, near the right edge, not next to the demo start
    assert m.polygon.contains(shapely.Point(m.attractor))
    assert m.polygon.contains(shapely.Point(m.demo_start))
    right_x = np.sort(m.vertices[:, 0])[-2:]
    assert m.attractor[0] > m.demo_start[0]
    assert m.attractor[0] >= 0.9 * right_x.min() + 0.1 * m.vertices[:, 0].min() - 1e-9
    # half-space form agrees with shapely on random points
    pts = np.random.default_rng(layout_seed).uniform(-8, 8, size=(4000, 2))
    np.testing.assert_array_equal(m.inside(pts), shapely.contains_xy(m.polygon, pts[:, 0], pts[:, 1]))
    a, b = convex_halfspaces(m.vertices)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0)
    np.testing.assert_array_equal(in_halfspaces(a, b, pts), m.inside(pts))


def test_leaving_the_mode_is_a_terminating_violation() -> None:
    env = gym.make(ENV_ID, layout_seed=4)
    m = env.unwrapped.model
    # start just inside the left-most vertex's first edge and push outward at full speed
    edge_mid = 0.5 * (m.vertices[0] + m.vertices[1])
    start = edge_mid - 0.05 * m.A[0]
    _, info = env.reset(options={"state": start})
    assert info["mode_name"] == "inside" and info["sensors"] == {"in_mode": True}
    _, reward, terminated, truncated, info = env.step((20 * m.A[0]).astype(np.float32))
    assert info["constraint_violation"] and info["mode_name"] == "outside" and not info["success"]
    assert terminated and not truncated and reward == -1.0

    # without termination the failure is remembered: reaching the attractor afterwards is no success
    env2 = ConvexModeEnv(layout_seed=4, terminate_on_violation=False)
    env2.reset(options={"state": start})
    _, _, terminated, _, info = env2.step((20 * m.A[0]).astype(np.float32))
    assert info["constraint_violation"] and not terminated
    env2.step((-20 * m.A[0]).astype(np.float32))  # back in
    info = env2.perturb(to=m.attractor)
    assert info["mode_name"] == "inside" and not info["success"]


def test_success_at_the_attractor_and_push_is_not_a_violation() -> None:
    env = ConvexModeEnv(layout_seed=4)
    m = env.model
    env.reset(options={"state": m.attractor})
    _, reward, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["success"] and terminated and reward == 1.0
    env.reset(options={"state": m.demo_start})
    info = env.perturb(to=np.array([7.9, 7.9]))  # pushed out of the mode by the world
    assert info["perturbed"] and info["mode_name"] == "outside" and not info["constraint_violation"]
    info = env.perturb(to=m.attractor)  # pushed back in: the policy never left, so this counts
    assert info["success"]


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({}, ValueError),
        ({"delta": np.zeros(2), "to": np.zeros(2)}, ValueError),
        ({"delta": np.zeros(3)}, ValueError),
        ({"to": np.array([np.nan, 0.0])}, ValueError),
        ({"delta": "far"}, TypeError),
    ],
)
def test_perturb_rejects_bad_arguments(kwargs: dict, error: type[Exception]) -> None:
    env = ConvexModeEnv()
    env.reset(seed=0)
    with pytest.raises(error):
        env.perturb(**kwargs)


def test_bad_constructor_arguments() -> None:
    with pytest.raises(ValueError, match="layout_seed"):
        ConvexModeEnv(layout_seed=-1)
    with pytest.raises(TypeError, match="layout_seed"):
        ConvexModeEnv(layout_seed=1.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="start_noise"):
        ConvexModeEnv(start_noise=-1.0)
    with pytest.raises(TypeError, match="start_noise"):
        ConvexModeEnv(start_noise="big")  # type: ignore[arg-type]


def test_start_distributions() -> None:
    rng = np.random.default_rng(0)
    uniform = ConvexModeModel(layout_seed=3)
    starts = uniform.sample_start(rng, 2000)
    assert uniform.inside(starts).all()
    # uniform over the mode: the mean of the starts is the polygon's centroid
    np.testing.assert_allclose(starts.mean(axis=0), np.asarray(uniform.polygon.centroid.coords[0]), atol=0.2)

    on_demo = ConvexModeModel(layout_seed=3, start_noise=0.0)
    starts = on_demo.sample_start(rng, 500)
    d = on_demo.attractor - on_demo.demo_start
    cross = d[0] * (starts[:, 1] - on_demo.demo_start[1]) - d[1] * (starts[:, 0] - on_demo.demo_start[0])
    np.testing.assert_allclose(cross, 0.0, atol=1e-9)  # on the demonstration segment

    noisy = ConvexModeModel(layout_seed=3, start_noise=5.0)
    starts = noisy.sample_start(rng, 500)
    assert noisy.inside(starts).all()
    cross = d[0] * (starts[:, 1] - noisy.demo_start[1]) - d[1] * (starts[:, 0] - noisy.demo_start[0])
    assert np.abs(cross).max() > 1.0


def test_advance_does_not_mutate_inputs_and_trajectory_success() -> None:
    m = ConvexModeModel(layout_seed=1)
    prev = m.sample_start(np.random.default_rng(0), 16)
    pos = prev + np.random.default_rng(1).normal(0, 3, size=prev.shape)
    memory = m.reset_memory(prev)
    copies = (memory.copy(), prev.copy(), pos.copy())
    new_memory, violation = m.advance(memory, prev, pos)
    for before, after in zip(copies, (memory, prev, pos), strict=True):
        np.testing.assert_array_equal(before, after)
    np.testing.assert_array_equal(violation, ~m.inside(pos))
    np.testing.assert_array_equal(new_memory[:, 0], violation)

    line = np.linspace(m.demo_start, m.attractor, 50)
    assert m.trajectory_success(line)
    outside = np.array([8.0, 8.0]) if not m.inside(np.array([[8.0, 8.0]]))[0] else np.array([-8.0, -8.0])
    assert not m.trajectory_success(np.vstack([line[:10], outside, line[10:]]))
    assert not m.trajectory_success(line[:10])


def test_vector_env_agrees_with_single_envs() -> None:
    n = 8
    vec = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", layout_seed=2)
    singles = [ConvexModeEnv(layout_seed=2) for _ in range(n)]
    starts = np.stack([e.model.sample_start(np.random.default_rng(i), 1)[0] for i, e in enumerate(singles)])
    with pytest.raises(ValueError, match="state"):
        vec.reset(options={"state": starts[:3]})
    obs, infos = vec.reset(seed=0, options={"state": starts})
    for i, env in enumerate(singles):
        o, info = env.reset(options={"state": starts[i]})
        np.testing.assert_array_equal(o, obs[i])
        assert info["mode"] == infos["mode"][i]
    rng = np.random.default_rng(3)
    drift = rng.uniform(-15, 15, size=(n, 2))
    done = np.zeros(n, dtype=bool)
    ended = 0
    for _ in range(150):
        actions = (drift + rng.normal(0, 5, size=(n, 2))).astype(np.float32)
        for i, te, tr, _ in step_singles_like_vector(vec, singles, actions, done):
            done[i] = te or tr
            ended += te
    assert ended >= 2  # some agents left the mode or reached the attractor, so termination was compared


@pytest.mark.parametrize("layout_seed", [0, 7, 23])
def test_expert_succeeds(layout_seed: int) -> None:
    env = gym.make(ENV_ID, layout_seed=layout_seed)
    assert expert_successes(env, range(100), forbid_violations=True) >= 99


def test_expert_with_noisy_starts_and_perturbations() -> None:
    env = gym.make(ENV_ID, layout_seed=9, start_noise=5.0)
    expert = make_expert(env)
    m = env.unwrapped.model
    rng = np.random.default_rng(0)
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        expert.reset(obs, info)
        for t in range(1000):
            if t == 5:  # pushed to another in-mode state: the expert follows the true state
                env.unwrapped.perturb(to=m.sample_start(rng, 1)[0])
            obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
            if terminated or truncated:
                break
        assert info["success"]


def test_render_rgb_array() -> None:
    env = gym.make(ENV_ID, render_mode="rgb_array", render_size=128)
    env.reset(seed=0)
    env.step(np.ones(2, dtype=np.float32))
    image = env.render()
    assert image.shape == (128, 128, 3) and image.dtype == np.uint8
    assert len(np.unique(image.reshape(-1, 3), axis=0)) >= 4  # background, mode, outline, attractor, agent
