"""LTL-DS: one LPV-DS per mode, sequenced by the LTL task automaton and bounded by learned cuts (thesis ch. 3).

The thesis's policy (Eq. "LTL-DS") is ``pi(x, alpha) = M_m(x) f_m(x)``: the
sensors ``alpha`` tell the task automaton which mode ``m`` the system is in
(:class:`~steer_envs.ltl.replanner.ModeReplanner`), the mode's dynamical
system ``f_m`` (an :class:`~steer_envs.baselines.lpv_ds.lpvds.LPVDS`, stable at the
mode's attractor) drives the state toward the guard of the next planned mode,
and the modulation ``M_m`` (:func:`~steer_envs.baselines.lpv_ds.modulation.modulate`)
keeps the flow behind the cuts learned from the mode's invariance failures.

**Fitting** (:func:`fit_mode_dynamics`): demonstrations are segmented by their
sensor-derived modes (:func:`~steer_envs.data.segmentation.segment_demonstrations`);
each mode's segments train its LPV-DS. The attractor rule is a choice:

* ``"guard"`` (default): the mean of the *first states after* each segment
  (the transition states, just inside the next mode). The flow then crosses
  the guard in finite time and the next sensor fires.
* ``"last"``: the thesis appendix's mean of the *last in-mode* states. A DS
  only approaches its attractor asymptotically, so the transition then fires
  only where the environment counts points near an attractor as in the next
  region (the public TLI code's 0.4 rule, which SoupScoop-v0 applies to the
  public demonstrations' fixed attractors, not to learned ones).

A mode with too little data (the goal mode ``d`` of soup scooping is one
final state) reuses the DS and attractor of the mode the demonstrations
entered it from (the public code: "the done mode reuses the transport DS").

**Acting** (:class:`LTLDSPolicy`): ``act(obs, info)`` reads ``info["sensors"]``,
updates the automaton and returns the (modulated) velocity of the current
mode. A mode change that is not the plan's next mode and was not caused by a
push is an *invariance failure*: with ``modulation=True`` it adds a cut
through the last in-mode state and re-solves all cuts of that mode
(:func:`~steer_envs.baselines.lpv_ds.cuts.resolve_cuts`); the mode's entry
state, the other last-in-mode states and the attractor stay inside. Pushes are
recognised by ``info["perturbed"]`` (the ``info`` that
``env.unwrapped.perturb`` returns; pass it to ``act``) or, with ``dt`` given,
by a state jump larger than the last command can explain. Cuts persist across
episodes (that is the learning); :meth:`LTLDSPolicy.clear_cuts` forgets them.
One extension of the thesis: a state that re-enters a mode *beyond* one of its
cuts gets no further outward motion
(:func:`~steer_envs.baselines.lpv_ds.modulation.hold_beyond_cuts`), because a
guard can lie on a cut and re-entries there would otherwise loop.
"""

from __future__ import annotations

import itertools
import warnings
from collections import Counter
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal, cast

import numpy as np
from numpy.typing import ArrayLike

from steer_envs.baselines.lpv_ds.cuts import ATTRACTOR_MARGIN, CutSet, FailureRecord, resolve_cuts
from steer_envs.baselines.lpv_ds.lpvds import LPVDS, MIN_POINTS_PER_DIM
from steer_envs.baselines.lpv_ds.modulation import clip_speed, hold_beyond_cuts, modulate
from steer_envs.core.policy import VelocityPolicy
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import boolean, real_array, real_scalar, sensor_reading
from steer_envs.data.segmentation import segment_demonstrations
from steer_envs.ltl.gr1 import GR1Spec
from steer_envs.ltl.replanner import ModeReplanner, UnknownSensorReading

__all__ = ["AttractorRule", "LTLDSPolicy", "ModeDynamics", "ModeEvent", "fit_mode_dynamics", "repeated_failures"]

AttractorRule = Literal["guard", "last"]
#: slack of the push detection by state jumps (relative to the commanded step, plus an absolute floor).
JUMP_TOL = 1e-6


