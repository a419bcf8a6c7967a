"""DSModulationWrapper: a gym adapter that learns cuts on invariance failures and modulates velocity actions.

The method lives in :mod:`steer_envs.baselines.lpv_ds`: the cuts and their
QCQP in :mod:`~steer_envs.baselines.lpv_ds.cuts`, the modulation in
:mod:`~steer_envs.baselines.lpv_ds.modulation`. This wrapper only watches the
env's modes, turns an unplanned mode exit into a
:class:`~steer_envs.baselines.lpv_ds.cuts.FailureRecord`, re-solves that mode's
cuts and passes every action through
:func:`~steer_envs.baselines.lpv_ds.modulation.modulate`.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Callable, Iterable, Mapping
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike

from steer_envs.baselines.lpv_ds.cuts import ATTRACTOR_MARGIN, CutSet, FailureRecord, _vec, resolve_cuts
from steer_envs.baselines.lpv_ds.modulation import clip_speed, modulate
from steer_envs.core.env import HasTask, perturbable_env
from steer_envs.core.validation import boolean, describe, integer, real_array, real_scalar
from steer_envs.wrappers.constructor_args import record_constructor_args

__all__ = ["DSModulationWrapper", "PlanFn"]

WHO = "DSModulationWrapper"

PlanFn = Callable[[int, Mapping[str, Any]], Iterable[int] | None]


class DSModulationWrapper(gym.ActionWrapper[Any, Any, Any], gym.utils.RecordConstructorArgs):
    """Modulate any velocity action by learned cuts; learn a cut on every invariance failure.

    The unwrapped env must be a :class:`~steer_envs.core.env.PerturbableEnv`
    (``state`` and ``perturb``) and report ``info["mode"]`` (the 2D kinematic envs do). The agent's action is a
    nominal velocity (from a DS, BC, or anything); the env receives
    ``M(x) action`` for the current mode (nominal where that mode has no
    attractor or no cuts yet).

    **Attractors** come from the constructor: ``attractor`` is either one point
    (used for the mode the env starts in, e.g. ConvexMode's single mode) or a
    mapping ``mode index -> point`` (e.g. the per-mode attractors of
    :mod:`steer_envs.data.segmentation`).

    **The plan.** A mode change ``m -> m'`` during a step is an invariance
    failure unless the plan asked for it: ``plan(m, info)`` (constructor arg)
    returns the modes the plan allows next; by default the wrapper reads
    ``info["plan"]`` of the step before the transition (a mode sequence from
    the current mode, as :class:`~steer_envs.wrappers.LTLReplanWrapper`
    provides; so wrap *around* it: ``DSModulationWrapper(LTLReplanWrapper(env),
    ...)``), and with no plan every exit of a mode is a failure (single-mode
    envs). Exits caused by a push (:meth:`perturb`, or
    ``env.unwrapped.perturb`` noticed as a jump of the state between steps) are
    not failures.

    On a failure the cut through the last in-mode state is added and all cuts
    of that mode are re-solved with the new visited set (the TLI protocol). Cuts
    persist across episodes (that is the learning); :meth:`clear_cuts` forgets.
    ``info`` gains ``invariance_failure``, ``cut_added``, ``num_cuts`` and ``modulated``.

    Args:
        env: a steer-envs kinematic env (possibly wrapped) whose action is a
            velocity of the state's dimension ``d``.
        attractor: one point ``(d,)``, or a mapping mode index -> point.
        plan: optional ``(mode, info) -> allowed next modes`` (mode indices).
        home_mode: the mode a single ``attractor`` belongs to (default: the
            task's initial mode).
        margin: radius around each attractor every cut keeps inside (a real number >= 0).
        learn: add cuts on failures (``False``: only apply the given ``cuts``); a bool.
        cuts: optional initial ``{mode: CutSet}`` (extended in place as cuts are learned).

    Arguments that could never work are refused here: an attractor or cut set of
    another dimension than the state, a mode index (int) the task does not have.

    The constructor arguments are recorded (``env.spec``) as given, ``cuts`` as
    a copy taken before any learning.

    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import steer_envs
    >>> env = DSModulationWrapper(gym.make("steer_envs/ConvexMode-v0", layout_seed=0), attractor=[0.0, 0.0])
    >>> obs, info = env.reset(seed=0)
    >>> obs, reward, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
    >>> info["num_cuts"], info["invariance_failure"]
    (0, False)
    >>> env.spec.additional_wrappers[0].kwargs["margin"]
    0.4
    """

    def __init__(
        self,
        env: gym.Env,
        attractor: ArrayLike | Mapping[int, ArrayLike],
        *,
        plan: PlanFn | None = None,
        home_mode: int | None = None,
        margin: float = ATTRACTOR_MARGIN,
        learn: bool = True,
        cuts: Mapping[int, CutSet] | None = None,
    ) -> None:
        # `plan` may be a bound method: record it, do not copy its owner (the cuts are copied)
        record_constructor_args(self, locals(), deepcopy=False, cuts=copy.deepcopy(cuts))
        gym.ActionWrapper.__init__(self, env)
        who = WHO
        base = perturbable_env(env, who=who)
        self._base = base
        if plan is not None and not callable(plan):
            raise TypeError(f"plan must be None or a callable (mode, info) -> modes, got {type(plan).__name__}")
        margin = real_scalar(margin, "margin", low=0.0, owner=who)
        learn = boolean(learn, "learn", owner=who)
        self.max_speed: float | None = getattr(base, "max_speed", None)
        self.dt: float | None = getattr(base, "dt", None)
        task = base.task if isinstance(base, HasTask) else None
        self._task = task
        # the velocity is a state derivative: attractors, cuts and actions live in the state's space
        self.dim = int(np.asarray(base.state).reshape(-1).size)
        space = env.action_space
        if isinstance(space, gym.spaces.Box) and space.shape != (self.dim,):
            raise ValueError(
                f"{who}: the env's action must be a velocity of the state's dimension ({self.dim},), "
                f"got an action space of shape {space.shape}"
            )
        self._num_modes = len(task.modes) if task is not None else None
        self.attractors = self._attractors(attractor, home_mode)
        self.plan_fn = plan
        self.margin = margin
        self.learn = learn
        self.cut_sets: dict[int, CutSet] = self._initial_cuts(cuts)
        self.failures: dict[int, list[FailureRecord]] = {}
        self._mode: int | None = None
        self._entry: np.ndarray | None = None
        self._state: np.ndarray | None = None
        self._info: dict[str, Any] = {}
        self._modulated = False
        self._warned_plan = False

    # ------------------------------------------------------------ helpers
    def _mode_index(self, value: Any, name: str) -> int:
        """A mode index of the env's task (any int >= 0 when the env has no task)."""
        num_modes = self._num_modes
        return integer(value, name, low=0, high=None if num_modes is None else num_modes - 1, owner=WHO)

    def _attractors(
        self, attractor: ArrayLike | Mapping[int, ArrayLike], home_mode: int | None
    ) -> dict[int, np.ndarray]:
        """Mode index -> attractor from the constructor's ``attractor`` (one point or a mapping) and ``home_mode``."""
        if isinstance(attractor, Mapping):
            if not attractor:
                raise ValueError(f"{WHO}: attractor must map at least one mode index to a point")
            return {
                self._mode_index(m, "attractor key (mode index)"): self._point(a, f"attractor[{m!r}]")
                for m, a in attractor.items()
            }
        task = self._task
        if home_mode is None:
            home_mode = task.mode_index(task.initial or task.modes[0]) if task is not None else 0
        return {self._mode_index(home_mode, "home_mode"): self._point(attractor, "attractor")}

    def _initial_cuts(self, cuts: Mapping[int, CutSet] | None) -> dict[int, CutSet]:
        """The constructor's ``cuts`` checked against the state's dimension and the task's modes."""
        if cuts is not None and not isinstance(cuts, Mapping):
            raise TypeError(f"{WHO}: cuts must be None or a mapping mode index -> CutSet, got {describe(cuts)}")
        out: dict[int, CutSet] = {}
        for m, cs in (cuts or {}).items():
            if not isinstance(cs, CutSet):
                raise TypeError(f"cuts[{m}] must be a CutSet, got {type(cs).__name__}")
            if cs.dim != self.dim:
                raise ValueError(f"{WHO}: cuts[{m!r}] has dimension {cs.dim}, the state has {self.dim}")
            out[self._mode_index(m, "cuts key (mode index)")] = cs
        return out

    def _point(self, value: Any, name: str) -> np.ndarray:
        """An attractor: a finite point of the state's dimension."""
        arr = _vec(value, f"DSModulationWrapper: {name}")
        if arr.shape != (self.dim,):
            raise ValueError(f"DSModulationWrapper: {name} must have the state's shape ({self.dim},), got {arr.shape}")
        return arr

    def attractor_of(self, mode: int) -> np.ndarray | None:
        """The attractor of ``mode`` (None: that mode is not modulated and learns no cuts)."""
        return self.attractors.get(int(mode))

    def clear_cuts(self) -> None:
        """Forget every learned cut and failure."""
        self.cut_sets.clear()
        self.failures.clear()

    @property
    def num_cuts(self) -> int:
        """Cuts over all modes."""
        return sum(len(c) for c in self.cut_sets.values())

    def _planned(self, mode: int, info: Mapping[str, Any]) -> set[int] | None:
        """Modes the plan allows after ``mode`` (None: no plan, every exit is a failure)."""
        if self.plan_fn is not None:
            nxt = self.plan_fn(mode, info)
            if nxt is None:
                return None
            if isinstance(nxt, (str, bytes)) or not isinstance(nxt, Iterable):
                raise TypeError(
                    f"DSModulationWrapper: plan(mode, info) must return mode indices or None, got {describe(nxt)}"
                )
            return {integer(m, "plan(mode, info) entry", owner="DSModulationWrapper") for m in nxt}
        plan = info.get("plan")
        if plan is None:
            return None
        names = tuple(self._task.modes) if self._task is not None else ()
        if any(isinstance(m, str) and m not in names for m in plan):
            if not self._warned_plan:
                warnings.warn(
                    f"info['plan'] {list(plan)} names modes the env's task does not have {names}; pass `plan=`",
                    RuntimeWarning,
                    stacklevel=3,
                )
                self._warned_plan = True
            return None
        seq = [names.index(m) if isinstance(m, str) else int(m) for m in plan]
        if mode in seq:
            i = seq.index(mode)
            return set(seq[i + 1 : i + 2])
        return set(seq[:1])

    def _track(self, info: Mapping[str, Any], *, entered: bool) -> None:
        mode = int(info["mode"])
        state = np.asarray(self._base.state, dtype=np.float64)
        if entered or mode != self._mode:
            self._entry = state.copy()
        self._mode, self._state, self._info = mode, state, dict(info)

    def _extra(self, info: Mapping[str, Any], failure: bool, added: bool) -> dict[str, Any]:
        return dict(
            info, invariance_failure=failure, cut_added=added, num_cuts=self.num_cuts, modulated=self._modulated
        )

    # --------------------------------------------------------------- API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self._modulated = False
        self._track(info, entered=True)
        return obs, self._extra(info, False, False)

    def perturb(self, delta: ArrayLike | None = None, *, to: ArrayLike | None = None) -> dict[str, Any]:
        """Push the agent (``env.unwrapped.perturb``); a mode exit caused by a push is not a failure."""
        info = self._base.perturb(delta, to=to)
        self._track(info, entered=False)
        return info

    def action(self, action: Any) -> np.ndarray:
        """The modulated velocity for the current state and mode (float32).

        ``action`` is a finite real velocity of the state's shape ``(d,)`` (a list, a
        numpy array or a torch tensor, detached); strings, complex numbers, booleans,
        NaN/inf and other shapes are refused (``TypeError``/``ValueError``).
        """
        v = real_array(action, "action", shape=(self.dim,), owner="DSModulationWrapper")
        self._modulated = False
        cuts = self.cut_sets.get(self._mode) if self._mode is not None else None
        if cuts is None or len(cuts) == 0:
            return v.astype(np.float32)  # nothing to modulate
        x = np.asarray(self._base.state, dtype=np.float64)
        out = modulate(x[None], v[None], cuts, self.max_speed)[0]
        nominal = clip_speed(v[None], self.max_speed)[0] if self.max_speed is not None else v
        self._modulated = not np.allclose(out, nominal)
        return out.astype(np.float32)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        before = np.asarray(self._base.state, dtype=np.float64)
        pushed = self._state is not None and not np.array_equal(before, self._state)
        prev_mode, prev_info, entry = self._mode, self._info, self._entry
        obs, reward, terminated, truncated, info = self.env.step(self.action(action))
        after = np.asarray(self._base.state, dtype=np.float64)
        mode = int(info["mode"])
        failure = added = False
        # a push through env.unwrapped.perturb (not our perturb) makes the pre-step mode unknown: no verdict
        if not pushed and prev_mode is not None and mode != prev_mode:
            planned = self._planned(prev_mode, prev_info)
            failure = planned is None or mode not in planned
            if failure and self.learn and self.attractor_of(prev_mode) is not None and entry is not None:
                added = self._add_failure(prev_mode, before, after, entry)
        # after an unseen push the entry state is unknown: the first state we see again stands in for it
        self._track(info, entered=pushed)
        return obs, reward, terminated, truncated, self._extra(info, failure, added)

    def _add_failure(self, mode: int, last_in: np.ndarray, fail: np.ndarray, entry: np.ndarray) -> bool:
        att = self.attractor_of(mode)
        assert att is not None
        records = [*self.failures.get(mode, []), FailureRecord(last_in.copy(), fail.copy(), entry.copy())]
        try:
            cuts = resolve_cuts(records, att, self.margin)
        except ValueError as err:
            warnings.warn(f"DSModulationWrapper: no cut for this failure ({err})", RuntimeWarning, stacklevel=3)
            return False
        self.failures[mode] = records
        self.cut_sets.setdefault(mode, CutSet(att)).set_cuts(cuts)
        if self.dt is not None and self.max_speed is not None:
            h = self.cut_sets[mode].arrays()[2]
            if h.min() <= self.dt * self.max_speed:
                warnings.warn(
                    f"a cut is {h.min():.3g} from the attractor, not more than dt * max_speed = "
                    f"{self.dt * self.max_speed:.3g}: the discrete-time no-crossing guarantee does not hold",
                    RuntimeWarning,
                    stacklevel=3,
                )
        return True
