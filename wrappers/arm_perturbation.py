"""ArmPerturbationWrapper: the "+p" evaluation perturbations of GLiDE's robosuite study (thesis Table 4.3).

While a policy runs, the wrapper now and then disturbs the arm from outside,
the way the thesis's evaluation "randomly displace[s] the end-effector or
open[s] the gripper":

- **schedule**: after each step, with probability ``probability`` (0.1) a
  perturbation starts (it affects the next step), unless ``max_perturbations``
  (2) have already happened this episode, a gripper opening or a drive push
  is still running, or the next step is one of the last ``quiet_steps`` (10)
  of the step limit.
  The first step of an episode is never perturbed (a push needs a step to land on).
  With ``after_mode_change=True`` none starts before the episode's ground-truth
  mode (``info["mode"]``) has first changed, i.e. once the arm has left reach:
  the polygon study's evaluation schedule in GLiDE's public code. Without it the
  pushes mostly land during reach, where the gripper is open anyway and a push
  costs a few steps.
- **kind**: with probability ``gripper_fraction`` (1/2) a *gripper opening*,
  otherwise an *end-effector push*. Half and half because the thesis names
  both kinds and no ratio; GLiDE's own replays use 1 gripper in 3, but a push
  of a free arm mostly costs a few steps while an opening drops a held
  object, so the even split keeps both failure kinds in the numbers.
- **push**, ``push_style="displace"`` (the default): a displacement of the eef
  by ``delta``: a uniform direction on the sphere, a length uniform in
  ``push_range`` ((0.05, 0.1) m, the size of GLiDE's replay perturbations),
  done by ``env.unwrapped.perturb(delta=...)`` (closed-loop OSC steps, not env
  steps) right after the step, so the policy sees the pushed state. A push
  that would take the eef below the object's height at reset has its vertical
  part flipped upward: pushing the fingers into the table is not a push the
  arm could take; a push that would leave the arm's workspace
  (``env.unwrapped.perturb_workspace``) is drawn again.
- **push**, ``push_style="drive"`` (GLiDE's public evaluation code, robomimic's
  ``EnvPerturber``): for the next ``push_steps`` (10) env steps the position
  part of the policy's action gets a unit vector added, pointing from that
  action to a target drawn once per push, uniform in ``[-1, 1]^3`` with its
  height raised to at least 0.5 (so pushes lean upward, away from the table);
  the env clips the sum to ``[-1, 1]``. Against a still policy a 10-step drive
  moves the eef 11-12 cm (the OSC lags its 0.05 m a step commands); the policy
  fights it while it lasts. :data:`PUBLIC_CODE_SETTINGS` is that code's whole schedule.
- **gripper opening**: the gripper command of the next ``n`` steps is forced
  to open (-1), ``n`` uniform in ``gripper_steps`` ((5, 20), the replays'
  range), cut short so the opening ends before the last ``quiet_steps``.

Randomness comes from the wrapper's own generator, seeded by ``reset(seed)``
(``default_rng([seed, 1])``: independent of the env's placement draws from the
same seed), so a seed replays the same perturbations for the same policy.

``info`` keys added at every step: ``perturbed`` (this step was pushed or had
its gripper forced open), ``perturbation`` (``"push"``, ``"gripper"`` or None:
what started on this step), ``perturbation_count`` (started so far this
episode), ``gripper_forced`` (the gripper command was overridden).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from types import MappingProxyType
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from steer_envs.core.validation import describe, integer, one_of, real_scalar
from steer_envs.envs.checks import check_seed
from steer_envs.envs.robosuite.adapter import RobosuiteEnv
from steer_envs.wrappers.constructor_args import record_constructor_args

__all__ = ["PERTURBATION_KINDS", "PUBLIC_CODE_SETTINGS", "PUSH_STYLES", "ArmPerturbationWrapper"]

#: the kinds of perturbation the wrapper starts (``info["perturbation"]``).
PERTURBATION_KINDS: tuple[str, ...] = ("push", "gripper")
#: how a push moves the arm (see the module): an instant displacement or a drive over several steps.
PUSH_STYLES: tuple[str, ...] = ("displace", "drive")
#: the schedule of GLiDE's public robosuite evaluation (robomimic ``EnvPerturber``'s defaults): a push starts
#: with probability 0.1 a step, lasts 10 steps, at most 2 an episode, from the first steps on; its gripper
#: perturbation has probability 0 there, so none here.
PUBLIC_CODE_SETTINGS: Mapping[str, Any] = MappingProxyType(
    {
        "probability": 0.1,
        "max_perturbations": 2,
        "quiet_steps": 0,
        "push_style": "drive",
        "push_steps": 10,
        "gripper_fraction": 0.0,
    }
)
#: a displacement outside the arm's workspace is drawn again, at most this many draws in all
_PUSH_DRAWS = 20
_DRIVE_MIN_HEIGHT = 0.5  # a drive's target height is at least this (action units), as in the public code
_OWNER = "ArmPerturbationWrapper"


def _pair(value: Any, name: str, *, as_int: bool, low: float) -> tuple[float, float]:
    """``value`` as an ordered pair ``(lo, hi)`` with ``low <= lo <= hi`` (ints for ``as_int``)."""
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != 2:
        raise TypeError(f"{_OWNER}: `{name}` must be a pair (lo, hi), got {describe(value)}")
    if as_int:
        lo, hi = (float(integer(v, name, low=int(low), owner=_OWNER)) for v in value)
    else:
        lo, hi = (real_scalar(v, name, low=low, owner=_OWNER) for v in value)
    if lo > hi:
        raise ValueError(f"{_OWNER}: `{name}` must have lo <= hi, got {tuple(value)!r}")
    return lo, hi


def _step_limit(env: gym.Env[Any, Any], max_episode_steps: int | None) -> int:
    """``max_episode_steps`` checked, or (``None``) the step limit of ``env.spec`` (``ValueError`` if it has none)."""
    if max_episode_steps is None:
        spec = env.spec
        max_episode_steps = spec.max_episode_steps if spec is not None else None
        if max_episode_steps is None:
            raise ValueError(
                f"{_OWNER}: `env` has no step limit in its spec; pass `max_episode_steps` "
                "(or wrap the gym.make env, which has the registry's TimeLimit)"
            )
    return integer(max_episode_steps, "max_episode_steps", low=1, owner=_OWNER)


class ArmPerturbationWrapper(
    gym.Wrapper[np.ndarray, np.ndarray, np.ndarray, np.ndarray], gym.utils.RecordConstructorArgs
):
    """Random end-effector pushes and gripper openings during an episode of a robosuite arm (see the module).

    Args:
        env: a :class:`~steer_envs.envs.robosuite.adapter.RobosuiteEnv`, wrapped or not
            (``gym.make("steer_envs/Lift-v0")``).
        probability: chance per step that a perturbation starts, in [0, 1].
        max_perturbations: at most this many per episode (int >= 0).
        quiet_steps: no perturbation affects the last this many steps of the step limit (int >= 0).
        push_range: ``(lo, hi)`` length of a ``"displace"`` push, m (0 <= lo <= hi).
        push_style: ``"displace"`` or ``"drive"`` (see the module).
        push_steps: env steps a ``"drive"`` push lasts (int >= 1).
        gripper_fraction: chance that a perturbation is a gripper opening, in [0, 1].
        gripper_steps: ``(lo, hi)`` steps a gripper opening lasts (ints, 1 <= lo <= hi).
        after_mode_change: start none before the episode's mode first changes (bool).
        max_episode_steps: the episode's step limit; None reads it from ``env.spec``
            (the registry's TimeLimit), and it is an error if there is none.

    >>> import gymnasium as gym
    >>> import steer_envs
    >>> env = ArmPerturbationWrapper(gym.make("steer_envs/Lift-v0"))  # doctest: +SKIP
    >>> obs, info = env.reset(seed=0)  # doctest: +SKIP
    >>> info["perturbation_count"]  # doctest: +SKIP
    0
    """

    def __init__(
        self,
        env: gym.Env[Any, Any],
        *,
        probability: float = 0.1,
        max_perturbations: int = 2,
        quiet_steps: int = 10,
        push_range: tuple[float, float] = (0.05, 0.1),
        push_style: str = "displace",
        push_steps: int = 10,
        gripper_fraction: float = 0.5,
        gripper_steps: tuple[int, int] = (5, 20),
        after_mode_change: bool = False,
        max_episode_steps: int | None = None,
    ) -> None:
        record_constructor_args(self, locals())
        if not isinstance(env, gym.Env) or not isinstance(env.unwrapped, RobosuiteEnv):
            raise TypeError(f"{_OWNER}: `env` must be a RobosuiteEnv (wrapped or not), got {describe(env)}")
        gym.Wrapper.__init__(self, env)
        self.probability = real_scalar(probability, "probability", low=0.0, high=1.0, owner=_OWNER)
        self.max_perturbations = integer(max_perturbations, "max_perturbations", low=0, owner=_OWNER)
        self.quiet_steps = integer(quiet_steps, "quiet_steps", low=0, owner=_OWNER)
        self.push_range = _pair(push_range, "push_range", as_int=False, low=0.0)
        self.push_style = one_of(push_style, "push_style", PUSH_STYLES, owner=_OWNER)
        self.push_steps = integer(push_steps, "push_steps", low=1, owner=_OWNER)
        self.gripper_fraction = real_scalar(gripper_fraction, "gripper_fraction", low=0.0, high=1.0, owner=_OWNER)
        lo, hi = _pair(gripper_steps, "gripper_steps", as_int=True, low=1)
        self.gripper_steps = (int(lo), int(hi))
        if not isinstance(after_mode_change, bool):
            raise TypeError(f"{_OWNER}: `after_mode_change` must be a bool, got {describe(after_mode_change)}")
        self.after_mode_change = after_mode_change
        self.max_episode_steps = _step_limit(env, max_episode_steps)
        self._rng = np.random.default_rng()
        self._t = 0  # steps taken this episode
        self._count = 0
        self._open_left = 0  # steps of the running gripper opening still to force
        self._drive_left = 0  # steps of the running drive push still to apply
        self._drive_target = np.zeros(3)
        self._floor = -np.inf
        self._start_mode: Any = None  # the episode's first mode
        self._mode_changed = False
        self._push_info: dict[str, Any] = {}
        #: the perturbations of the current episode: (step they affect, kind, push delta or opening length)
        self.log: list[tuple[int, str, Any]] = []

    @property
    def arm(self) -> RobosuiteEnv:
        """The wrapped :class:`RobosuiteEnv`."""
        base = self.env.unwrapped
        assert isinstance(base, RobosuiteEnv)
        return base

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset the env and the schedule; ``seed`` (None or int >= 0) also seeds the perturbations."""
        seed = check_seed(seed, f"{_OWNER}.reset")
        obs, info = self.env.reset(seed=seed, options=options)
        if seed is not None:
            self._rng = np.random.default_rng([seed, 1])
        self._t = self._count = self._open_left = self._drive_left = 0
        self._floor = float(self.arm.object_pos[2])
        self._start_mode, self._mode_changed = info.get("mode"), False
        self.log = []
        return obs, self._annotate(info, perturbed=False, started=None)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        """One env step (gripper forced open, or the action driven, while one runs), then maybe the next one."""
        forced, driven = self._open_left > 0, self._drive_left > 0
        if forced or driven:
            act = np.array(action, dtype=np.float32, copy=True)
            if act.shape == (7,):  # a malformed action is the env's to refuse
                if forced:
                    act[6] = -1.0
                if driven:
                    act[:3] += self._drive_direction(act[:3])
            action = act
            self._open_left = max(self._open_left - 1, 0)
            self._drive_left = max(self._drive_left - 1, 0)
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._t += 1
        self._mode_changed = self._mode_changed or info.get("mode") != self._start_mode
        started, pushed = None, False
        if not (terminated or truncated) and self._may_start():
            started = self._start()
            if started == "push" and self.push_style == "displace":
                pushed = True
                obs = self._observation()
                info = self._after_push(info)
        info = self._annotate(info, perturbed=forced or driven or pushed, started=started)
        info["gripper_forced"] = forced
        return obs, reward, terminated, truncated, info

    # ---------------------------------------------------------------- schedule
    def _may_start(self) -> bool:
        """A perturbation may start now, to affect step ``self._t`` (0-based), and the coin says it does."""
        if self._count >= self.max_perturbations or self._open_left > 0 or self._drive_left > 0:
            return False
        if self.after_mode_change and not self._mode_changed:
            return False
        if self._steps_before_quiet() <= 0:
            return False
        return bool(self._rng.random() < self.probability)

    def _start(self) -> str:
        """Start one perturbation (a push is done now); returns its kind."""
        self._count += 1
        if self._rng.random() < self.gripper_fraction:
            lo, hi = self.gripper_steps
            n = int(self._rng.integers(lo, hi + 1))
            n = min(n, self._steps_before_quiet())  # over before the quiet steps
            self._open_left = n
            self.log.append((self._t, "gripper", n))
            return "gripper"
        if self.push_style == "drive":
            target = self._rng.uniform(-1.0, 1.0, size=3)
            target[2] = max(_DRIVE_MIN_HEIGHT, target[2])
            self._drive_target = target
            self._drive_left = min(self.push_steps, self._steps_before_quiet())  # over before the quiet steps
            self.log.append((self._t, "push", target.copy()))
            return "push"
        delta = self._displacement()
        for _ in range(_PUSH_DRAWS - 1):  # a push the arm cannot take is drawn again
            if self.arm.perturb_workspace.contains(self.arm.state[:3] + delta):
                break
            delta = self._displacement()
        else:
            # near the workspace's edge no draw fits: the shortest push toward its inside
            delta = self._inward(delta)
        self.log.append((self._t, "push", delta))
        self._push_info = self.arm.perturb(delta=delta)
        return "push"

    def _displacement(self) -> np.ndarray:
        """A random displacement: a uniform direction, a length uniform in ``push_range``, never into the floor."""
        direction = self._rng.normal(size=3)
        direction /= max(float(np.linalg.norm(direction)), 1e-12)
        delta = direction * float(self._rng.uniform(*self.push_range))
        if self.arm.state[2] + delta[2] < self._floor:
            delta[2] = abs(delta[2])
        return np.asarray(delta)

    def _inward(self, delta: np.ndarray) -> np.ndarray:
        """``delta``'s length, pointed from the eef toward the workspace's box centre (inside it for short pushes)."""
        space = self.arm.perturb_workspace
        toward = (np.asarray(space.low) + np.asarray(space.high)) / 2 - self.arm.state[:3]
        toward /= max(float(np.linalg.norm(toward)), 1e-12)
        return np.asarray(toward * float(np.linalg.norm(delta)))

    def _steps_before_quiet(self) -> int:
        """Steps from step ``self._t`` (0-based) up to the quiet steps at the end of the step limit."""
        return self.max_episode_steps - self.quiet_steps - self._t

    def _drive_direction(self, position_action: np.ndarray) -> np.ndarray:
        """The unit vector from the policy's position action toward the running drive's target."""
        offset = self._drive_target - np.asarray(position_action, dtype=np.float64)
        return (offset / max(float(np.linalg.norm(offset)), 1e-12)).astype(np.float32)

    def _after_push(self, info: dict[str, Any]) -> dict[str, Any]:
        """The step's ``info`` updated to the pushed state (mode, sensors); the step's violation and success kept."""
        push = self._push_info
        success = bool(info["success"] or push["success"])
        return {
            **info,
            **push,
            "constraint_violation": bool(info["constraint_violation"] or push["constraint_violation"]),
            "success": success,
            "is_success": success,
        }

    def _observation(self) -> np.ndarray:
        """The env's observation of the current (pushed) state, as ``RobosuiteEnv`` builds it."""
        arm = self.arm
        return np.concatenate([np.ravel(arm.robosuite_obs[k]) for k in arm.obs_keys]).astype(np.float32)

    def _annotate(self, info: dict[str, Any], *, perturbed: bool, started: str | None) -> dict[str, Any]:
        return {
            **info,
            "perturbed": bool(perturbed),
            "perturbation": started,
            "perturbation_count": self._count,
            "gripper_forced": False,
        }
