"""What the skill-plan trackers of BlockStack and Kitchen share: checking a plan, finding a waypoint, the outcome.

A plan is ``(H, d)`` waypoints (the end-effector position, the domain's
extras and last the gripper command); :func:`check_plan` refuses anything
else, :func:`first_index` finds the first waypoint where a condition holds
(e.g. where the gripper closes). Executing a plan gives a
:class:`PlanOutcome` (the Kitchen's adds the modes before and after).

Both trackers run a plan in one of :data:`EXECUTIONS` (:func:`check_execution`):

* ``"open_loop"``: each waypoint gets a fixed number of control steps, then
  the tracker moves on wherever the arm is (it waits only at a gripper switch,
  briefly, for the eef to reach the switching waypoint);
* ``"closed_loop"``: as the thesis's robots ran their plans: the tracker does
  not move on before the measured eef is within a tolerance of the waypoint
  (a bounded number of extra steps), a grasp is checked by contact (both
  finger pads on the intended object; if not, it opens, re-approaches the
  object where it is now and closes again, a bounded number of times, and only
  when the plan's closing waypoint was a grasp of that object), and a release
  waits until the let-go object rests on its support before the arm moves on.

>>> first_index(check_plan([[0.0, 0.0, 0.3, -1.0], [0.0, 0.0, 0.2, 1.0]], 4, 10, "demo")[:, 3] > 0)
1
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.core.validation import one_of, real_array

__all__ = ["EXECUTIONS", "PlanOutcome", "PlanRun", "check_execution", "check_plan", "first_index"]

#: how a tracker runs a plan (module docstring); the first is the default.
EXECUTIONS = ("open_loop", "closed_loop")


@dataclass(frozen=True)
class PlanOutcome:
    """What executing a plan did.

    Attributes:
        executed: the skill the world shows happened (the domain reads it off
            the state before vs after), or None.
        violation: some step reported ``constraint_violation``.
        steps: control steps run.
        trail: ``(steps + 1, 3)`` eef positions, the start included.
        obs: the env's observation after the last step (what the next plan is conditioned on).
        regrasps: grasps the closed-loop tracker tried again after one closed on nothing (0 open-loop).

    >>> PlanOutcome("pick_1", False, 3, np.zeros((4, 3)), np.zeros(33)).success
    True
    """

    executed: str | None
    violation: bool
    steps: int
    trail: np.ndarray
    obs: np.ndarray
    regrasps: int = 0

    @property
    def success(self) -> bool:
        """A skill happened and no step violated a constraint."""
        return self.executed is not None and not self.violation


class PlanRun:
    """What a tracker records while it runs one plan on ``base`` (an unwrapped arm env): the trail of eef
    positions, the control steps, whether a step violated a constraint, the last observation, the re-grasps.

    Each tracker computes its actions and sends them through :meth:`advance`.
    """

    def __init__(self, base: Any) -> None:
        self.base = base
        self.trail = [base.state]
        self.violation = False
        self.steps = 0
        self.last_obs = base._obs()
        self.regrasps = 0

    def advance(self, action: np.ndarray) -> None:
        """One control step of ``action``, recorded."""
        self.last_obs, _, _, _, info = self.base.step(action)
        self.violation |= bool(info["constraint_violation"])
        self.trail.append(self.base.state)
        self.steps += 1


def check_plan(plan: Any, width: int, max_waypoints: int, owner: str) -> np.ndarray:
    """``plan`` as a finite float64 ``(H, width)`` array with ``1 <= H <= max_waypoints``.

    ``TypeError`` / ``ValueError`` naming ``owner`` and ``plan`` otherwise.
    """
    arr = real_array(plan, "plan", ndim=2, max_size=max_waypoints * width, owner=owner)
    if arr.shape[0] < 1 or arr.shape[1] != width:
        raise ValueError(f"{owner}: `plan` must have shape (H, {width}) with H >= 1, got {arr.shape}")
    return arr


def check_execution(execution: Any, owner: str) -> str:
    """``execution`` if it is one of :data:`EXECUTIONS`; ``ValueError`` naming ``owner`` and the argument otherwise.

    >>> check_execution("closed_loop", "demo")
    'closed_loop'
    """
    return one_of(execution, "execution", EXECUTIONS, owner=owner)


def first_index(mask: np.ndarray) -> int | None:
    """The index of the first true entry of ``mask``, or None."""
    hits = np.flatnonzero(mask)
    return int(hits[0]) if hits.size else None
