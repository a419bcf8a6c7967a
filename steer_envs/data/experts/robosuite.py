"""Scripted experts of the robosuite tasks (Lift, Can, Square): privileged phase machines.

Each reads the unwrapped :class:`~steer_envs.envs.robosuite.adapter.RobosuiteEnv`
(robosuite's observation dict, placements) and commands the eef with a
proportional delta-OSC action (gain 10, clipped to [-1, 1]). ``phase`` and
``target`` (the point the last action aimed at) say what it is doing, which the
human-like demonstrator (:mod:`steer_envs.data.experts.human_like`) reads.

- Lift: above the cube, down, close, lift to 1.05 m. In the public-code variant
  (``RobosuiteEnv(variant="public_code")``) the lift is the one the public GLiDE
  fork appends to its demos instead: the closed gripper rises 1 cm a step with a
  small seeded random xy walk (a per-demo drift within +-2 mm a step plus 1 mm
  noise) until the cube is 0.40 m above the table (about 40 steps).
- Can: above the can, down, close, lift, carry to the near corner of the target
  bin quadrant (its centre is at the edge of the Panda's reach), lower, open, retreat.
- Square: above the handle with the gripper yaw matched to the nut's (mod 90
  degrees), down, close, lift, carry with the nut's yaw turned to 0 (mod 90)
  using the held offset ``nut - eef`` measured after the grasp, then lower with
  closed-loop xy correction of the nut over the peg, open.

>>> LiftExpert.gain
10.0
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.control.blockstack import wrap_quarter, yaw_of
from steer_envs.core.validation import integer
from steer_envs.envs.robosuite.adapter import RobosuiteEnv

__all__ = ["CanExpert", "LiftExpert", "PhaseExpert", "SquareExpert"]


class PhaseExpert:
    """A phase machine over ``env.robosuite_obs``; each task's expert defines :meth:`act`."""

    gain = 10.0
    #: control steps the gripper closes on the object before the expert moves on
    close_steps = 8
    #: x the distances at which free-motion waypoints (above an object, the top of a lift, Can's carry) count as
    #: reached: above 1 the expert cuts corners, moving on before it has settled there
    waypoint_tolerance = 1.0

    def __init__(self, env: RobosuiteEnv) -> None:
        if not isinstance(env, RobosuiteEnv):
            raise TypeError(f"{type(self).__name__}: `env` must be a RobosuiteEnv, got {type(env).__name__}")
        self.env = env
        self.phase = "above"
        self.count = 0
        self.target = np.array(env.state, dtype=np.float64)

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Start a new episode in the first phase."""
        self.phase, self.count = "above", 0
        self.target = np.array(self.env.state, dtype=np.float64)

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for the current sim state (each task's expert defines it)."""
        raise NotImplementedError

    def _move(self, target: np.ndarray, gripper: float) -> tuple[np.ndarray, np.ndarray]:
        self.target = np.array(target, dtype=np.float64)
        d = target - self.env.robosuite_obs["robot0_eef_pos"]
        action = np.zeros(7, dtype=np.float32)
        action[:3] = np.clip(d * self.gain, -1.0, 1.0)
        action[6] = gripper
        return action, d

    def _wait(self, phase: str, steps: int, nxt: str) -> None:
        if self.phase == phase:
            self.count += 1
            if self.count > steps:
                self.phase, self.count = nxt, 0


