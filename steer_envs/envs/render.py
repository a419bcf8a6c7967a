"""A tiny numpy rasterizer for the 2D kinematic envs.

Drawing with numpy keeps ``render()`` fast and free of a GUI toolkit. The
canvas maps a world rectangle to an ``H x W`` RGB image with ``y`` pointing up.

>>> import numpy as np
>>> canvas = Canvas(np.array([-1.0, -1.0]), np.array([1.0, 1.0]), width=32, height=32)
>>> canvas.disc(np.zeros(2), 4, (220, 30, 30))
>>> canvas.image.shape, canvas.image[16, 16].tolist()
((32, 32, 3), [220, 30, 30])
"""

from __future__ import annotations

import itertools

import numpy as np

#: A palette for region labels; index 0 is "free space" (white).
REGION_PALETTE: np.ndarray = np.array(
    [
        [255, 255, 255],  # white / free space
        [255, 221, 87],  # yellow
        [255, 182, 193],  # pink
        [144, 210, 144],  # green
        [120, 120, 120],  # dark
        [160, 196, 255],  # blue
        [255, 170, 110],  # orange
        [200, 160, 230],  # purple
        [150, 230, 220],  # teal
        [230, 140, 140],  # red
    ],
    dtype=np.uint8,
)


class Canvas:
    """An RGB image of the world box ``[lo, hi]`` (``lo``, ``hi`` are xy corners)."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, width: int = 256, height: int = 256) -> None:
        self.lo = np.asarray(lo, dtype=np.float64)
        self.hi = np.asarray(hi, dtype=np.float64)
        self.width, self.height = int(width), int(height)
        self.image = np.full((self.height, self.width, 3), 255, dtype=np.uint8)

    def pixel_centers(self) -> np.ndarray:
        """World coordinates of every pixel centre, shape ``(H * W, 2)``, row-major."""
        xs = self.lo[0] + (np.arange(self.width) + 0.5) / self.width * (self.hi[0] - self.lo[0])
        ys = self.hi[1] - (np.arange(self.height) + 0.5) / self.height * (self.hi[1] - self.lo[1])
        gx, gy = np.meshgrid(xs, ys)
        return np.stack([gx.ravel(), gy.ravel()], axis=1)

    def to_pixel(self, points: np.ndarray) -> np.ndarray:
        """World xy ``(N, 2)`` -> integer pixel (col, row) ``(N, 2)``."""
        p = np.atleast_2d(np.asarray(points, dtype=np.float64))
        col = (p[:, 0] - self.lo[0]) / (self.hi[0] - self.lo[0]) * self.width
        row = (self.hi[1] - p[:, 1]) / (self.hi[1] - self.lo[1]) * self.height
        return np.stack([col, row], axis=1).astype(np.int64)

    def fill_labels(self, labels: np.ndarray, palette: np.ndarray = REGION_PALETTE) -> None:
        """Colour every pixel by its region label (labels in pixel_centers order)."""
        labels = np.asarray(labels, dtype=np.int64).reshape(self.height, self.width)
        self.image[:] = palette[np.mod(labels, len(palette))]

    def _plot(self, cols: np.ndarray, rows: np.ndarray, color: tuple[int, int, int]) -> None:
        keep = (cols >= 0) & (cols < self.width) & (rows >= 0) & (rows < self.height)
        self.image[rows[keep], cols[keep]] = color

    def disc(self, center: np.ndarray, radius_px: int, color: tuple[int, int, int]) -> None:
        c = self.to_pixel(center)[0]
        r = int(radius_px)
        dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
        inside = dx**2 + dy**2 <= r * r
        self._plot(c[0] + dx[inside], c[1] + dy[inside], color)

    def polyline(self, points: np.ndarray, color: tuple[int, int, int], thickness: int = 1) -> None:
        """Draw a polyline through world points ``(N, 2)``."""
        pix = self.to_pixel(points).astype(np.float64)
        if len(pix) == 1:
            pix = np.vstack([pix, pix])
        for a, b in itertools.pairwise(pix):
            n = int(max(abs(b - a).max(), 1)) + 1
            t = np.linspace(0.0, 1.0, n)[:, None]
            seg = np.rint(a + t * (b - a)).astype(np.int64)
            for ox in range(-(thickness // 2), thickness - thickness // 2):
                for oy in range(-(thickness // 2), thickness - thickness // 2):
                    self._plot(seg[:, 0] + ox, seg[:, 1] + oy, color)
