"""A human-like demonstrator for Lift, Can and Square: the scripted expert with a teleoperator's variation.

**A sensitivity study, not a replacement for the scripted expert.** GLiDE's
thesis trained on robomimic's proficient-human (PH) demonstrations, which
cannot be obtained here; the scripted experts
(:mod:`steer_envs.data.experts.robosuite`) move the same way every time. This
demonstrator asks whether that matters: it wraps a scripted expert (which still
decides *what* to do, from the simulator's state, and so still succeeds) and
changes *how* it moves, with seeded draws:

- an **idle start** (the operator has not begun: usually a few steps, now and
  then up to 20, of no motion, the gripper command "open");
- a **speed** that varies across demos (a factor drawn per demo) and within one
  (a slow random wobble around it): the expert's proportional gain, and the top
  speed when slower than the expert; where Square needs a fine fit (to its
  thin handle, the nut over the peg) no faster than the expert;
- **hesitations**: short pauses (2-6 steps, the arm held still) that start at
  random while moving;
- **curved approaches**: in free motion the arm bows sideways or up (never
  down), by a fraction of the distance still to go (so the bow vanishes at the
  target);
- **overshoot and correction**: on some free-motion targets the arm shoots past
  the target (1-3 cm, horizontally) and the expert brings it back;
- **cut corners**: a free-motion waypoint (above the object, the top of a lift)
  counts as reached 1.5-3 times farther off than the expert's own tolerance, so
  the next motion starts before the arm has settled;
- a **varied grasp dwell**: the gripper closes for the expert's time plus 0-6
  steps before the lift, and Square's nut is let go once it has stopped sinking (a person
  lets go when it looks done) rather than after the expert's fixed wait.

The public-code Lift's appended lift (1 cm a step, the fork's own script
extending its human demos) stays scripted.

Calibration: only the mean speed per task (:data:`CALIBRATED_SPEED`), chosen
to bring the mean demo length over reset seeds 0-9 toward robomimic's PH means
(:data:`PH_MEAN_LENGTH`; 200 demos per task at 20 Hz, recorded with robosuite's
collection script, which also stops 10 steps after success as
:func:`~steer_envs.data.robosuite_replays.record_demo` does). robomimic's own
docs list the datasets but not their lengths; the lengths are the frame counts
of the PH datasets as converted to LeRobot format: Square 30,154 frames
(``huggingface.co/datasets/ankile/robomimic-ph-square-image``, ``meta/info.json``),
Lift about 9,670 and Can about 23,200 (the same author's ``robomimic-ph-lift-image``
and ``robomimic-ph-can-image``). Over reset seeds 0-19 every demo succeeds and the
mean lengths stay above PH's: Lift 52 (scripted 63, PH 48), Can 131 (141, 116),
Square 262 (256, 151; median 195, the tail is the expert's retries on the peg's
top). Past these factors a higher speed shortens a demo by a step or two at
most: the arm's top speed under the delta controller (about 1.3 cm a step at
full action) binds, and the expert's plan (lift straight up, then carry;
Square's retries) is longer than a person's path. The other settings are fixed by what
they describe (steps, centimetres), not tuned to any result.

>>> HumanLikeSettings().idle_steps
(3, 20)
>>> sorted(PH_MEAN_LENGTH.items())
[('can', 116.0), ('lift', 48.35), ('square', 150.77)]
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.core.validation import integer, real_scalar
from steer_envs.data.experts.robosuite import CanExpert, LiftExpert, PhaseExpert, SquareExpert

__all__ = ["CALIBRATED_SPEED", "PH_MEAN_LENGTH", "HumanLikeDemonstrator", "HumanLikeSettings"]

#: robomimic's proficient-human demos: mean length in control steps (frames / 200 demos; see the module).
PH_MEAN_LENGTH: Mapping[str, float] = {"lift": 9_670 / 200, "can": 23_200 / 200, "square": round(30_154 / 200, 2)}
#: the mean speed factor per task (its only calibrated setting): mean demo length near :data:`PH_MEAN_LENGTH`.
CALIBRATED_SPEED: Mapping[str, float] = {"lift": 3.0, "can": 2.5, "square": 2.5}

#: phases of each expert in free motion (curves and overshoot apply), and those the wrapper leaves scripted.
_FREE: Mapping[type, frozenset[str]] = {
    LiftExpert: frozenset({"above", "lift"}),
    CanExpert: frozenset({"above", "lift", "carry", "retreat"}),
    SquareExpert: frozenset({"lift", "carry"}),  # above the thin handle it lines up like the expert
}
#: fine fits, where a person goes no faster than the expert: Square's thin handle, the nut lined up over the peg
_CAREFUL: Mapping[type, frozenset[str]] = {SquareExpert: frozenset({"above", "down", "carry", "lower"})}
_SCRIPTED = frozenset({"raise"})  # the public-code Lift's appended lift
_DWELL = frozenset({"close", "release"})  # timed by the expert's own count: no pauses there


@dataclass(frozen=True)
class HumanLikeSettings:
    """What varies and by how much (ranges are inclusive; ``speed`` None: the task's :data:`CALIBRATED_SPEED`).

    Attributes:
        idle_steps: steps of no motion at the start: within this range, its low end plus an exponential draw ...
        idle_mean: ... of this mean in all (before the cut at the high end).
        speed: the mean speed factor (x the expert's gain).
        speed_spread: standard deviation of the log of the per-demo factor.
        speed_wobble: standard deviation of the log of the within-demo factor (a slow AR(1) process) ...
        wobble_memory: ... and its step-to-step correlation.
        hesitation_rate: chance per moving step that a pause starts ...
        hesitation_steps: ... and its length.
        curve: the largest sideways bow of a free-motion approach, as a fraction of the distance to go.
        overshoot_chance: chance that a free-motion target is overshot ...
        overshoot: ... by this far (m), horizontally ...
        overshoot_radius: ... starting once the target is this close (m).
        waypoint_tolerance: the expert's ``waypoint_tolerance``, uniform in this range per demo.
        dwell_steps: steps added to the expert's own grasp wait (``close_steps``) before the lift.
        settle_steps: Square: steps the nut must have stopped sinking before it is let go.
    """

    idle_steps: tuple[int, int] = (3, 20)
    idle_mean: float = 7.0
    speed: float | None = None
    speed_spread: float = 0.2
    speed_wobble: float = 0.25
    wobble_memory: float = 0.9
    hesitation_rate: float = 0.02
    hesitation_steps: tuple[int, int] = (2, 6)
    curve: float = 0.4
    overshoot_chance: float = 0.5
    overshoot: tuple[float, float] = (0.01, 0.03)
    overshoot_radius: float = 0.04
    waypoint_tolerance: tuple[float, float] = (1.5, 3.0)
    dwell_steps: tuple[int, int] = (0, 6)
    settle_steps: tuple[int, int] = (2, 6)

    def __post_init__(self) -> None:
        for name, low in (("idle_steps", 0), ("hesitation_steps", 1), ("dwell_steps", 0), ("settle_steps", 1)):
            _check_range(self, name, low, integers=True)
        _check_range(self, "overshoot", 0.0)
        _check_range(self, "waypoint_tolerance", 1e-9)
        for name in ("speed_spread", "speed_wobble", "curve", "overshoot_radius"):
            real_scalar(getattr(self, name), name, low=0.0, owner=_OWNER)
        for name in ("wobble_memory", "hesitation_rate", "overshoot_chance"):
            real_scalar(getattr(self, name), name, low=0.0, high=1.0, owner=_OWNER)
        if self.speed is not None:
            real_scalar(self.speed, "speed", low=0.0, low_inclusive=False, owner=_OWNER)
        lo, hi = self.idle_steps
        real_scalar(self.idle_mean, "idle_mean", low=lo, high=hi, owner=_OWNER)


_OWNER = "HumanLikeSettings"


def _check_range(settings: HumanLikeSettings, name: str, low: float, *, integers: bool = False) -> None:
    """``settings.<name>`` is a ``(low, high)`` pair of finite numbers >= ``low`` with low <= high."""
    value = getattr(settings, name)
    if not isinstance(value, tuple) or len(value) != 2:
        raise ValueError(f"{_OWNER}: `{name}` must be a (low, high) pair, got {value!r}")
    if integers:
        pair = [float(integer(v, name, low=int(low), owner=_OWNER)) for v in value]
    else:
        pair = [real_scalar(v, name, low=low, owner=_OWNER) for v in value]
    if pair[0] > pair[1]:
        raise ValueError(f"{_OWNER}: `{name}` must have low <= high, got {value!r}")


class HumanLikeDemonstrator:
    """Wraps a scripted expert of Lift, Can or Square and moves like a (proficient) teleoperator (see the module).

    Args:
        expert: a :class:`~steer_envs.data.experts.robosuite.LiftExpert`, ``CanExpert`` or ``SquareExpert``;
            the wrapper sets its ``gain`` and grasp timing, so give it one of its own.
        seed: seeds every draw (one stream; each episode draws its own idle start, speed, dwell ...).
        settings: the variation (:class:`HumanLikeSettings`).

    Same protocol as the experts (``reset(obs, info)``, ``act(obs, info)``).

    >>> HumanLikeDemonstrator(object())
    Traceback (most recent call last):
    TypeError: HumanLikeDemonstrator: `expert` must be a LiftExpert, CanExpert or SquareExpert, got object
    """

    def __init__(self, expert: PhaseExpert, *, seed: int = 0, settings: HumanLikeSettings | None = None) -> None:
        owner = type(self).__name__
        if type(expert) not in _FREE:
            raise TypeError(
                f"{owner}: `expert` must be a LiftExpert, CanExpert or SquareExpert, got {type(expert).__name__}"
            )
        if settings is not None and not isinstance(settings, HumanLikeSettings):
            raise TypeError(f"{owner}: `settings` must be HumanLikeSettings or None, got {type(settings).__name__}")
        self.expert = expert
        self.settings = settings or HumanLikeSettings()
        self.rng = np.random.default_rng([integer(seed, "seed", low=0, owner=owner), 41])
        task = expert.env.task_name
        self.mean_speed = float(self.settings.speed or CALIBRATED_SPEED[task])
        self._free = _FREE[type(expert)]
        self._careful = _CAREFUL.get(type(expert), frozenset())
        self._base_gain = float(type(expert).gain)
        self.idle, self.demo_speed, self._wobble = 0, self.mean_speed, 0.0  # until reset draws the episode's
        self._clear()

    def _start(self) -> None:
        """Draw the episode's idle start, speed, grasp dwell and nut release; clear the step state."""
        s, rng = self.settings, self.rng
        lo, hi = s.idle_steps
        self.idle = min(hi, lo + int(rng.exponential(s.idle_mean - lo + 0.5))) if s.idle_mean > lo else lo
        self.demo_speed = self.mean_speed * float(np.exp(rng.normal(0.0, s.speed_spread)))
        self._wobble = float(rng.normal())
        self.expert.close_steps = type(self.expert).close_steps + int(
            rng.integers(s.dwell_steps[0], s.dwell_steps[1] + 1)
        )
        self.expert.waypoint_tolerance = float(rng.uniform(*s.waypoint_tolerance))
        if isinstance(self.expert, SquareExpert):
            self.expert.settle_steps = int(rng.integers(s.settle_steps[0], s.settle_steps[1] + 1))
        self._clear()

    def _clear(self) -> None:
        """The step state of a new episode."""
        self.t = 0
        self.paused = 0  # steps of the current hesitation still to come
        self._gripper = -1.0
        self._segment: str | None = None  # the expert phase the current curve / overshoot draws belong to
        self._bow = np.zeros(3)
        self._overshoot = 0.0  # m; 0: none planned in this segment
        self._overshoot_left = -1  # steps of the overshoot still to come (-1: not started)
        self._overshoot_dir = np.zeros(3)

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Start a new episode: the expert's, and this episode's draws (``idle``, ``demo_speed``, the dwell ...)."""
        self.expert.reset(obs, info)
        self._start()

    @property
    def speed(self) -> float:
        """The speed factor of the current step (the per-demo factor times the wobble)."""
        return self.demo_speed * float(np.exp(self.settings.speed_wobble * self._wobble))

    def _hold(self) -> np.ndarray:
        action = np.zeros(7, dtype=np.float32)
        action[6] = self._gripper
        return action

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for the current sim state."""
        s, rng = self.settings, self.rng
        self.t += 1
        rho = s.wobble_memory
        self._wobble = rho * self._wobble + float(np.sqrt(1 - rho**2) * rng.normal())
        if self.t <= self.idle:
            return self._hold()
        if self.paused > 0:
            self.paused -= 1
            return self._hold()
        phase = self.expert.phase
        if phase not in _SCRIPTED | _DWELL and rng.random() < s.hesitation_rate:
            self.paused = int(rng.integers(s.hesitation_steps[0], s.hesitation_steps[1] + 1)) - 1
            return self._hold()
        if phase != self._segment:
            self._new_segment(phase)
        speed = 1.0 if phase in _SCRIPTED else self.speed
        if phase in self._careful:
            speed = min(speed, 1.0)
        self.expert.gain = self._base_gain * speed
        action = np.asarray(self.expert.act(obs, info), dtype=np.float64)
        self.expert.gain = self._base_gain
        if phase in self._free:
            action[:3] += self._shape(phase)
        cap = min(1.0, speed)
        action[:3] = np.clip(action[:3], -cap, cap)
        self._gripper = float(action[6])
        return action.astype(np.float32)

    def _new_segment(self, phase: str) -> None:
        """A new expert phase: draw its bow (free motion) and whether its target is overshot."""
        s, rng = self.settings, self.rng
        self._segment = phase
        self._bow = np.zeros(3)
        self._overshoot, self._overshoot_left = 0.0, -1
        if phase not in self._free:
            return
        self._bow = rng.normal(size=3)
        self._bow[2] = abs(self._bow[2])  # bows go sideways or up, never down into the table, bins or pegs
        self._bow *= rng.uniform(0.0, s.curve) / max(float(np.linalg.norm(self._bow)), 1e-9)
        if rng.random() < s.overshoot_chance:
            self._overshoot = float(rng.uniform(*s.overshoot))

    def _shape(self, phase: str) -> np.ndarray:
        """The action added in free motion: the bow toward the side, then the overshoot past the target."""
        expert = self.expert
        d = expert.target - expert.env.robosuite_obs["robot0_eef_pos"]
        dist = float(np.linalg.norm(d))
        unit = d / max(dist, 1e-9)
        side = self._bow - np.dot(self._bow, unit) * unit  # the bow's part across the path
        extra = expert.gain * dist * side
        horizontal = np.array([d[0], d[1], 0.0])
        if self._overshoot > 0 and self._overshoot_left < 0 and dist < self.settings.overshoot_radius:
            reach = float(np.linalg.norm(horizontal))
            if reach > 0.005:  # a vertical approach (onto the object) is never overshot
                self._overshoot_left = 2
                self._overshoot_dir = horizontal / reach
        if self._overshoot_left > 0:
            self._overshoot_left -= 1
            extra = extra + self._overshoot_dir * self._overshoot / 0.05 / 2  # metres over 2 steps, 5 cm per unit
        return extra