@dataclass(frozen=True)
class ModeDynamics:
    """The motion policy of one mode.

    Attributes:
        mode: the mode name.
        policy: a batched velocity policy ``(N, d) -> (N, d)`` (an :class:`LPVDS` when fitted here).
        attractor: ``(d,)`` where ``policy`` converges (the modulation's reference point).
        source: the mode whose data trained ``policy`` (``mode`` itself unless it reuses another's).
        entry_states, last_states: ``(n, d)`` first and last in-mode states of the demonstration segments.
    """

    mode: str
    policy: VelocityPolicy
    attractor: np.ndarray
    source: str
    entry_states: np.ndarray
    last_states: np.ndarray


@dataclass(frozen=True)
class ModeEvent:
    """A mode change seen by :class:`LTLDSPolicy`.

    ``kind`` is ``"planned"`` (the plan's next mode), ``"push"`` (caused by a
    perturbation) or ``"failure"`` (an invariance failure of ``source``);
    ``before`` is the last state in ``source``, ``after`` the first in ``target``.
    """

    step: int
    source: str
    target: str
    kind: str
    before: np.ndarray
    after: np.ndarray
    cut_added: bool = False


def _as_demo(demo: Any, i: int) -> tuple[np.ndarray, list[Hashable], np.ndarray]:
    """``(states (T, d), labels (T,), velocities (T - 1, d))`` from a Demonstration or a 3-tuple."""
    if hasattr(demo, "states") and hasattr(demo, "modes") and hasattr(demo, "actions"):
        states, labels, vel = demo.states, demo.modes, demo.actions
    elif isinstance(demo, tuple | list) and len(demo) == 3:
        states, labels, vel = demo
    else:
        raise TypeError(
            f"demos[{i}] must be a Demonstration or a (states, modes, velocities) tuple, got {type(demo).__name__}"
        )
    x = np.asarray(states, dtype=np.float64)
    v = np.asarray(vel, dtype=np.float64)
    if x.ndim != 2 or len(x) < 2:
        raise ValueError(f"demos[{i}]: states must have shape (T >= 2, d), got {x.shape}")
    if v.shape != (len(x) - 1, x.shape[1]):
        raise ValueError(
            f"demos[{i}]: velocities must have shape {(len(x) - 1, x.shape[1])} (one per step), got {v.shape}"
        )
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
        raise ValueError(f"demos[{i}]: states and velocities must be finite")
    lab = list(np.asarray(labels).tolist()) if isinstance(labels, np.ndarray) else list(labels)
    if len(lab) != len(x):
        raise ValueError(f"demos[{i}]: need one mode label per state ({len(x)}), got {len(lab)}")
    return x, lab, v


