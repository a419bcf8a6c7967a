"""Pinhole camera maths of the robosuite adapter: world points <-> pixels of a rendered frame.

Pure numpy, no robosuite import: the adapter passes in the camera's 4x4
world-to-image matrix (robosuite's ``camera_utils.get_camera_transform_matrix``
for a square frame), which maps a world point ``p`` to ``(x z, y z, z, 1)``.
Conventions, shared by :meth:`RobosuiteEnv.pixel_to_world
<steer_envs.envs.robosuite.adapter.RobosuiteEnv.pixel_to_world>` and friends:

- image convention: pixel ``(u, v)`` is column ``u``, row ``v``, row 0 at the
  top, as in the frames ``render`` returns (robosuite's raw frames are upside
  down; its camera matrix already points its image y axis down);
- robosuite's ``(x, y)`` are continuous coordinates from the image's top-left
  corner, so pixel ``(u, v)`` covers ``[u, u + 1) x [v, v + 1)`` and integer
  ``(u, v)`` name pixel *centres* here: ``u = x - 0.5``;
- depth ``z`` is the distance along the camera's optical axis (m), what
  MuJoCo's depth buffer holds once converted to metres (not the ray length).

>>> cam = np.array([[100.0, 0, 64, 0], [0, 100, 64, 0], [0, 0, 1, 0], [0, 0, 0, 1]])  # at the origin, looking along +z
>>> world_to_pixel([[0.1, -0.2, 2.0]], cam)
array([[68.5, 53.5,  2. ]])
>>> pixel_to_world(68.5, 53.5, 2.0, cam)
array([ 0.1, -0.2,  2. ])
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.core.validation import real_array

__all__ = ["nearest_pixel", "pixel_to_world", "world_to_pixel"]

#: image coordinates of a pixel's centre, relative to robosuite's continuous coordinates (x = u + 0.5)
_CENTRE = 0.5


def world_to_pixel(points: Any, world_to_image: Any) -> np.ndarray:
    """``(u, v, depth)`` of each world point (``(..., 3)``, m): pixel coordinates in image convention and z-depth.

    Points behind the camera get a negative depth (their ``(u, v)`` are then
    meaningless); nothing is clipped to the frame.
    """
    p = real_array(points, "points", owner="world_to_pixel")
    if p.ndim < 1 or p.shape[-1] != 3:
        raise ValueError(f"world_to_pixel: points must have shape (..., 3), got {p.shape}")
    m = real_array(world_to_image, "world_to_image", shape=(4, 4), owner="world_to_pixel")
    h = p @ m[:3, :3].T + m[:3, 3]
    z = h[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = h[..., :2] / z[..., None] - _CENTRE
    return np.concatenate([uv, z[..., None]], axis=-1)


def pixel_to_world(u: float, v: float, depth: float, world_to_image: Any) -> np.ndarray:
    """The world point (3,) seen at pixel coordinates ``(u, v)`` (image convention) at z-depth ``depth`` (m).

    The inverse of :func:`world_to_pixel`; arguments are taken as given (the
    adapter validates them against its frame).
    """
    m = real_array(world_to_image, "world_to_image", shape=(4, 4), owner="pixel_to_world")
    x, y = u + _CENTRE, v + _CENTRE
    h = np.linalg.solve(m, np.array([x * depth, y * depth, depth, 1.0]))
    return np.asarray(h[:3] / h[3], dtype=np.float64)


def nearest_pixel(u: float, v: float, size: int) -> tuple[int, int]:
    """``(row, column)`` of the pixel nearest to ``(u, v)`` in a ``size x size`` frame (clipped into it).

    >>> nearest_pixel(3.4, 255.7, 256)
    (255, 3)
    """
    col = min(max(int(np.floor(u + 0.5)), 0), size - 1)
    row = min(max(int(np.floor(v + 0.5)), 0), size - 1)
    return row, col
