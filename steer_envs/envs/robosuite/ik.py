"""Inverse kinematics for the arm envs' pushes: damped least squares on the arm joints, within their limits.

``perturb`` sets the arm's joints so the end effector is exactly on the
pushed target. :class:`ArmIK` solves for those joints kinematically (no sim
step) and keeps every joint inside the model's range (``jnt_range``): a joint
set past its limit meets MuJoCo's limit constraint at full stiffness on the
next step, which can blow the simulation up. A target the arm cannot take
within its limits is reported (the residual), not approximated silently.

Two solves share the damped least-squares step: :meth:`ArmIK.solve` moves an
``MjData`` in place from its current joints (the push itself), and
:meth:`ArmIK.plan` tries several start configurations on a scratch copy (the
check before a push, which leaves the simulation untouched).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

__all__ = ["IK_TOLERANCE", "ArmIK", "Residual"]

#: a solve has reached its target when the residual is below this (m; rad for orientation parts).
IK_TOLERANCE = 1e-7
_DAMPING = 1e-8

#: ``residual(data) -> (error, jacobian)``: the target's error at ``data``'s joints (``k``,) and its Jacobian
#: over the arm's joints (``k x n``); ``data``'s kinematics are current when it is called.
Residual = Callable[[Any], tuple[np.ndarray, np.ndarray]]


class ArmIK:
    """Damped least-squares IK over the arm joints ``qpos`` (indices into ``qpos``) of ``model``, within their limits.

    Args:
        model: the ``MjModel``.
        joints: the arm's joint ids (their ranges bound the solution where ``jnt_limited``).
        qpos: the joints' ``qpos`` indices.
    """

    def __init__(self, model: Any, joints: Sequence[int] | np.ndarray, qpos: np.ndarray) -> None:
        import mujoco

        self.model = model
        self.qpos = np.asarray(qpos, dtype=int)
        ids = np.asarray(joints, dtype=int)
        limited = np.asarray(model.jnt_limited[ids], dtype=bool)
        ranges = np.asarray(model.jnt_range[ids], dtype=np.float64)
        #: the joints' lower and upper bounds (rad; +-inf where a joint is unlimited)
        self.low = np.where(limited, ranges[:, 0], -np.inf)
        self.high = np.where(limited, ranges[:, 1], np.inf)
        self._scratch = mujoco.MjData(model)

    def within_limits(self, q: np.ndarray) -> bool:
        """``q`` (the arm joints) lies inside the joint ranges."""
        return bool(np.all((q >= self.low) & (q <= self.high)))

    def solve(self, data: Any, residual: Residual, *, iters: int, tol: float = 1e-9) -> float:
        """Move ``data``'s arm joints (in place, ``mj_forward`` after each update) toward ``residual``'s zero.

        Stops below ``tol`` or after ``iters`` updates; each update is the damped
        least-squares step clipped to the joint ranges. Returns the final residual norm.
        """
        import mujoco

        for _ in range(iters):
            err, jac = residual(data)
            if np.linalg.norm(err) < tol:
                break
            step = jac.T @ np.linalg.solve(jac @ jac.T + _DAMPING * np.eye(len(err)), err)
            data.qpos[self.qpos] = np.clip(data.qpos[self.qpos] + step, self.low, self.high)
            mujoco.mj_forward(self.model, data)
        return float(np.linalg.norm(residual(data)[0]))

    def plan(
        self, data: Any, residual: Residual, seeds: Sequence[np.ndarray], *, iters: int, tol: float = 1e-9
    ) -> np.ndarray | None:
        """Arm joints that bring ``residual`` within :data:`IK_TOLERANCE`, or None; ``data`` is not touched.

        Starts from ``data``'s joints, then from each of ``seeds`` (clipped to the
        ranges), on a scratch copy of ``data``'s positions (kinematics only).
        """
        import mujoco

        model, s = self.model, self._scratch
        starts = [np.array(data.qpos[self.qpos], dtype=np.float64), *(np.asarray(q, dtype=np.float64) for q in seeds)]
        for q in starts:
            s.qpos[:] = data.qpos
            s.qpos[self.qpos] = np.clip(q, self.low, self.high)
            for _ in range(iters):
                mujoco.mj_kinematics(model, s)
                mujoco.mj_comPos(model, s)
                err, jac = residual(s)
                if np.linalg.norm(err) < tol:
                    break
                step = jac.T @ np.linalg.solve(jac @ jac.T + _DAMPING * np.eye(len(err)), err)
                s.qpos[self.qpos] = np.clip(s.qpos[self.qpos] + step, self.low, self.high)
            mujoco.mj_kinematics(model, s)
            mujoco.mj_comPos(model, s)
            if np.linalg.norm(residual(s)[0]) < IK_TOLERANCE:
                return np.array(s.qpos[self.qpos])
        return None