def fit_mode_dynamics(
    demos: Sequence[Any],
    task: TaskSpec,
    *,
    attractor_rule: AttractorRule = "guard",
    overshoot: float = 0.0,
    random_state: int = 0,
    ds_options: Mapping[str, Any] | None = None,
) -> dict[str, ModeDynamics]:
    """Segment ``demos`` by mode and fit one LPV-DS per mode (see the module docstring).

    Args:
        demos: :class:`~steer_envs.data.demos.Demonstration` objects or
            ``(states (T, d), modes (T,), velocities (T - 1, d))`` tuples; modes
            are indices or names of ``task.modes``.
        task: the task (mode names).
        attractor_rule: ``"guard"`` (mean transition state) or ``"last"`` (mean last in-mode state).
        overshoot: with ``"guard"``, move the attractor this far along the mean direction
            of the crossing steps (last in-mode -> first next-mode state): the mean of
            scattered crossing points of a curved guard may fall short of the guard.
        random_state: seed of the GMM fits.
        ds_options: extra keyword arguments of :class:`LPVDS`.

    Returns:
        ``mode name -> ModeDynamics`` for every mode of ``task``. Raises
        ``ValueError`` when a mode never occurs in the demonstrations (thesis
        Asm. 3: the demonstrations cover every mode).
    """
    if not isinstance(task, TaskSpec):
        raise TypeError(f"task must be a TaskSpec, got {type(task).__name__}")
    if attractor_rule not in ("guard", "last"):
        raise ValueError(f"attractor_rule must be 'guard' or 'last', got {attractor_rule!r}")
    if not isinstance(demos, Sequence) or len(demos) == 0:
        raise ValueError("demos must be a non-empty sequence of demonstrations")
    overshoot = real_scalar(overshoot, "overshoot", low=0.0)
    parsed = [_as_demo(d, i) for i, d in enumerate(demos)]
    # the last state has no velocity: it only serves as the transition state of the final segment
    seg = segment_demonstrations([(x[:-1], lab[:-1], v) for x, lab, v in parsed], task=task)
    d = parsed[0][0].shape[1]
    out: dict[str, ModeDynamics] = {}
    for key, data in seg.modes.items():
        mode = str(key)
        if sum(len(s) for s in data.segments) < MIN_POINTS_PER_DIM * d:
            continue  # too little data: reuses its predecessor's DS below
        attractor = _guard_attractor(parsed, data, overshoot) if attractor_rule == "guard" else data.attractor
        ds = LPVDS(random_state=random_state, **dict(ds_options or {}))
        ds.fit(data.states, data.velocities, attractor=attractor)
        out[mode] = ModeDynamics(mode, ds, attractor, mode, data.entry_states, data.last_states)
    missing = _borrow_dynamics(out, task, seg, _entered_from(parsed, task), d)
    if missing:
        raise ValueError(
            f"the demonstrations never visit mode(s) {missing} of task {task.name!r} (with enough data, or as the "
            "target of a demonstrated transition); LTL-DS needs demonstrations covering every mode (thesis Asm. 3)"
        )
    return {m: out[m] for m in task.modes}


def _entered_from(
    parsed: Sequence[tuple[np.ndarray, list[Hashable], np.ndarray]], task: TaskSpec
) -> dict[str, Counter[str]]:
    """Mode -> how often the demonstrations entered it from each other mode."""
    entered_from: dict[str, Counter[str]] = {}
    for _, lab, _ in parsed:
        names = [task.modes[task.mode_index(cast(str | int, m))] for m in lab]
        for a, b in itertools.pairwise(names):
            if a != b:
                entered_from.setdefault(b, Counter())[a] += 1
    return entered_from


def _guard_attractor(
    parsed: Sequence[tuple[np.ndarray, list[Hashable], np.ndarray]], data: Any, overshoot: float
) -> np.ndarray:
    """The ``"guard"`` attractor: the mean first state after each segment, ``overshoot`` along the mean crossing."""
    after = np.stack([parsed[s.demo][0][s.stop] for s in data.segments])  # the demo's last state at its end
    attractor = after.mean(axis=0)
    steps = after - data.last_states
    steps = steps / np.maximum(np.linalg.norm(steps, axis=1, keepdims=True), 1e-12)
    direction = steps.mean(axis=0)
    if overshoot > 0 and np.linalg.norm(direction) > 1e-9:
        attractor = attractor + overshoot * direction / np.linalg.norm(direction)
    return attractor


def _borrow_dynamics(
    out: dict[str, ModeDynamics], task: TaskSpec, seg: Any, entered_from: Mapping[str, Counter[str]], d: int
) -> list[str]:
    """Give each mode without a DS the DS of the mode most often entering it (in place); the modes left without."""
    missing = []
    for mode in task.modes:
        if mode in out:
            continue
        sources = [m for m, _ in entered_from.get(mode, Counter()).most_common() if m in out]
        if not sources:
            missing.append(mode)
            continue
        src = out[sources[0]]
        segs = [s for k, md in seg.modes.items() if str(k) == mode for s in md.segments]
        entry = np.stack([s.entry for s in segs]) if segs else np.zeros((0, d))
        last = np.stack([s.last for s in segs]) if segs else np.zeros((0, d))
        out[mode] = ModeDynamics(mode, src.policy, src.attractor, src.source, entry, last)
    return missing


