"""Where a person's input lands: pixel views of an env, sketches resampled, and the error a bad request raises.

A view converts between the pixels of the rendered frame and world points:
:class:`PixelMap` for an env with an affine ``pixel_to_xy`` (Maze2D's top-down
image), :class:`CameraView` for a camera with depth (BlockStack: a click lands
on the first surface the pixel sees). :func:`resample_by_arclength` turns a
mouse path drawn at any speed into evenly spaced sketch points. A
:class:`PlaneView` maps a camera's pixels onto a plane facing it (a robosuite
arm's agent dragged across the image: ArmScoop's spoon, Lift's gripper). Requests that
cannot be served raise :class:`SessionError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.core.validation import integer, real_array

__all__ = [
    "MAX_INPUT_POINTS",
    "CameraView",
    "PixelMap",
    "PlaneView",
    "SessionError",
    "make_view",
    "rendered_frame",
    "resample_by_arclength",
]

#: the most mouse points one sketch may have before resampling
MAX_INPUT_POINTS = 4096


class SessionError(ValueError):
    """A request the session cannot serve (bad interaction, wrong state); the message says why."""


@dataclass(frozen=True)
class PixelMap:
    """An affine map between image pixels ``(u = column, v = row)`` and world ``(x, y)`` of a 2D view.

    Built by probing the env's ``pixel_to_xy`` at three pixels and checked at a
    fourth, so any env whose view is an axis-aligned or rotated scaling works.
    """

    width: int
    height: int
    matrix: np.ndarray  # (2, 2): world = matrix @ [u, v] + offset
    offset: np.ndarray

    @classmethod
    def from_env(cls, base: Any, width: int, height: int) -> PixelMap:
        """Probe ``base.pixel_to_xy``; ``SessionError`` when the env has none or it is not affine."""
        to_xy = getattr(base, "pixel_to_xy", None)
        if not callable(to_xy):
            raise SessionError(
                f"{type(base).__name__} has no pixel_to_xy(u, v): steer-ui needs a 2D view it can map clicks into"
            )
        origin = np.asarray(to_xy(0.0, 0.0), dtype=np.float64)
        du = np.asarray(to_xy(1.0, 0.0), dtype=np.float64) - origin
        dv = np.asarray(to_xy(0.0, 1.0), dtype=np.float64) - origin
        matrix = np.stack([du, dv], axis=1)
        probe = np.asarray(to_xy(float(width), float(height)), dtype=np.float64)
        if matrix.shape != (2, 2) or abs(np.linalg.det(matrix)) < 1e-12:
            raise SessionError(f"{type(base).__name__}.pixel_to_xy is not an invertible 2D map")
        if not np.allclose(matrix @ np.array([width, height]) + origin, probe, atol=1e-6):
            raise SessionError(f"{type(base).__name__}.pixel_to_xy is not affine; steer-ui maps 2D views only")
        return cls(int(width), int(height), matrix, origin)

    @classmethod
    def from_box(cls, low: Any, high: Any, width: int, height: int) -> PixelMap:
        """The top-down view of the world box ``[low, high]`` drawn ``width x height`` (x right, y up).

        The convention of the kinematic envs' frames (:class:`~steer_envs.envs.render.Canvas`).

        >>> view = PixelMap.from_box([-8.0, -8.0], [8.0, 8.0], 256, 256)
        >>> view.to_world([[0.0, 0.0], [128.0, 128.0]]).tolist()
        [[-8.0, 8.0], [0.0, 0.0]]
        """
        lo = real_array(low, "low", shape=(2,), owner="PixelMap.from_box")
        hi = real_array(high, "high", shape=(2,), owner="PixelMap.from_box")
        if not np.all(hi > lo):
            raise SessionError(f"PixelMap.from_box: need low < high, got {lo.tolist()}, {hi.tolist()}")
        width, height = integer(width, "`width`", low=1), integer(height, "`height`", low=1)
        matrix = np.diag([(hi[0] - lo[0]) / width, -(hi[1] - lo[1]) / height])
        return cls(width, height, matrix, np.array([lo[0], hi[1]]))

    def to_world(self, pixels: Any) -> np.ndarray:
        """``(..., 2)`` pixels -> world points."""
        return np.asarray(pixels, dtype=np.float64) @ self.matrix.T + self.offset

    def to_pixels(self, points: Any) -> np.ndarray:
        """``(..., 2)`` world points -> pixels (fractional)."""
        return (np.asarray(points, dtype=np.float64) - self.offset) @ np.linalg.inv(self.matrix).T

    def check_pixels(self, pixels: Any, name: str) -> np.ndarray:
        """``pixels`` as a finite ``(N, 2)`` array inside the image; ``ValueError`` naming ``name`` otherwise."""
        return _check_pixels(pixels, name, self.width, self.height)


class CameraView:
    """Pixels of a camera frame <-> world points through the depth buffer (a robosuite env's camera).

    :meth:`to_world` lifts pixels onto the first surface they see (one depth
    render per call); :meth:`to_pixels` projects world points (plans, sketches).
    """

    def __init__(self, base: Any) -> None:
        for name in ("render_rgbd", "camera_matrix", "render_size"):
            if not hasattr(base, name):
                raise SessionError(f"{type(base).__name__} has no {name}: CameraView needs a robosuite camera env")
        self.base = base
        self.width = self.height = int(base.render_size)

    def to_world(self, pixels: Any) -> np.ndarray:
        """``(N, 2)`` pixels -> ``(N, 3)`` world points on the surfaces they see."""
        from steer_envs.envs.robosuite import camera as cam

        arr = np.atleast_2d(np.asarray(pixels, dtype=np.float64))
        depth = self.base.render_rgbd()[1]
        matrix = self.base.camera_matrix()
        out = []
        for u, v in arr:
            row, col = cam.nearest_pixel(min(u, self.width - 1e-6), min(v, self.height - 1e-6), self.width)
            out.append(cam.pixel_to_world(u, v, float(depth[row, col]), matrix))
        return np.asarray(out)

    def to_pixels(self, points: Any) -> np.ndarray:
        """``(..., k >= 3)`` points whose first three entries are world xyz -> ``(..., 2)`` pixels (not clipped).

        Skill plans carry more per waypoint (``[x, y, z, gripper]``); only the position is drawn.
        """
        from steer_envs.envs.robosuite import camera as cam

        arr = np.asarray(points, dtype=np.float64)
        if arr.ndim < 1 or arr.shape[-1] < 3:
            raise SessionError(f"CameraView.to_pixels needs points with x, y, z on the last axis, got {arr.shape}")
        xyz = arr[..., :3]
        flat = cam.world_to_pixel(xyz.reshape(-1, 3), self.base.camera_matrix())
        return np.asarray(flat, dtype=np.float64)[:, :2].reshape(*xyz.shape[:-1], 2)

    def check_pixels(self, pixels: Any, name: str) -> np.ndarray:
        """As :meth:`PixelMap.check_pixels`."""
        return _check_pixels(pixels, name, self.width, self.height)


class PlaneView:
    """Pixels of a robosuite camera frame <-> world points on the plane ``world[axis] = level`` (a drag's plane).

    A pixel is lifted onto the plane through the agent that faces the camera
    (``axis`` 0, world ``x``, for the ``frontview`` camera, which looks along
    ``-x``): dragging the agent across the image moves it in that plane, the
    way a person expects. :meth:`to_pixels` projects world points (flows,
    trails, targets).
    """

    def __init__(self, base: Any, axis: int = 0) -> None:
        for name in ("camera_matrix", "render_size"):
            if not hasattr(base, name):
                raise SessionError(f"{type(base).__name__} has no {name}: PlaneView needs a robosuite camera env")
        self.base = base
        self.axis = integer(axis, "`axis`", low=0, high=2)
        self.width = self.height = int(base.render_size)
        self._matrix = np.asarray(base.camera_matrix(), dtype=np.float64)  # the scene cameras are fixed

    def to_pixels(self, points: Any) -> np.ndarray:
        """``(..., 3)`` world points -> ``(..., 2)`` pixels (fractional, not clipped)."""
        from steer_envs.envs.robosuite import camera as cam

        arr = np.asarray(points, dtype=np.float64)
        if arr.ndim < 1 or arr.shape[-1] != 3:
            raise SessionError(f"PlaneView.to_pixels needs world points (..., 3), got shape {arr.shape}")
        flat = cam.world_to_pixel(arr.reshape(-1, 3), self._matrix)
        return np.asarray(flat, dtype=np.float64)[:, :2].reshape(*arr.shape[:-1], 2)

    def to_world(self, pixels: Any, level: float) -> np.ndarray:
        """``(N, 2)`` pixels -> ``(N, 3)`` world points where their rays cross the plane ``world[axis] = level``.

        ``SessionError`` for a pixel whose ray runs along the plane or meets it behind the camera.
        """
        arr = np.atleast_2d(np.asarray(pixels, dtype=np.float64))
        inverse = np.linalg.inv(self._matrix)
        origin = inverse @ np.array([0.0, 0.0, 0.0, 1.0])  # the camera centre (depth 0)
        out = []
        for u, v in arr:
            ray = inverse @ np.array([u + 0.5, v + 0.5, 1.0, 0.0])  # world step per metre of depth
            if abs(ray[self.axis]) < 1e-9:
                raise SessionError(f"pixel ({u:g}, {v:g}) looks along the drag plane: it meets no point of it")
            depth = (float(level) - origin[self.axis]) / ray[self.axis]
            if depth <= 0:
                raise SessionError(f"pixel ({u:g}, {v:g}) meets the drag plane behind the camera")
            out.append(origin[:3] + depth * ray[:3])
        return np.asarray(out)

    def check_pixels(self, pixels: Any, name: str) -> np.ndarray:
        """As :meth:`PixelMap.check_pixels`."""
        return _check_pixels(pixels, name, self.width, self.height)


def rendered_frame(env: Any) -> np.ndarray:
    """``env.render()`` checked to be an ``(H, W, 3)`` image (``SessionError`` otherwise)."""
    image = env.render()
    if not isinstance(image, np.ndarray) or image.ndim != 3:
        raise SessionError("the env must render an (H, W, 3) image (render_mode='rgb_array')")
    return image


def make_view(kind: str, base: Any, image: np.ndarray) -> PixelMap | CameraView | PlaneView:
    """The view of a domain (``"pixels"``, ``"box"``, ``"camera"`` or ``"plane"``) for the unwrapped env ``base``."""
    if kind == "camera":
        return CameraView(base)
    if kind == "plane":
        return PlaneView(base)
    if kind == "box":
        model = getattr(base, "model", None)
        if model is None or not hasattr(model, "low"):
            raise SessionError(f"{type(base).__name__} has no workspace box (model.low / model.high) to draw")
        return PixelMap.from_box(model.low, model.high, image.shape[1], image.shape[0])
    if kind == "pixels":
        return PixelMap.from_env(base, image.shape[1], image.shape[0])
    raise SessionError(f"unknown view {kind!r}: 'pixels', 'box', 'camera' or 'plane'")


def _check_pixels(pixels: Any, name: str, width: int, height: int) -> np.ndarray:
    arr = real_array(pixels, name, owner="steer-ui")
    if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) == 0:
        raise SessionError(f"`{name}` must be a list of [u, v] pixel pairs, got shape {arr.shape}")
    if len(arr) > MAX_INPUT_POINTS:
        raise SessionError(f"`{name}` may hold at most {MAX_INPUT_POINTS} points, got {len(arr)}")
    inside = (arr[:, 0] >= 0) & (arr[:, 0] <= width) & (arr[:, 1] >= 0) & (arr[:, 1] <= height)
    if not inside.all():
        bad = arr[~inside][0]
        raise SessionError(
            f"`{name}` must lie inside the {width}x{height} image, got a point at ({bad[0]:g}, {bad[1]:g})"
        )
    return arr


def resample_by_arclength(points: Any, n: int) -> np.ndarray:
    """``n`` points evenly spaced along the polyline ``points`` ``(G, d)`` (a mouse path drawn at any speed).

    Repeated points are dropped first; a path of zero length gives ``SessionError``
    (a click is a point, not a sketch).

    >>> resample_by_arclength([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [1.0, 3.0]], 3).tolist()
    [[0.0, 0.0], [1.0, 1.0], [1.0, 3.0]]
    """
    pts = real_array(points, "points", owner="resample_by_arclength")
    n = integer(n, "`n`", low=2)
    if pts.ndim != 2 or len(pts) == 0:
        raise SessionError(f"`points` must have shape (G, d), got {pts.shape}")
    keep = np.concatenate([[True], np.any(np.diff(pts, axis=0) != 0.0, axis=1)])
    pts = pts[keep]
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    total = float(seg.sum())
    if len(pts) < 2 or total <= 0.0:
        raise SessionError("a sketch needs a path of non-zero length (for a single click, use a point)")
    at = np.concatenate([[0.0], np.cumsum(seg)])
    want = np.linspace(0.0, total, n)
    return np.stack([np.interp(want, at, pts[:, k]) for k in range(pts.shape[1])], axis=1)
