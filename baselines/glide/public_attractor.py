"""The attractor of the public GLiDE fork's robosuite evaluation: a small additive pull toward the grasp.

In the first mode (before the grasp) the fork adds ``coef`` times the negative
gradient, with respect to the end effector, of the potential
``exp(|(object - eef) - g|)`` to the position part of the policy's action: a
pull of size ``coef * exp(d)`` toward the grasp point ``object - g``, ``d``
the distance to it. ``g`` is the object-minus-eef offset at the grasp, its
height scaled by 1.5 (the fork places it "a bit higher"); here it is the mean
offset at the demos' exits from the first mode (the fork's is a constant read
off its demos). The pull acts only while the end effector is at least
``min_distance`` (0.1 m) from the object, and while it acts the rotation part
of the action is zero (the fork's ``--use-upright-gripper``). In every other
mode the action is the policy's. Each component stays in [-1, 1] (robosuite's
controller clips its input there anyway).

The thesis's attractor (:class:`~steer_envs.baselines.glide.arm_policies.ModeAttractor`)
is another design: one per mode, blended with the policy's action beyond a
quantile of the demos' distances.

>>> import numpy as np
>>> from steer_envs.data import robosuite_replays as rr
>>> rel = rr.feature_columns("lift", ["block_to_robot0_eef_pos"])
>>> f = np.zeros((3, sum(size for _, size in rr.FEATURES["lift"])))
>>> f[:, rel] = [[0.0, 0.0, -0.3], [0.0, 0.0, -0.1], [0.0, 0.0, -0.02]]  # the eef comes down onto the block
>>> pull = PublicCodeAttractor.from_demos("lift", [f], [np.array([0, 0, 1])])
>>> pull.offset.round(3).tolist()  # the grasp offset, its height scaled by 1.5
[0.0, 0.0, -0.03]
>>> far = f[0]  # 0.3 m above the block: pulled down, rotation zeroed
>>> pull.apply(np.full(7, 0.5), far).round(3).tolist()
[0.5, 0.5, 0.369, 0.0, 0.0, 0.0, 0.5]
>>> pull.apply(np.full(7, 0.5), f[2]).tolist()  # within 0.1 m of the block: the policy's action
[0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from steer_envs.baselines.glide.arm_plan import OBJECT_MOTION
from steer_envs.core.validation import one_of, real_scalar
from steer_envs.data import robosuite_replays as rr
from steer_envs.envs.robosuite.tasks import TASK_NAMES

__all__ = ["PUBLIC_COEF", "PUBLIC_MIN_DISTANCE", "PUBLIC_Z_SCALE", "PublicCodeAttractor"]

#: the fork's gain of the first mode's pull, the eef-object distance below which it stops (m), and the factor
#: on the grasp offset's height
PUBLIC_COEF = 0.1
PUBLIC_MIN_DISTANCE = 0.1
PUBLIC_Z_SCALE = 1.5


@dataclass(frozen=True)
class PublicCodeAttractor:
    """The fork's first-mode pull (see the module).

    Attributes:
        columns: the 3 columns of the object-minus-eef feature in the task's feature vector.
        offset: ``g``, the grasp's object-minus-eef offset (height already scaled).
        coef: the pull's gain; min_distance: it acts while ``|object - eef| >= min_distance`` (m).
    """

    columns: np.ndarray
    offset: np.ndarray
    coef: float = PUBLIC_COEF
    min_distance: float = PUBLIC_MIN_DISTANCE

    @classmethod
    def from_demos(
        cls,
        task: str,
        features: Sequence[np.ndarray],
        modes: Sequence[np.ndarray],
        *,
        z_scale: float = PUBLIC_Z_SCALE,
        coef: float = PUBLIC_COEF,
        min_distance: float = PUBLIC_MIN_DISTANCE,
    ) -> PublicCodeAttractor:
        """The pull of ``task`` from labelled demos (feature rows ``(T_i, D)``, modes ``(T_i,)``).

        ``g``: the mean object-minus-eef offset of the first state after each exit
        from mode 0 (of the demos' last states where no demo leaves it), its height times ``z_scale``.
        """
        owner = "PublicCodeAttractor"
        task = one_of(task, "task", TASK_NAMES, owner=owner)
        z_scale = real_scalar(z_scale, "z_scale", low=0.0, owner=owner)
        coef = real_scalar(coef, "coef", low=0.0, owner=owner)
        min_distance = real_scalar(min_distance, "min_distance", low=0.0, owner=owner)
        if len(features) == 0 or len(features) != len(modes):
            raise ValueError(f"{owner}: features and modes must be non-empty and of equal length")
        cols = rr.feature_columns(task, [OBJECT_MOTION[task]])
        exits, last = [], []
        for f, m in zip(features, modes, strict=True):
            f, m = np.asarray(f, dtype=np.float64), np.asarray(m, dtype=np.int64)
            if f.ndim != 2 or m.shape != (len(f),) or len(f) == 0:
                raise ValueError(
                    f"{owner}: each demo needs features (T>=1, D) and modes (T,), got {f.shape}, {m.shape}"
                )
            exits.append(f[1:][(m[:-1] == 0) & (m[1:] != 0)][:, cols])
            last.append(f[-1, cols])
        at = np.concatenate(exits)
        offset = (at if len(at) else np.stack(last)).mean(0) * np.array([1.0, 1.0, z_scale])
        return cls(cols, offset, coef, min_distance)

    def pull(self, features: np.ndarray) -> np.ndarray | None:
        """The position pull ``(3,)`` for a feature vector ``(D,)``; ``None`` within ``min_distance`` of the object."""
        rel = np.asarray(features, dtype=np.float64)[self.columns]
        if float(np.linalg.norm(rel)) < self.min_distance:
            return None
        to_grasp = rel - self.offset  # the eef's way to the grasp point object - g
        d = float(np.linalg.norm(to_grasp))
        if d == 0.0:
            return np.zeros(3)
        return self.coef * math.exp(d) * to_grasp / d

    def apply(self, action: np.ndarray, features: np.ndarray) -> np.ndarray:
        """``action`` ``(7,)`` with the pull added to its position part and its rotation zeroed, where it acts."""
        out = np.array(action, dtype=np.float64, copy=True)
        pull = self.pull(features)
        if pull is not None:
            out[:3] += pull
            out[3:6] = 0.0
        return np.clip(out, -1.0, 1.0)
