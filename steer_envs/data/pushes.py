"""Random push schedules: the perturbations the TLI studies apply to a running episode (thesis ch. 3).

A push is a displacement of the state applied through ``env.unwrapped.perturb``.
The studies schedule them in four ways:

* :func:`perturbation_schedule` -- at distinct random steps, a uniform
  direction on the sphere and a uniform length (SoupScoop, ``(step, delta)`` pairs);
* :func:`push_schedule` -- the same as a mapping ``step -> delta`` with the
  direction drawn as an angle (Cooking);
* :func:`tile_push_schedule` and :func:`dark_push_target` -- a push fires after
  a random dwell on its trigger tile and moves the end effector into the dark
  region beside the row (ColorTracing);
* :func:`push_plan` -- a push fires after a random dwell in its trigger mode and
  moves ``(y, z, pitch)`` by a scaled random direction (ArmScoop);
* :func:`track_pushes` -- a push fires once the object passes a random point of
  the inspection track (InspectionLine).

>>> import numpy as np
>>> pushes = perturbation_schedule(np.random.default_rng(0), 3, 600, 16.0)
>>> [step for step, _ in pushes] == sorted(step for step, _ in pushes)
True
"""

from __future__ import annotations

import numpy as np

from steer_envs.core.validation import integer, real_scalar
from steer_envs.envs.color_tracing import TILES

__all__ = [
    "ARM_PUSH_MODES",
    "ARM_PUSH_SCALE",
    "dark_push_target",
    "perturbation_schedule",
    "push_plan",
    "push_schedule",
    "tile_push_schedule",
    "track_pushes",
]

#: a dark push's distance from the row's axis (ColorTracing) and its horizontal shift
DARK_PUSH_Y = (2.5, 6.0)
DARK_PUSH_X = 1.5
#: an arm push's scale per axis (m, m, rad): a uniform direction times a length in [0.5, 1] times this
ARM_PUSH_SCALE = np.array([0.06, 0.04, 1.0])
#: modes the first arm pushes wait for: scooping, then carrying; further pushes pick any of a, b, c
ARM_PUSH_MODES = ("b", "c")


def perturbation_schedule(
    rng: np.random.Generator, n: int, push_window: int, magnitude: float, dim: int = 2
) -> list[tuple[int, np.ndarray]]:
    """``n`` pushes ``(step, displacement)`` at distinct steps in ``[1, push_window]``, sorted by step.

    Directions are uniform on the circle (sphere), magnitudes uniform in ``[0, magnitude]``.

    >>> pushes = perturbation_schedule(np.random.default_rng(0), 3, 600, 16.0)
    >>> all(np.linalg.norm(d) <= 16.0 for _, d in pushes)
    True
    """
    if not isinstance(n, int) or n < 0:
        raise ValueError(f"n must be an int >= 0, got {n!r}")
    if not isinstance(push_window, int) or push_window < max(1, n):
        raise ValueError(f"push_window must be an int >= max(1, n) = {max(1, n)}, got {push_window!r}")
    magnitude = real_scalar(magnitude, "magnitude", low=0.0, owner="perturbation_schedule")
    dim = integer(dim, "dim", low=1, owner="perturbation_schedule")
    steps = np.sort(rng.choice(np.arange(1, push_window + 1), size=n, replace=False))
    direction = rng.normal(size=(n, dim))
    direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-12)
    size = rng.uniform(0.0, magnitude, size=n)
    return [(int(s), d * m) for s, d, m in zip(steps, direction, size, strict=True)]


def push_schedule(rng: np.random.Generator, n: int, window: int, magnitude: float) -> dict[int, np.ndarray]:
    """``n`` pushes ``step -> displacement`` at distinct steps in ``[1, window]`` (uniform direction and length).

    >>> sorted(push_schedule(np.random.default_rng(0), 2, 10, 1.0)) == sorted(set(push_schedule(
    ...     np.random.default_rng(0), 2, 10, 1.0)))
    True
    """
    n = integer(n, "n", low=0, owner="push_schedule")
    window = integer(window, "window", low=max(1, n), owner="push_schedule")
    magnitude = real_scalar(magnitude, "magnitude", low=0.0, owner="push_schedule")
    steps = rng.choice(np.arange(1, window + 1), size=n, replace=False)
    angle = rng.uniform(0.0, 2.0 * np.pi, size=n)
    size = rng.uniform(0.0, magnitude, size=n)
    return {int(s): m * np.array([np.cos(a), np.sin(a)]) for s, a, m in zip(steps, angle, size, strict=True)}


