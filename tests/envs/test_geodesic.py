"""GeodesicDistance: shortest paths around convex obstacles (PolygonNav's free-space dense reward)."""

from __future__ import annotations

import numpy as np
import pytest

from steer_envs.envs.geodesic import GeodesicDistance


def square(cx: float, cy: float, half: float = 1.0) -> np.ndarray:
    return np.array([[cx - half, cy - half], [cx + half, cy - half], [cx + half, cy + half], [cx - half, cy + half]])


def test_without_obstacles_it_is_the_straight_line() -> None:
    field = GeodesicDistance([], target=np.array([1.0, 2.0]))
    pts = np.random.default_rng(0).uniform(-5, 5, size=(20, 2))
    np.testing.assert_allclose(field(pts), np.linalg.norm(pts - [1.0, 2.0], axis=1))


def test_a_wall_of_touching_squares_is_walked_around_at_its_end() -> None:
    # three unit squares side by side make a 6-wide wall from x = -3 to 3 between the point and the target
    wall = [square(-2.0, 0.0), square(0.0, 0.0), square(2.0, 0.0)]
    field = GeodesicDistance(wall, target=np.array([0.0, 3.0]), clearance=0.0)
    around = 2 * float(np.hypot(3.0, 2.0)) + 2.0  # to a bottom corner, up the wall's side, to the target
    assert field(np.array([[0.0, -3.0]]))[0] == pytest.approx(around)
    assert field(np.array([[0.0, 2.0]]))[0] == pytest.approx(1.0)  # in sight: straight
    # nearer the wall's end the detour is shorter, and it never beats the straight line
    pts = np.array([[x, -3.0] for x in np.linspace(0.0, 2.5, 6)])
    d = field(pts)
    assert np.all(np.diff(d) < 0) and np.all(d >= np.linalg.norm(pts - [0.0, 3.0], axis=1))


def test_clearance_keeps_the_path_off_the_corners_and_repeated_calls_agree() -> None:
    field = GeodesicDistance([square(0.0, 0.0)], target=np.array([0.0, 3.0]), clearance=0.1)
    tight = GeodesicDistance([square(0.0, 0.0)], target=np.array([0.0, 3.0]), clearance=0.0)
    p = np.array([[0.0, -3.0]])
    assert field(p)[0] > tight(p)[0]
    first = field(p)
    first[0] = -1.0  # the answer is the caller's: changing it changes no later answer
    assert field(p)[0] == pytest.approx(tight(p)[0], abs=0.5) and field(p)[0] > 0
    inside = np.array([[0.0, 0.0]])  # sees no node: the straight line
    assert field(inside)[0] == pytest.approx(3.0)
