"""Perturbations of a demonstration: pure functions of a reference path and a random generator.

GLiDE's counterfactual replays (:mod:`steer_envs.data.counterfactual`) follow
paths these functions make from demos (a :class:`PerturbedReference` each): :func:`segment_perturbation` (the
thesis's detour through a random point), :func:`kernel_perturbation` (the public
code's Gaussian pull of a window) and :func:`gripper_toggle` (a window of the
gripper command negated or forced).

>>> import numpy as np
>>> path = np.linspace([0.0, 0.0], [1.0, 1.0], 5)
>>> waypoints, (x, y), z = segment_perturbation(path, np.random.default_rng(0), [-1, -1], [1, 1])
>>> bool((waypoints[0] == path[0]).all() and (waypoints[-1] == path[-1]).all())
True
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from steer_envs.core.validation import BoundExceeded, integer, real_array, real_scalar

__all__ = [
    "MAX_WAYPOINTS",
    "PERTURBATION_KINDS",
    "REFERENCE_KINDS",
    "PerturbedReference",
    "check_path",
    "gripper_toggle",
    "kernel_perturbation",
    "segment_perturbation",
]

PerturbationKind = Literal["segment", "kernel", "gripper"]
PERTURBATION_KINDS: tuple[str, ...] = ("segment", "kernel", "gripper")
#: the kinds a :class:`PerturbedReference` may have (``"demo"``: the unperturbed demonstration).
REFERENCE_KINDS: tuple[str, ...] = ("demo", *PERTURBATION_KINDS)
#: the most waypoints one reference may hold (a guard against arrays that can never be replayed).
MAX_WAYPOINTS = 1_000_000


def check_path(path: Any, name: str = "path") -> np.ndarray:
    """A reference path: finite reals of shape ``(T >= 2, d >= 1)``."""
    arr = real_array(path, name, ndim=2)
    if len(arr) < 2 or arr.shape[1] < 1:
        raise ValueError(f"{name} must have shape (T >= 2, d >= 1), got {arr.shape}")
    return arr


def _check_bounds(low: Any, high: Any, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """``low`` and ``high`` broadcast to ``(dim,)``, finite, with ``low < high``."""
    lo_in, hi_in = real_array(low, "low", finite=False), real_array(high, "high", finite=False)
    try:
        lo, hi = np.broadcast_to(lo_in, (dim,)), np.broadcast_to(hi_in, (dim,))
    except ValueError:
        raise ValueError(
            f"low/high must be scalars or ({dim},) vectors, got shapes {lo_in.shape}, {hi_in.shape}"
        ) from None
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo < hi)):
        raise ValueError(f"low/high must be finite with low < high, got low={lo.tolist()}, high={hi.tolist()}")
    return lo, hi


def segment_perturbation(
    path: np.ndarray, rng: np.random.Generator, low: np.ndarray, high: np.ndarray
) -> tuple[np.ndarray, tuple[int, int], np.ndarray]:
    """Thesis perturbation: replace the segment ``XY`` of ``path`` by ``XZ`` and ``ZY``.

    X and Y are two distinct points of the path (so the first and last states
    are kept), Z is uniform in the box ``[low, high]``. Returns the new
    waypoints (straight lines between consecutive waypoints are implied), the
    indices ``(x, y)`` and ``Z``.
    """
    path = check_path(path)
    lo, hi = _check_bounds(low, high, path.shape[1])
    x, y = sorted(int(i) for i in rng.choice(len(path), size=2, replace=False))
    z = rng.uniform(lo, hi)
    waypoints = np.concatenate([path[: x + 1], z[None, :], path[y:]])
    return waypoints, (x, y), z


#: draws of :func:`kernel_perturbation`'s rejection sampling of its window before it gives up.
_MAX_WINDOW_DRAWS = 1_000_000


def kernel_perturbation(
    path: np.ndarray,
    rng: np.random.Generator,
    low: np.ndarray,
    high: np.ndarray,
    *,
    sharpness: float = 5.0,
    min_window: int = 2,
) -> tuple[np.ndarray, tuple[int, int], np.ndarray]:
    """Public-code perturbation: pull a window ``[s, e]`` of ``path`` toward a random ``Z``.

    Each point ``p_t`` with ``s <= t <= e`` moves by ``(Z - p_t) w_t`` with
    ``w_t = exp(-sharpness (t - c)^2 / (s - c)^2)``, ``c = (s + e) / 2``. The
    window never contains the first or last state, so both are kept.
    Returns the new waypoints, ``(s, e)`` and ``Z``.
    """
    path = check_path(path)
    lo, hi = _check_bounds(low, high, path.shape[1])
    real_scalar(sharpness, "sharpness", low=0.0, low_inclusive=False)
    min_window = integer(min_window, "min_window", low=2)
    inner = len(path) - 2  # indices 1 .. T-2
    if inner <= min_window:
        raise ValueError(f"path of length {len(path)} is too short for a window of >= {min_window} steps")
    # rejection sampling of the window: each draw succeeds with probability >= 2 / (inner (inner - 1)) > 0
    for _ in range(_MAX_WINDOW_DRAWS):
        s, e = sorted(int(i) for i in rng.choice(inner, size=2, replace=False) + 1)
        if e - s >= min_window:
            break
    else:
        raise BoundExceeded(
            f"kernel_perturbation: no window of >= {min_window} steps drawn within {_MAX_WINDOW_DRAWS} draws "
            f"(path of length {len(path)})"
        )
    z = rng.uniform(lo, hi)
    t = np.arange(s, e + 1, dtype=np.float64)
    c = 0.5 * (s + e)
    w = np.exp(-sharpness * (t - c) ** 2 / (s - c) ** 2)
    out = path.copy()
    out[s : e + 1] += (z[None, :] - out[s : e + 1]) * w[:, None]
    return out, (s, e), z


def gripper_toggle(
    gripper: np.ndarray,
    rng: np.random.Generator,
    *,
    min_steps: int = 5,
    max_steps: int = 20,
    force: float | None = None,
) -> tuple[np.ndarray, tuple[int, int]]:
    """Toggle (negate) or ``force`` the gripper command for ``min_steps..max_steps`` steps.

    ``gripper`` is a ``(T,)`` command sequence with open/closed encoded as
    ``-1``/``+1`` (robosuite). Returns the new sequence and the window
    ``(start, end)`` (inclusive).
    """
    g = real_array(gripper, "gripper", ndim=1)
    if len(g) < 2:
        raise ValueError(f"gripper must have shape (T >= 2,), got {g.shape}")
    min_steps, max_steps = integer(min_steps, "min_steps"), integer(max_steps, "max_steps")
    if not 1 <= min_steps <= max_steps:
        raise ValueError(f"need 1 <= min_steps <= max_steps, got {min_steps}, {max_steps}")
    if force is not None:
        force = real_scalar(force, "force")
    length = int(min(len(g), rng.integers(min_steps, max_steps + 1)))
    start = int(rng.integers(0, len(g) - length + 1))
    out = g.copy()
    out[start : start + length] = -out[start : start + length] if force is None else float(force)
    return out, (start, start + length - 1)


@dataclass(frozen=True)
class PerturbedReference:
    """A perturbed demo: the waypoints the replay controller follows.

    Attributes:
        waypoints: ``(W, d)`` states; the controller moves in straight lines between them.
        kind: ``"demo"`` (unperturbed), ``"segment"``, ``"kernel"`` or ``"gripper"``.
        source: index of the demonstration it came from.
        window: ``(X, Y)`` / ``(s, e)`` / gripper window, indices into the source demo (``(-1, -1)`` for demos).
        target: Z (``(d,)``), NaN for demos and gripper toggles.
        gripper: optional ``(W,)`` gripper commands.
    """

    waypoints: np.ndarray
    kind: str
    source: int
    window: tuple[int, int]
    target: np.ndarray
    gripper: np.ndarray | None = None

    def __post_init__(self) -> None:
        owner = "PerturbedReference"
        wps = real_array(self.waypoints, "waypoints", ndim=2, owner=owner)
        if not (1 <= len(wps) <= MAX_WAYPOINTS and wps.shape[1] >= 1):
            raise ValueError(
                f"{owner}: waypoints must have shape (W, d) with 1 <= W <= {MAX_WAYPOINTS}, d >= 1, got {wps.shape}"
            )
        if not isinstance(self.kind, str) or self.kind not in REFERENCE_KINDS:
            raise ValueError(f"{owner}: kind must be one of {list(REFERENCE_KINDS)}, got {self.kind!r}")
        source = integer(self.source, "source", owner=owner)
        if not isinstance(self.window, (tuple, list)) or len(self.window) != 2:
            raise TypeError(f"{owner}: window must be a pair of ints, got {self.window!r}")
        window = (integer(self.window[0], "window[0]", owner=owner), integer(self.window[1], "window[1]", owner=owner))
        target = real_array(self.target, "target", shape=(wps.shape[1],), finite=False, owner=owner)
        gripper = None
        if self.gripper is not None:
            gripper = real_array(self.gripper, "gripper", shape=(len(wps),), owner=owner)
        object.__setattr__(self, "waypoints", wps)
        object.__setattr__(self, "source", source)
        object.__setattr__(self, "window", window)
        object.__setattr__(self, "target", target)
        object.__setattr__(self, "gripper", gripper)
