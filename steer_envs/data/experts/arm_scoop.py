"""Scripted expert of ArmScoop-v0: a closed-loop waypoint controller in ``(y, z, pitch)``.

Memoryless like the 2D soup expert: the velocity is a function of the state
and the sensed mode, so after any push it re-plans from where the spoon is, and
a spill sends it back to scoop. Per mode (waypoints in ``(y, z, pitch)``):

* ``a`` (reach): hover above the soup tipped down (:data:`DIP_PITCH`), then
  dip in (the mode switches to ``b`` at the surface);
* ``b`` (scoop): sweep through the soup toward the target side while turning
  the spoon up to :data:`CARRY_PITCH`, then lift out (beads load);
* ``c`` (transport): straight to above the target bowl, levelling the spoon;
* ``d`` (done): stay.

Straight segments in ``(y, z, pitch)`` at :data:`SPEED` (m/s) and
:data:`TURN_RATE` (rad/s), both axes arriving together.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.envs.robosuite.arm_scoop import SOUP_SURFACE, SOUP_Y, TARGET_Y, ArmScoopEnv

#: pitch of the spoon entering the soup (tip down, rad) and carrying beads (tipped back, rad).
DIP_PITCH = -0.6
CARRY_PITCH = 0.2
#: linear speed (m/s) and turn rate (rad/s) of the expert's moves.
SPEED = 0.12
TURN_RATE = 0.8
#: the waypoints (y, z, pitch).
HOVER = np.array([SOUP_Y - 0.03, SOUP_SURFACE + 0.04, DIP_PITCH])
DIP = np.array([SOUP_Y - 0.03, SOUP_SURFACE - 0.03, DIP_PITCH])
SWEEP = np.array([SOUP_Y + 0.03, SOUP_SURFACE - 0.03, CARRY_PITCH])
LIFT = np.array([SOUP_Y + 0.03, SOUP_SURFACE + 0.04, CARRY_PITCH])
ABOVE_TARGET = np.array([TARGET_Y, SOUP_SURFACE + 0.05, 0.0])


def toward(state: np.ndarray, target: np.ndarray, dt: float) -> np.ndarray:
    """Velocity moving ``state`` straight at ``target``: position at :data:`SPEED`, pitch at :data:`TURN_RATE`."""
    delta = target - state
    time = max(float(np.linalg.norm(delta[:2])) / SPEED, abs(float(delta[2])) / TURN_RATE, dt)
    return delta / time


class ArmScoopExpert:
    """Closed-loop scripted expert of :class:`ArmScoopEnv`; see the module docstring."""

    def __init__(self, env: ArmScoopEnv) -> None:
        if not isinstance(env, ArmScoopEnv):
            raise TypeError(f"env must be an ArmScoopEnv (env.unwrapped), got {type(env).__name__}")
        self.env = env

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Nothing to reset: the expert is memoryless."""

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The velocity ``(y', z', pitch')`` (float32) for the observed state and ``info["mode_name"]``."""
        x = np.asarray(obs, dtype=np.float64)
        mode = info["mode_name"]
        if mode == "a":
            aligned = abs(x[0] - HOVER[0]) < 0.01 and abs(x[2] - HOVER[2]) < 0.05 and x[1] < HOVER[1] + 0.01
            target = DIP if aligned else HOVER
        elif mode == "b":
            target = LIFT if (x[2] > CARRY_PITCH - 0.05 and x[0] > SWEEP[0] - 0.01) else SWEEP
        elif mode == "c":
            target = ABOVE_TARGET
        else:
            return np.zeros(3, dtype=np.float32)
        return toward(x, target, self.env.dt).astype(np.float32)
