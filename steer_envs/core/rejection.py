"""Rejection sampling of ``n`` points: draw candidates for the places still open, keep those accepted, repeat.

Each round draws exactly as many candidates as places are still open (so the
random stream depends only on what was accepted before) and stops once every
place is filled; after ``max_rounds`` rounds with places still open it raises
:class:`~steer_envs.core.validation.BoundExceeded` with the caller's message.

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> points = rejection_sample(lambda m: rng.uniform(-1, 1, (m, 2)), lambda p: p[:, 0] > 0, 5, 2, 100, str)
>>> points.shape, bool(np.all(points[:, 0] > 0))
((5, 2), True)
>>> rejection_sample(lambda m: np.zeros((m, 2)), lambda p: p[:, 0] > 0, 5, 2, 3, lambda k: f"{k} left")
Traceback (most recent call last):
steer_envs.core.validation.BoundExceeded: 5 left
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from steer_envs.core.validation import BoundExceeded

__all__ = ["rejection_sample"]


def rejection_sample(
    draw: Callable[[int], np.ndarray],
    accept: Callable[[np.ndarray], np.ndarray],
    n: int,
    dim: int,
    max_rounds: int,
    failure: Callable[[int], str],
) -> np.ndarray:
    """``(n, dim)`` points each accepted by ``accept``; :class:`BoundExceeded` if ``max_rounds`` leave some open.

    ``draw(m)`` gives ``(m, dim)`` candidates, ``accept(candidates)`` a bool
    mask; open places keep their order, so the first candidate accepted for a
    place fills it. ``failure(open_places)`` is the error's message.
    """
    out = np.empty((n, dim))
    todo = np.arange(n)
    for _ in range(max_rounds):
        if len(todo) == 0:
            return out
        candidates = draw(len(todo))
        ok = accept(candidates)
        out[todo[ok]] = candidates[ok]
        todo = todo[~ok]
    if len(todo) == 0:
        return out
    raise BoundExceeded(failure(len(todo)))
