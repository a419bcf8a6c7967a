"""Where a push may take a robosuite arm: :class:`Workspace`, and the Panda's, derived from the robot and the table.

``perturb`` of the arm envs refuses a target outside the env's
``perturb_workspace`` (a ``ValueError`` naming the argument and stating the
bounds) instead of driving the arm into the table, into its own base or past
its reach. The arm envs' workspace (:func:`arm_workspace`) is the set of points

- within :data:`PANDA_REACH` m of the arm's shoulder (the second joint's axis;
  the Panda's grip site reaches about 0.94 m from it within the joint limits,
  the margin keeps targets off the fully stretched arm),
- at least :data:`PERTURB_CLEARANCE` above the top of the table (or of
  robosuite's bins' floors; the fingertips reach about 1 cm below the grip
  site, so a lower target pushes them into the table),
- at least :data:`NEAR` m from the vertical axis through the robot's base
  (the arm's own links stand there) and, below the base's top,
  :data:`MOUNT_RADIUS` m from it (the robot's mount).

The arm takes every point of it within its joint limits (a joint-limited IK
from the robot's home pose turned toward the point reaches all of it).

>>> ws = Workspace(np.zeros(3), np.ones(3))
>>> ws.contains([0.5, 0.5, 0.5]), ws.contains([0.5, 0.5, 1.5])
(True, False)
>>> ball = Workspace(-np.ones(3), np.ones(3), centre=np.zeros(3), reach=1.0)
>>> ball.contains([0.9, 0.0, 0.0]), ball.contains([0.9, 0.9, 0.0])
(True, False)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["MOUNT_RADIUS", "NEAR", "PANDA_REACH", "PERTURB_CLEARANCE", "Workspace", "arm_workspace"]

#: a push may not take the grip site lower than this above the table's top (m).
PERTURB_CLEARANCE = 0.005
#: a push may not take the grip site farther than this from the shoulder (m; the Panda reaches ~0.94 m).
PANDA_REACH = 0.9
#: a push may not take the grip site closer than this to the vertical axis through the robot's base (m) ...
NEAR = 0.1
#: ... nor, below the base's top, closer than this (m; the mount's pedestal).
MOUNT_RADIUS = 0.25


@dataclass(frozen=True)
class Workspace:
    """A box ``[low, high]`` of push targets; optionally only its points within ``reach`` of ``centre`` and at
    least ``near`` from the vertical axis through ``axis`` (x, y) (``mount[1]`` below height ``mount[0]``).

    Attributes:
        low, high: the box's corners (in the env's state coordinates).
        centre, reach: the ball's centre and radius (None: no ball).
        axis, near: the excluded vertical column's axis (x, y) and radius (None: no column).
        mount: the column's wider foot: its top height and radius (None: none).
        axes: the coordinates' names, for messages.
    """

    low: np.ndarray
    high: np.ndarray
    centre: np.ndarray | None = None
    reach: float | None = None
    axis: np.ndarray | None = None
    near: float | None = None
    mount: tuple[float, float] | None = None
    axes: tuple[str, ...] = field(default=("x", "y", "z"))

    def contains(self, point: Any) -> bool:
        """``point`` (finite reals, the box's size) lies in the box, in the ball and outside the column."""
        p = np.asarray(point, dtype=np.float64)
        if not np.all(np.isfinite(p)) or not np.all((p >= self.low) & (p <= self.high)):
            return False
        if self.centre is not None and self.reach is not None and float(np.linalg.norm(p - self.centre)) > self.reach:
            return False
        if self.axis is None or self.near is None:
            return True
        radius = self.near if self.mount is None or p[2] >= self.mount[0] else max(self.near, self.mount[1])
        return float(np.linalg.norm(p[:2] - self.axis)) >= radius

    def clip(self, point: Any) -> np.ndarray:
        """``point`` clipped to the box (the ball is not applied)."""
        return np.clip(np.asarray(point, dtype=np.float64), self.low, self.high)

    def describe(self) -> str:
        """The bounds in words, e.g. ``"x in [-0.310, 0.340], ... and within 0.900 of (...)"``."""
        out = ", ".join(
            f"{a} in [{lo:.3f}, {hi:.3f}]" for a, lo, hi in zip(self.axes, self.low, self.high, strict=True)
        )
        if self.centre is not None and self.reach is not None:
            out += f", within {self.reach:.3f} of the shoulder ({', '.join(f'{c:.3f}' for c in self.centre)})"
        if self.axis is not None and self.near is not None:
            out += (
                f", at least {self.near:.3f} from the base's vertical axis ({', '.join(f'{c:.3f}' for c in self.axis)})"
            )
            if self.mount is not None:
                out += f" ({self.mount[1]:.3f} below z {self.mount[0]:.3f})"
        return out

    def check(self, target: np.ndarray, name: str, owner: str) -> np.ndarray:
        """``target`` if it lies in the workspace, else a ``ValueError`` naming ``name`` and the bounds."""
        if not self.contains(target):
            raise ValueError(
                f"{owner}: `{name}` takes the arm to {np.round(target, 4).tolist()}, outside its workspace "
                f"({self.describe()}; m, world frame): a push there would go through the table, into the robot "
                "or past the arm's reach"
            )
        return target


def arm_workspace(base: np.ndarray, shoulder: np.ndarray, surface_z: float) -> Workspace:
    """The Panda's push workspace (see the module) from its base and shoulder positions and the table top's height.

    >>> ws = arm_workspace(np.array([-0.56, 0.0, 0.912]), np.array([-0.56, 0.0, 1.245]), 0.8)
    >>> ws.contains([-0.1, 0.0, 1.0]), ws.contains([-0.1, 0.0, 0.79]), ws.contains([0.45, 0.0, 1.0])
    (True, False, False)
    >>> ws.contains([-0.5, 0.0, 1.0]), ws.contains([-0.4, 0.0, 1.0]), ws.contains([-0.4, 0.0, 0.85])  # by the robot
    (False, True, False)
    """
    base = np.asarray(base, dtype=np.float64)
    shoulder = np.asarray(shoulder, dtype=np.float64)
    low = np.array([shoulder[0] - PANDA_REACH, shoulder[1] - PANDA_REACH, surface_z + PERTURB_CLEARANCE])
    high = shoulder + PANDA_REACH
    return Workspace(
        low,
        high,
        centre=shoulder,
        reach=PANDA_REACH,
        axis=base[:2].copy(),
        near=NEAR,
        mount=(float(base[2]), MOUNT_RADIUS),
    )