class LiftExpert(PhaseExpert):
    """Lift: grasp the cube from above and raise it to 1.05 m (public-code variant: 1 cm a step, see the module).

    ``seed`` seeds the public-code variant's xy walk (one stream per expert,
    a walk drawn per episode); the thesis variant draws nothing.
    """

    #: the thesis variant lifts the cube to this height (m)
    lift_height = 1.05
    #: public-code variant: the closed gripper rises this much a control step (m) ...
    raise_step = 0.01
    #: ... with an xy walk: a drift drawn per demo within +-walk_drift (m a step) ...
    walk_drift = 0.002
    #: ... plus Gaussian noise of this standard deviation (m a step) ...
    walk_noise = 0.001
    #: ... up to this far above the success height (m), where the rise stops
    raise_margin = 0.15

    def __init__(self, env: RobosuiteEnv, *, seed: int = 0) -> None:
        super().__init__(env)
        self.rng = np.random.default_rng(integer(seed, "seed", low=0, owner=type(self).__name__))
        self.public_code = env.variant == "public_code"
        self._reference: np.ndarray | None = None
        self._drift = np.zeros(2)

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Start a new episode in the first phase."""
        super().reset(obs, info)
        self._reference = None

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for the current sim state."""
        o = self.env.robosuite_obs
        eef, cube = o["robot0_eef_pos"], o["cube_pos"]
        if self.phase == "above":
            action, d = self._move(cube + np.array([0.0, 0.0, 0.08]), -1)
            if np.linalg.norm(d) < 0.01 * self.waypoint_tolerance:
                self.phase = "down"
        elif self.phase == "down":
            action, d = self._move(cube, -1)
            if np.linalg.norm(d) < 0.005:
                self.phase, self.count = "close", 0
        elif self.phase == "close":
            action, _ = self._move(cube, 1)
            self._wait("close", self.close_steps, "raise" if self.public_code else "lift")
        elif self.phase == "raise":
            action, _ = self._move(self._raised(eef), 1)
        else:
            action, _ = self._move(np.array([cube[0], cube[1], self.lift_height]), 1)
        return action

    def _raised(self, eef: np.ndarray) -> np.ndarray:
        """The public-code lift's next reference: 1 cm higher than the last, its xy one step of the walk on."""
        if self._reference is None:
            self._reference = np.array(eef, dtype=np.float64)
            self._drift = self.rng.uniform(-self.walk_drift, self.walk_drift, 2)
        else:
            self._reference[:2] += self.rng.normal(self._drift, self.walk_noise)
        height = self.env.spec_task.success_height
        assert height is not None  # the public-code variant has one
        top = float(self.env.rs_env.table_offset[2]) + height + self.raise_margin
        self._reference[2] = min(self._reference[2] + self.raise_step, top)
        return self._reference.copy()


class CanExpert(PhaseExpert):
    """Can: pick the can, place it at the near corner of its target bin quadrant, retreat."""

    down_steps = 25

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Start a new episode; read the target bin placement."""
        super().reset(obs, info)
        rs = self.env.rs_env
        self.bin = np.array(rs.target_bin_placements[rs.object_to_id["can"]], dtype=np.float64)
        self.aim = self.bin.copy()
        self.aim[:2] += np.asarray(rs.bin_size[:2]) / 8 * np.sign(np.asarray(rs.bin2_pos[:2]) - self.bin[:2])

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for the current sim state."""
        o = self.env.robosuite_obs
        eef, can = o["robot0_eef_pos"], o["Can_pos"]
        aim, z0 = self.aim, self.bin[2]
        targets = {
            "above": (can + np.array([0.0, 0.0, 0.10]), -1),
            "down": (can + np.array([0.0, 0.0, -0.01]), -1),
            "close": (can, 1),
            "lift": (np.array([eef[0], eef[1], z0 + 0.20]), 1),
            "carry": (np.array([aim[0], aim[1], z0 + 0.20]), 1),
            "lower": (np.array([aim[0], aim[1], z0 + 0.10]), 1),
            "release": (eef, -1),
            "retreat": (np.array([aim[0], aim[1], z0 + 0.30]), -1),
        }
        target, grip = targets[self.phase]
        action, d = self._move(np.asarray(target, dtype=np.float64), grip)
        n = float(np.linalg.norm(d))
        if self.phase == "above" and n < 0.01 * self.waypoint_tolerance:
            self.phase, self.count = "down", 0
        elif self.phase == "down":
            self.count += 1
            # the fingers may stop on the can's rim 1-2 cm above the target: close there after a while
            if (abs(d[2]) < 0.02 and np.linalg.norm(d[:2]) < 0.01) or self.count > self.down_steps:
                self.phase, self.count = "close", 0
        elif self.phase in ("lift", "carry", "lower") and n < 0.02 * (
            1.0 if self.phase == "lower" else self.waypoint_tolerance
        ):
            self.phase = {"lift": "carry", "carry": "lower", "lower": "release"}[self.phase]
            self.count = 0
        self._wait("close", self.close_steps, "lift")
        self._wait("release", 8, "retreat")
        return action


