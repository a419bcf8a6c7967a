"""Catching MuJoCo's silent resets in the arm envs: :class:`SimulationUnstableError` and its check.

When MuJoCo meets a NaN, an Inf or a huge value in the state, the velocities
or the accelerations of a simulation, it prints a warning, counts it in
``data.warning`` and resets the whole simulation to the model's initial state
(time 0, objects at their defaults, the arm pointing up), then goes on
stepping as if nothing happened. An arm env that passed such a step on would
hand the user a different world under the same episode. The arm envs instead
compare MuJoCo's warning counters (and the sim time, which a reset turns
back) before and after every control step, and raise
:class:`SimulationUnstableError` naming the warning; the env then refuses
``step`` and ``perturb`` until the next ``reset``.

Nothing here imports robosuite; MuJoCo is imported when a check runs.

>>> issubclass(SimulationUnstableError, RuntimeError)
True
>>> UNSTABLE_WARNINGS
('mjWARN_BADQPOS', 'mjWARN_BADQVEL', 'mjWARN_BADQACC', 'mjWARN_BADCTRL')
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["UNSTABLE_WARNINGS", "SimulationUnstableError", "StepWatch"]

#: MuJoCo's warnings that mean the simulation went bad: a bad position, velocity or
#: acceleration (after each MuJoCo resets the simulation) or a bad control (zeroed).
UNSTABLE_WARNINGS = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC", "mjWARN_BADCTRL")
_WHAT = {
    "mjWARN_BADQPOS": "a NaN, Inf or huge joint position",
    "mjWARN_BADQVEL": "a NaN, Inf or huge joint velocity",
    "mjWARN_BADQACC": "a NaN, Inf or huge joint acceleration",
    "mjWARN_BADCTRL": "a NaN or Inf control",
}


class SimulationUnstableError(RuntimeError):
    """MuJoCo found the arm env's simulation unstable and reset it: the episode cannot go on; call ``reset()``.

    Raised by ``step`` and ``perturb`` of the robosuite arm envs (and by every
    later ``step`` or ``perturb`` until ``reset``), never swallowed: an episode
    that went on would continue in a world MuJoCo had silently set back to its
    initial state.

    >>> raise SimulationUnstableError("Lift-v0: MuJoCo reset the simulation")
    Traceback (most recent call last):
    steer_envs.envs.robosuite.stability.SimulationUnstableError: Lift-v0: MuJoCo reset the simulation
    """


def _counts(data: Any) -> np.ndarray:
    import mujoco

    return np.array([data.warning[getattr(mujoco.mjtWarning, w)].number for w in UNSTABLE_WARNINGS], dtype=np.int64)


@dataclass
class StepWatch:
    """MuJoCo's instability counters and the sim time of ``data`` (an ``MjData``) before some sim steps.

    ``StepWatch.start(data)`` before the steps, ``watch.check(owner)`` after:
    a raised counter or a time that went back (MuJoCo resets the time with the
    rest) raises :class:`SimulationUnstableError` naming ``owner``, the warning
    and the time.
    """

    data: Any
    counts: np.ndarray
    time: float

    @classmethod
    def start(cls, data: Any) -> StepWatch:
        """The counters and time of ``data`` now."""
        return cls(data, _counts(data), float(data.time))

    def problem(self) -> str | None:
        """What went wrong since :meth:`start` (a sentence), or None if the simulation stayed sound."""
        now = _counts(self.data)
        raised = [i for i in range(len(UNSTABLE_WARNINGS)) if now[i] > self.counts[i]]
        if raised:
            w = UNSTABLE_WARNINGS[raised[0]]
            import mujoco

            dof = int(self.data.warning[getattr(mujoco.mjtWarning, w)].lastinfo)
            return (
                f"MuJoCo found {_WHAT[w]} ({w}, DOF {dof}) after sim time {self.time:.3f} s and reset the "
                "simulation to the model's initial state"
            )
        if float(self.data.time) < self.time:
            return (
                f"the simulation was reset under the episode (sim time went back from {self.time:.3f} s "
                f"to {float(self.data.time):.3f} s)"
            )
        return None

    def check(self, owner: str) -> None:
        """Raise :class:`SimulationUnstableError` naming ``owner`` if the simulation went bad since :meth:`start`."""
        problem = self.problem()
        if problem is not None:
            raise SimulationUnstableError(f"{owner}: {problem}; the episode cannot go on: call reset()")