def tile_push_schedule(rng: np.random.Generator, n_pushes: int, max_dwell: int) -> list[tuple[str, int]]:
    """``n_pushes`` ``(trigger tile, dwell steps)``: ColorTracing tiles before red, distinct while there are enough.

    >>> [tile for tile, _ in tile_push_schedule(np.random.default_rng(0), 2, 15)] != []
    True
    """
    n = integer(n_pushes, "n_pushes", low=0, owner="tile_push_schedule")
    max_dwell = integer(max_dwell, "max_dwell", low=1, owner="tile_push_schedule")
    tiles = list(TILES[:-1])
    order = [str(t) for t in rng.permutation(tiles)] * (n // len(tiles) + 1)
    return [(order[k], int(rng.integers(1, max_dwell + 1))) for k in range(n)]


def dark_push_target(rng: np.random.Generator, x: np.ndarray) -> np.ndarray:
    """Where a ColorTracing push moves the end effector at ``x``: a random side of the row, into the dark region.

    ``|y|`` uniform in :data:`DARK_PUSH_Y`, ``x`` shifted by up to :data:`DARK_PUSH_X` (kept in ``[-7.5, 7.5]``).
    """
    side = 1.0 if rng.random() < 0.5 else -1.0
    return np.array(
        [np.clip(x[0] + rng.uniform(-DARK_PUSH_X, DARK_PUSH_X), -7.5, 7.5), side * rng.uniform(*DARK_PUSH_Y)]
    )


def push_plan(rng: np.random.Generator, n_pushes: int, max_dwell: int) -> list[tuple[str, int, np.ndarray]]:
    """``n_pushes`` ArmScoop pushes ``(trigger mode, dwell steps, delta (y, z, pitch))``.

    The first waits for scooping, the second for carrying (:data:`ARM_PUSH_MODES`), any further one for a
    random mode; each fires after ``1..max_dwell`` steps in its mode and moves the state by a uniform
    direction times a length uniform in ``[0.5, 1]`` times :data:`ARM_PUSH_SCALE`.

    >>> [mode for mode, _, _ in push_plan(np.random.default_rng(0), 2, 20)]
    ['b', 'c']
    """
    n = integer(n_pushes, "n_pushes", low=0, owner="push_plan")
    max_dwell = integer(max_dwell, "max_dwell", low=1, owner="push_plan")
    plan = []
    for k in range(n):
        mode = ARM_PUSH_MODES[k] if k < len(ARM_PUSH_MODES) else str(rng.choice(["a", "b", "c"]))
        direction = rng.normal(size=3)
        direction /= max(float(np.linalg.norm(direction)), 1e-12)
        delta = direction * rng.uniform(0.5, 1.0) * ARM_PUSH_SCALE
        plan.append((mode, int(rng.integers(1, max_dwell + 1)), delta))
    return plan


def track_pushes(
    rng: np.random.Generator, n_pushes: int, min_push: float, max_push: float
) -> list[tuple[float, np.ndarray]]:
    """``n_pushes`` InspectionLine pushes ``(threshold, delta)``, sorted by threshold.

    The ``k``-th fires once the object is on the track at ``x >= threshold`` (thresholds uniform in
    ``[-3, 2.5]``); the push has a uniform direction and a length uniform in ``[min_push, max_push]``.

    >>> [round(t, 2) <= 2.5 for t, _ in track_pushes(np.random.default_rng(0), 2, 4.0, 10.0)]
    [True, True]
    """
    thresholds = sorted(rng.uniform(-3.0, 2.5, size=n_pushes).tolist())
    return [
        (t, m * np.array([np.cos(a), np.sin(a)]))
        for t, a, m in zip(
            thresholds, rng.uniform(0, 2 * np.pi, n_pushes), rng.uniform(min_push, max_push, n_pushes), strict=True
        )
    ]