class SquareExpert(PhaseExpert):
    """Square: grasp the nut's handle, carry it over the peg with its yaw squared, lower it on."""

    carry_z = 1.0
    lower_z = 0.83
    down_steps = 40  # the fingers may touch the table before the handle height: close anyway
    lower_speed = 0.3  # action units: a slow descent does not jam the nut on the peg top
    stuck_steps = 30
    peg_top = 0.08  # m above the peg body: a nut centre higher than this rests on the peg top
    retry_shifts = (0.004, -0.004, 0.008, -0.008)  # m along the nut -> handle axis, one per retry
    max_retries = 4
    close_steps = 10
    lower_steps = 80  # the lower phase releases the nut after this many steps at the latest
    #: release as soon as the nut, below the peg's top, has sunk less than 1 mm over this many steps
    #: (None: the scripted expert's rule, at the lower target or after ``lower_steps``)
    settle_steps: int | None = None

    def __init__(self, env: RobosuiteEnv) -> None:
        super().__init__(env)
        rs = env.rs_env
        self._handle = rs.sim.model.site_name2id(rs.nuts[rs.nut_id].important_sites["handle"])

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Start a new episode; read the peg position."""
        super().reset(obs, info)
        rs = self.env.rs_env
        self.peg = np.array(rs.sim.data.body_xpos[rs.peg1_body_id], dtype=np.float64)
        self.retries = 0
        self._heights: list[float] = []  # the nut's heights over the current lower phase

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for the current sim state."""
        rs = self.env.rs_env
        o = self.env.robosuite_obs
        eef, nut = o["robot0_eef_pos"], o["SquareNut_pos"]
        handle = np.array(rs.sim.data.site_xpos[self._handle])
        nut_yaw = yaw_of(o["SquareNut_quat"])
        grip_yaw = wrap_quarter(nut_yaw - yaw_of(o["robot0_eef_quat"]))
        square_yaw = wrap_quarter(-nut_yaw)
        peg = self.peg
        if self.phase == "above":
            action, d = self._move(handle + np.array([0.0, 0.0, 0.08]), -1)
            action[5] = np.clip(grip_yaw * 2, -1, 1)
            if np.linalg.norm(d) < 0.01 and abs(grip_yaw) < 0.05:  # the handle is thin: no corner cutting
                self.phase, self.count = "down", 0
        elif self.phase == "down":
            action, d = self._move(handle + np.array([0.0, 0.0, -0.005]), -1)
            action[5] = np.clip(grip_yaw * 2, -1, 1)
            self.count += 1
            blocked = abs(d[2]) < 0.015 and np.linalg.norm(d[:2]) < 0.01
            if np.linalg.norm(d) < 0.01 or blocked or self.count > self.down_steps:
                self.phase, self.count = "close", 0
        elif self.phase == "close":
            action, _ = self._move(eef, 1)
            self._wait("close", self.close_steps, "lift")
        elif self.phase == "lift":
            action, d = self._move(np.array([eef[0], eef[1], self.carry_z]), 1)
            if np.linalg.norm(d) < 0.02 * self.waypoint_tolerance:
                self.phase = "carry"
        elif self.phase in ("carry", "lower"):
            held = nut - eef  # the actual held offset, re-read every step (the nut may slip)
            axis = (handle - nut)[:2] / max(float(np.linalg.norm((handle - nut)[:2])), 1e-6)
            # retries search along the handle axis: a nut hanging from its handle tilts, shifting its hole
            shift = self.retry_shifts[self.retries - 1] * axis if self.retries else np.zeros(2)
            xy = peg[:2] + shift - held[:2]
            z = self.carry_z if self.phase == "carry" else self.lower_z
            action, d = self._move(np.array([xy[0], xy[1], z]), 1)
            action[5] = np.clip(square_yaw * 2, -1, 1)
            xy_err = float(np.linalg.norm(nut[:2] - peg[:2] - shift))
            if self.phase == "carry" and xy_err < 0.005 and abs(d[2]) < 0.02 and abs(square_yaw) < 0.03:
                self.phase, self.count = "lower", 0
            elif self.phase == "lower":
                action[2] = np.clip(action[2], -self.lower_speed, self.lower_speed)
                if self.count == 0:
                    self._heights = []
                self._heights.append(float(nut[2]))
                self.count += 1
                stuck = self.count > self.stuck_steps and nut[2] > peg[2] + self.peg_top
                if stuck and self.retries < self.max_retries:  # resting on the peg top: lift, square up, retry
                    self.phase, self.count = "carry", 0
                    self.retries += 1
                elif (
                    abs(d[2]) < 0.01 or self.count > self.lower_steps or self._settled(nut[2] <= peg[2] + self.peg_top)
                ):
                    self.phase, self.count = "release", 0
        else:
            action, _ = self._move(eef, -1)
        return action

    def _settled(self, below_top: bool) -> bool:
        """With ``settle_steps``: the nut is below the peg's top and has stopped sinking (see the attribute)."""
        n = self.settle_steps
        return (
            n is not None and below_top and len(self._heights) > n and self._heights[-1 - n] - self._heights[-1] < 1e-3
        )
