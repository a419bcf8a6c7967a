"""What the skill-plan trackers of BlockStack and Kitchen share: checking a plan, finding a waypoint.

A plan is ``(H, d)`` waypoints (the end-effector position, the domain's
extras and last the gripper command); :func:`check_plan` refuses anything
else, :func:`first_index` finds the first waypoint where a condition holds
(e.g. where the gripper closes).

>>> first_index(check_plan([[0.0, 0.0, 0.3, -1.0], [0.0, 0.0, 0.2, 1.0]], 4, 10, "demo")[:, 3] > 0)
1
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.core.validation import real_array

__all__ = ["check_plan", "first_index"]


def check_plan(plan: Any, width: int, max_waypoints: int, owner: str) -> np.ndarray:
    """``plan`` as a finite float64 ``(H, width)`` array with ``1 <= H <= max_waypoints``.

    ``TypeError`` / ``ValueError`` naming ``owner`` and ``plan`` otherwise.
    """
    arr = real_array(plan, "plan", ndim=2, max_size=max_waypoints * width, owner=owner)
    if arr.shape[0] < 1 or arr.shape[1] != width:
        raise ValueError(f"{owner}: `plan` must have shape (H, {width}) with H >= 1, got {arr.shape}")
    return arr


def first_index(mask: np.ndarray) -> int | None:
    """The index of the first true entry of ``mask``, or None."""
    hits = np.flatnonzero(mask)
    return int(hits[0]) if hits.size else None
