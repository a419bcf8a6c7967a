"""What the robot steering studies (thesis Tables 2.2 and 2.3) share: held-out scenes and the outcome quadrants.

A study resets its env at evaluation scenes ``SCENE_SEED_OFFSET + seed``,
never at a scene of the skill data (recorded from reset seeds ``0..N-1``).
Each interaction is *aligned* or not (the plan does what the user meant) and a
*success* or not (the skill happened in the world); :func:`quadrant_shares`
turns a trial's interactions into the thesis's TA, CS and AS/AF/MS/MF shares.

>>> shares = quadrant_shares([True, True, False, False], [True, False, True, True])
>>> shares["TA"], shares["CS"], shares["AS"], shares["MF"]
(0.5, 0.75, 0.25, 0.0)
>>> quadrant_shares([], [])["TA"] is None  # no interaction: nothing to share
True
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["QUADRANTS", "SCENE_SEED_OFFSET", "quadrant_shares"]

#: evaluation scenes are reset seeds SCENE_SEED_OFFSET + seed (the skill data uses seeds 0..N-1).
SCENE_SEED_OFFSET = 100_000
#: the shares :func:`quadrant_shares` returns, in order.
QUADRANTS = ("TA", "CS", "AS", "AF", "MS", "MF")


def quadrant_shares(
    aligned: Sequence[bool] | np.ndarray, success: Sequence[bool] | np.ndarray
) -> dict[str, float | None]:
    """Shares of the interactions: aligned (TA), successful (CS), and the four aligned x success quadrants.

    ``AS`` aligned success, ``AF`` aligned failure, ``MS`` misaligned success,
    ``MF`` misaligned failure; every share ``None`` without interactions.
    """
    a = np.asarray(aligned, dtype=bool)
    s = np.asarray(success, dtype=bool)
    if a.shape != s.shape or a.ndim != 1:
        raise ValueError(f"quadrant_shares: `aligned` and `success` must be two flags per interaction, got {a.shape}")
    masks = (a, s, a & s, a & ~s, ~a & s, ~a & ~s)
    return {name: float(mask.mean()) if len(a) else None for name, mask in zip(QUADRANTS, masks, strict=True)}