class LTLDSPolicy:
    """The LTL-DS policy: automaton mode from sensors, that mode's DS, modulated by learned cuts.

    Args:
        task: the task (sensor APs, modes).
        spec: the GR(1) specification (e.g. :func:`steer_envs.ltl.specs.for_env`).
        dynamics: ``mode -> ModeDynamics`` for every mode of ``spec`` (see :func:`fit_mode_dynamics`).
        modulation: learn cuts from invariance failures and modulate by them (``False``: plain DS + automaton).
        max_speed: the env's speed limit (clipped before and after modulation; the
            discrete-time no-crossing guarantee needs it).
        margin: radius around each attractor that every cut keeps inside.
        dt: the env's time step; enables push detection by state jumps.
        hold_outside: for states beyond a cut, remove the velocity component that moves
            further out (:func:`hold_beyond_cuts`); ``False`` keeps the thesis's nominal
            flow there.

    Attributes:
        cut_sets: ``mode -> CutSet`` of the learned cuts.
        failures: ``mode -> [FailureRecord]`` (recorded with and without modulation).
        events: the mode changes since the last :meth:`reset`.

    >>> import gymnasium as gym
    >>> from steer_envs.data.demos import collect_demonstrations
    >>> from steer_envs.ltl.specs import for_env
    >>> env = gym.make("steer_envs/SoupScoop-v0", max_episode_steps=3000)
    >>> base = env.unwrapped
    >>> demos = collect_demonstrations("steer_envs/SoupScoop-v0", 1, seed=0)
    >>> policy = LTLDSPolicy.fit(demos, base.task, for_env(env), max_speed=base.max_speed, dt=base.dt)
    >>> obs, info = env.reset(seed=0)
    >>> policy.reset(obs, info)
    >>> while not info["success"]:
    ...     obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
    ...     if terminated or truncated:
    ...         break
    >>> info["success"], policy.plan[-1]
    (True, 'd')
    >>> env.close()
    """

    def __init__(
        self,
        task: TaskSpec,
        spec: GR1Spec,
        dynamics: Mapping[str, ModeDynamics],
        *,
        modulation: bool = True,
        max_speed: float | None = None,
        margin: float = ATTRACTOR_MARGIN,
        dt: float | None = None,
        hold_outside: bool = True,
    ) -> None:
        if not isinstance(task, TaskSpec):
            raise TypeError(f"task must be a TaskSpec, got {type(task).__name__}")
        if not isinstance(spec, GR1Spec):
            raise TypeError(f"spec must be a GR1Spec, got {type(spec).__name__}")
        self.replanner = ModeReplanner(task, spec)
        self.modes: tuple[str, ...] = self.replanner.modes
        if not isinstance(dynamics, Mapping):
            raise TypeError(f"dynamics must be a mapping mode -> ModeDynamics, got {type(dynamics).__name__}")
        missing = [m for m in self.modes if m not in dynamics]
        if missing:
            raise ValueError(f"dynamics lacks mode(s) {missing}; every mode of the spec {self.modes} needs a policy")
        for m in self.modes:
            if not isinstance(dynamics[m], ModeDynamics):
                raise TypeError(f"dynamics[{m!r}] must be a ModeDynamics, got {type(dynamics[m]).__name__}")
        if max_speed is not None:
            max_speed = real_scalar(max_speed, "max_speed", low=0.0, low_inclusive=False, owner="LTLDSPolicy")
        margin = real_scalar(margin, "margin", low=0.0, owner="LTLDSPolicy")
        if dt is not None:
            dt = real_scalar(dt, "dt", low=0.0, low_inclusive=False, owner="LTLDSPolicy")
        modulation = boolean(modulation, "modulation", owner="LTLDSPolicy")
        hold_outside = boolean(hold_outside, "hold_outside", owner="LTLDSPolicy")
        self.task = task
        self.spec = spec
        self.dynamics = {m: dynamics[m] for m in self.modes}
        self.modulation = bool(modulation)
        self.max_speed = None if max_speed is None else float(max_speed)
        self.margin = float(margin)
        self.dt = None if dt is None else float(dt)
        self.hold_outside = bool(hold_outside)
        self.dim = len(self.dynamics[self.modes[0]].attractor)
        self.cut_sets: dict[str, CutSet] = {m: CutSet(self.dynamics[m].attractor) for m in self.modes}
        self.failures: dict[str, list[FailureRecord]] = {m: [] for m in self.modes}
        self.events: list[ModeEvent] = []
        self._mode: str | None = None
        self._next: str | None = None
        self._x: np.ndarray | None = None
        self._v: np.ndarray | None = None
        self._entry: np.ndarray | None = None
        self._step = 0

    @classmethod
    def fit(
        cls,
        demos: Sequence[Any],
        task: TaskSpec,
        spec: GR1Spec,
        *,
        attractor_rule: AttractorRule = "guard",
        overshoot: float = 0.0,
        random_state: int = 0,
        ds_options: Mapping[str, Any] | None = None,
        **kwargs: Any,
    ) -> LTLDSPolicy:
        """Fit the per-mode DSs from demonstrations (:func:`fit_mode_dynamics`); ``kwargs`` go to the constructor."""
        dyn = fit_mode_dynamics(
            demos,
            task,
            attractor_rule=attractor_rule,
            overshoot=overshoot,
            random_state=random_state,
            ds_options=ds_options,
        )
        return cls(task, spec, dyn, **kwargs)

    # ------------------------------------------------------------ queries
    @property
    def mode(self) -> str:
        """The current automaton mode (after :meth:`reset`)."""
        if self._mode is None:
            raise RuntimeError("LTLDSPolicy: call reset(obs, info) first")
        return self._mode

    @property
    def plan(self) -> list[str]:
        """The planned mode sequence from the current mode."""
        return self.replanner.plan()

    @property
    def num_cuts(self) -> int:
        """Cuts over all modes."""
        return sum(len(c) for c in self.cut_sets.values())

    @property
    def num_failures(self) -> int:
        """Invariance failures recorded since construction (or :meth:`clear_cuts`)."""
        return sum(len(f) for f in self.failures.values())

    def clear_cuts(self) -> None:
        """Forget every learned cut and failure."""
        for m in self.modes:
            self.cut_sets[m].set_cuts([])
            self.failures[m] = []

    def flow(self, x: ArrayLike, mode: str) -> np.ndarray:
        """Velocities of ``mode``'s policy at states ``(N, d)``, modulated by its cuts when ``modulation`` is on."""
        if mode not in self.dynamics:
            raise ValueError(f"mode must be one of {self.modes}, got {mode!r}")
        xb = real_array(x, "x", finite=False, owner="LTLDSPolicy.flow")
        if xb.ndim != 2 or xb.shape[1] != self.dim or not np.all(np.isfinite(xb)):
            raise ValueError(f"x must be a finite array of shape (N, {self.dim}), got {xb.shape}")
        v = np.asarray(self.dynamics[mode].policy(xb), dtype=np.float64)
        if v.shape != xb.shape:
            raise ValueError(f"the policy of mode {mode!r} returned shape {v.shape} for states {xb.shape}")
        cuts = self.cut_sets[mode]
        if self.max_speed is not None:
            v = clip_speed(v, self.max_speed)
        if not (self.modulation and len(cuts)):
            return v
        out = modulate(xb, v, cuts, self.max_speed)
        if self.hold_outside:
            out = hold_beyond_cuts(xb, out, cuts)
        return out

    # ----------------------------------------------------------- acting
    def _state(self, obs: Any) -> np.ndarray:
        raw = obs["observation"] if isinstance(obs, Mapping) else obs
        x = real_array(raw, "obs", finite=False, owner="LTLDSPolicy").reshape(-1)
        if x.shape != (self.dim,) or not np.all(np.isfinite(x)):
            raise ValueError(f"obs must be a finite state of shape ({self.dim},), got {x.shape}")
        return x

    def _sensors(self, info: Mapping[str, Any]) -> dict[str, bool]:
        return sensor_reading(info, self.replanner.automaton.sensors, owner="LTLDSPolicy")

    def reset(self, obs: Any, info: Mapping[str, Any]) -> None:
        """Start an episode: locate the automaton from the first reading (cuts are kept)."""
        x = self._state(obs)
        self._mode = self.replanner.reset(self._sensors(info))
        self._next = self.replanner.next_mode()
        self._x, self._v, self._entry = x, None, x.copy()
        self.events = []
        self._step = 0

    def _jumped(self, x: np.ndarray) -> bool:
        if self.dt is None or self._x is None or self._v is None:
            return False
        step = self.dt * float(np.linalg.norm(self._v))
        return float(np.linalg.norm(x - self._x)) > step * (1 + 1e-3) + JUMP_TOL

    def observe(self, obs: Any, info: Mapping[str, Any]) -> str:
        """Track a reading without acting (e.g. the final one of an episode); returns the current mode.

        A mode change since the last call is classified as planned, push or
        invariance failure (which, with modulation, adds a cut).
        """
        if self._mode is None:
            self.reset(obs, info)
        x = self._state(obs)
        pushed = boolean(info.get("perturbed", False), "info['perturbed']", owner="LTLDSPolicy") or self._jumped(x)
        prev_mode, prev_next, prev_x = self._mode, self._next, self._x
        mode: str | None
        try:
            mode = self.replanner.update(self._sensors(info))
        except UnknownSensorReading:
            mode = prev_mode  # a reading no mode explains: keep acting in the tracked mode
        assert mode is not None and prev_mode is not None and prev_x is not None
        if mode != prev_mode:
            kind = "push" if pushed else ("planned" if mode == prev_next else "failure")
            added = False
            if kind == "failure":
                added = self._learn(prev_mode, prev_x, x)
            self.events.append(ModeEvent(self._step, prev_mode, mode, kind, prev_x.copy(), x.copy(), added))
            self._entry = x.copy()
        self._mode = mode
        self._next = self.replanner.next_mode()
        self._x = x
        return mode

    def act(self, obs: Any, info: Mapping[str, Any]) -> np.ndarray:
        """The velocity command (float32 ``(d,)``) for the current state; learns a cut on an invariance failure."""
        mode = self.observe(obs, info)
        assert self._x is not None
        v = self.flow(self._x[None], mode)[0]
        self._v = v
        self._step += 1
        return v.astype(np.float32)

    def _learn(self, mode: str, last_in: np.ndarray, failure: np.ndarray) -> bool:
        """Record an invariance failure of ``mode``; with modulation, re-solve that mode's cuts."""
        assert self._entry is not None
        record = FailureRecord(last_in.copy(), failure.copy(), self._entry.copy())
        records = [*self.failures[mode], record]
        self.failures[mode] = records
        if not self.modulation:
            return False
        try:
            cuts = resolve_cuts(records, self.dynamics[mode].attractor, self.margin)
        except ValueError as err:
            records.pop()
            warnings.warn(
                f"LTLDSPolicy: no cut for this failure of mode {mode!r} ({err})", RuntimeWarning, stacklevel=3
            )
            return False
        self.cut_sets[mode].set_cuts(cuts)
        return True


def repeated_failures(policy: LTLDSPolicy) -> int:
    """Invariance failures that crossed a cut learned from the earlier failures of their mode.

    The cuts are re-solved from the failures recorded before each one (what a
    policy with modulation had at that moment; without modulation what it would
    have had): a failure whose last in-mode state was inside those cuts and
    whose failure state lies beyond one of them is a failure experienced again.
    With modulation the thesis's guarantee says there are none.
    """
    repeats = 0
    for mode, records in policy.failures.items():
        attractor = policy.dynamics[mode].attractor
        for k in range(1, len(records)):
            try:
                cuts = CutSet(attractor, resolve_cuts(records[:k], attractor, policy.margin))
            except ValueError:
                continue  # no cut for an earlier failure (the policy skipped it too)
            last, fail = records[k].last_in_mode[None], records[k].failure[None]
            repeats += bool(cuts.inside(last)[0] and not cuts.inside(fail)[0])
    return repeats
