"""Where PolygonNav demos start: the env's reset (default) or spread evenly around the workspace edge."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from shapely.geometry import Point

import steer_envs  # noqa: F401  (registers the envs)
from steer_envs.data.demo_starts import EDGE_INSET, START_CLEARANCE, spread_phase, spread_start
from steer_envs.data.demos import collect_demonstrations
from steer_envs.envs.polygon_nav import WORKSPACE_HALF_WIDTH

ENV3 = "steer_envs/PolygonNav-3Mode-v0"


def test_spread_starts_ring_the_workspace_clear_of_the_polygons() -> None:
    env = gym.make(ENV3, layout_seed=0)
    model = env.unwrapped.model  # type: ignore[attr-defined]
    starts = np.array([spread_start(env, a, 7, phase=0.3) for a in range(7)])
    assert np.allclose(np.abs(starts).max(axis=1), WORKSPACE_HALF_WIDTH - EDGE_INSET)  # on the inset square
    assert all(model.union.distance(Point(p)) >= START_CLEARANCE for p in starts)
    gaps = np.diff(np.sort(np.arctan2(starts[:, 1], starts[:, 0])))
    assert gaps.max() < 2 * np.pi / 7 + 0.5 and gaps.min() > 2 * np.pi / 7 - 0.5  # about evenly spaced
    turned = spread_start(env, 7, 7, phase=0.3)  # a second round of attempts sits between the first
    assert min(np.linalg.norm(starts - turned, axis=1)) > 1.0
    assert spread_phase(3) == spread_phase(3) != spread_phase(4)
    with pytest.raises(TypeError, match="spread_start: `env` must be a PolygonNav env"):
        spread_start(gym.make("steer_envs/ConvexMode-v0"), 0, 7, phase=0.0)
    with pytest.raises(ValueError, match="n"):
        spread_start(env, 0, 0, phase=0.0)
    env.close()


def test_spread_demos_start_on_the_ring_and_uniform_demos_where_the_env_resets() -> None:
    spread = collect_demonstrations(ENV3, 3, seed=5, layout_seed=0, demo_starts="spread")
    env = gym.make(ENV3, layout_seed=0)
    phase = spread_phase(5)
    for a, demo in enumerate(spread):
        assert demo.success and np.allclose(demo.states[0], spread_start(env, a, 3, phase=phase), atol=1e-6)
    uniform = collect_demonstrations(ENV3, 2, seed=5, layout_seed=0)
    named = collect_demonstrations(ENV3, 2, seed=5, layout_seed=0, demo_starts="uniform")
    assert all(np.array_equal(u.states, v.states) for u, v in zip(uniform, named, strict=True))
    for s, demo in enumerate(uniform, start=5):
        assert np.allclose(demo.states[0], env.reset(seed=s)[0])
    env.close()


def test_bad_demo_starts_are_refused() -> None:
    with pytest.raises(ValueError, match="collect_demonstrations: demo_starts must be one of"):
        collect_demonstrations(ENV3, 1, layout_seed=0, demo_starts="edge")
    with pytest.raises(ValueError, match="demo_starts='spread' needs a PolygonNav env"):
        collect_demonstrations("steer_envs/ConvexMode-v0", 1, demo_starts="spread")
