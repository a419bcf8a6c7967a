"""``SteeringWrapper``: the env's action becomes the user's interaction; a frozen policy plans, a sampler steers.

ITPS (thesis ch. 2) keeps the policy frozen and lets a user steer it at
inference time. Wrapped this way, an env is driven by *interactions*: each
:meth:`SteeringWrapper.step` takes a :class:`~steer_envs.core.interaction.Point`,
``Sketch`` or ``Nudge`` (or ``None``: no steering), samples a batch of plans from
the policy with the sampler (:mod:`steer_envs.steering`) and executes
the chosen plan's waypoints (its action chunk) in the wrapped env, one inner
step per waypoint. A simulated user, a person or an RL agent can drive it.

Spaces:

* ``observation_space`` is the wrapped env's (the state after the chunk).
* ``action_space`` is an :class:`InteractionSpace` (``None`` or an interaction
  of the env's action dimension) by default. With ``sketch_points=G`` it is a
  ``Box`` of ``G * d`` numbers in the env's action bounds, read as a sketch
  ``(G, d)``: the flattened fixed-length sketch stable-baselines3 agents need.

``info`` (besides the last inner step's keys): ``plans`` ``(n, H, d)``,
``costs`` ``(n,)``, ``chosen``, ``plan_collides`` ``(n,)`` (when the env has
``plan_collides``), ``executed`` (the waypoints sent), ``sampler``,
``latency_ms``, ``perturbed_state`` (OP moved the agent there with
``env.unwrapped.perturb``) and ``constraint_violation`` (any inner step violated).
Reward is the sum of the inner rewards; the episode ends when an inner step
terminates or truncates. A policy with ``exec_start = k`` (LeRobot's DP: 1,
its ``plan[0]`` restates the current position) has ``plan[k:]`` executed.

Observation histories: a policy with ``n_obs_steps > 1`` (LeRobot's DP: 2)
receives the last ``n_obs_steps`` observations stacked ``(n_obs_steps, obs_dim)``
(the first one repeated after a reset), others the current observation; see
:func:`~steer_envs.steering.policy_observation`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from steer_envs.core.env import HasInteractionKinds, perturbable_env
from steer_envs.core.interaction import Interaction, Nudge, Point, Sketch
from steer_envs.core.policy import TrajectoryPolicy
from steer_envs.core.validation import describe, integer, real_array
from steer_envs.steering import (
    MAX_BATCH,
    OutputPerturbation,
    RandomSampling,
    Sampler,
    place_observation,
    policy_observation,
)
from steer_envs.utils.threads import limit_threads
from steer_envs.wrappers.constructor_args import record_constructor_args

__all__ = ["InteractionSpace", "SteeringWrapper"]

_KIND_CLASSES: dict[str, type] = {"point": Point, "sketch": Sketch, "nudge": Nudge}
#: the most points of a flattened sketch action (``sketch_points``).
MAX_SKETCH_POINTS = 100_000


class InteractionSpace(spaces.Space[Any]):
    """``None`` or a Point/Sketch/Nudge of dimension ``d`` (the kinds the env supports).

    :meth:`sample` draws a straight sketch (or a point / one-state nudge when
    sketches are not allowed) between uniform points of ``[low, high]``.
    """

    def __init__(
        self,
        low: Any,
        high: Any,
        kinds: Sequence[str] = ("point", "sketch", "nudge"),
        *,
        sketch_points: int = 16,
        seed: int | None = None,
    ) -> None:
        lo = real_array(low, "`low`", finite=False, owner="InteractionSpace").reshape(-1)
        hi = real_array(high, "`high`", finite=False, owner="InteractionSpace").reshape(-1)
        if lo.shape != hi.shape or lo.size < 1 or not np.all(np.isfinite(lo)) or not np.all(hi >= lo):
            raise ValueError(f"`low`/`high` must be finite vectors of one shape with low <= high, got {lo}, {hi}")
        if isinstance(kinds, str) or not all(isinstance(k, str) for k in kinds):
            raise ValueError(f"`kinds` must be a non-empty subset of {sorted(_KIND_CLASSES)}, got {kinds!r}")
        unknown = set(kinds) - set(_KIND_CLASSES)
        if not kinds or unknown:
            raise ValueError(f"`kinds` must be a non-empty subset of {sorted(_KIND_CLASSES)}, got {kinds!r}")
        self.low, self.high = lo, hi
        self.kinds = tuple(kinds)
        self.sketch_points = integer(
            sketch_points, "sketch_points", low=2, high=MAX_SKETCH_POINTS, owner="InteractionSpace"
        )
        super().__init__(shape=None, dtype=None, seed=seed)

    @property
    def dim(self) -> int:
        """State dimension ``d`` of the interactions."""
        return int(self.low.size)

    @property
    def is_np_flattenable(self) -> bool:
        return False

    def contains(self, x: Any) -> bool:
        if x is None:
            return True
        return isinstance(x, Point | Sketch | Nudge) and x.kind in self.kinds and x.dim == self.dim

    def sample(self, mask: Any = None, probability: Any = None) -> Interaction:
        if mask is not None or probability is not None:
            raise ValueError("InteractionSpace.sample does not support `mask` or `probability`")
        a, b = self.np_random.uniform(self.low, self.high, size=(2, self.dim))
        if "sketch" in self.kinds:
            return Sketch(a + np.linspace(0.0, 1.0, self.sketch_points)[:, None] * (b - a))
        if "point" in self.kinds:
            return Point(b)
        return Nudge(b[None])

    def __repr__(self) -> str:
        return f"InteractionSpace(dim={self.dim}, kinds={self.kinds})"

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, InteractionSpace)
            and self.kinds == other.kinds
            and np.array_equal(self.low, other.low)
            and np.array_equal(self.high, other.high)
        )


def _check_arguments(policy: Any, sampler: Any, unsteered: Any, batch: Any, execute: Any, sketch_points: Any) -> None:
    """Refuse :class:`SteeringWrapper` arguments that can never work (its docstring says which)."""
    if not isinstance(policy, TrajectoryPolicy):
        raise TypeError(f"`policy` must be a TrajectoryPolicy (horizon, action_dim, sample), got {policy!r}")
    if not isinstance(sampler, Sampler):
        raise TypeError(f"`sampler` must be a Sampler (RS, PR, OP, BI, GD, SS), got {type(sampler).__name__}")
    if unsteered is not None and not isinstance(unsteered, Sampler):
        raise TypeError(f"`unsteered` must be a Sampler or None, got {type(unsteered).__name__}")
    # a diffusion sampler given a policy that is no DiffusionPolicyLike / FlowPolicyLike would fail at every step
    sampler.check_policy(policy)
    if unsteered is not None:
        unsteered.check_policy(policy)
    if isinstance(batch, bool) or not isinstance(batch, (int, np.integer)):
        raise TypeError(f"SteeringWrapper: `batch` must be a positive integer, got {describe(batch)}")
    if not 1 <= batch <= MAX_BATCH:
        raise ValueError(f"SteeringWrapper: `batch` must be a positive integer <= {MAX_BATCH}, got {batch!r}")
    if execute is not None and (isinstance(execute, bool) or not isinstance(execute, (int, np.integer))):
        raise TypeError(f"`execute` must be a positive int or None, got {execute!r}")
    if execute is not None and execute < 1:
        raise ValueError(f"`execute` must be >= 1, got {execute!r}")
    if sketch_points is not None and (
        isinstance(sketch_points, bool) or not isinstance(sketch_points, (int, np.integer))
    ):
        raise TypeError(
            f"SteeringWrapper: `sketch_points` must be an integer >= 2 or None, got {describe(sketch_points)}"
        )
    if sketch_points is not None and not 2 <= sketch_points <= MAX_SKETCH_POINTS:
        raise ValueError(
            f"SteeringWrapper: `sketch_points` must be an integer in [2, {MAX_SKETCH_POINTS}] or None, "
            f"got {sketch_points!r}"
        )


class SteeringWrapper(gym.Wrapper[Any, Any, Any, Any], gym.utils.RecordConstructorArgs):
    """Drive ``env`` with user interactions; ``policy`` plans, ``sampler`` steers (see the module docstring).

    Args:
        env: an env whose action is the next state/waypoint the policy plans
            (e.g. ``steer_envs/Maze2D-Large-v0``).
        policy: a :class:`~steer_envs.core.policy.TrajectoryPolicy` (a
            ``DiffusionPolicyLike`` or ``FlowPolicyLike`` for BI/GD/SS) planning in the env's action space.
        sampler: the steering strategy used for non-``None`` actions.
        batch: plans sampled per step (ITPS: 32).
        execute: waypoints of the chosen plan executed per step (default: all).
        sketch_points: use a ``Box`` action of ``sketch_points * d`` numbers (a flattened sketch).
        unsteered: sampler for ``None`` actions (default :class:`RandomSampling`).
        threads: torch threads for the steering call (default 1: on a shared machine more
            threads are often far slower; ``None`` leaves torch's setting alone).

    Arguments that can never work are refused here: a diffusion sampler (BI/GD/SS)
    with a policy that is neither ``DiffusionPolicyLike`` nor ``FlowPolicyLike``, ``batch`` outside
    ``[1, MAX_BATCH]``, ``sketch_points`` outside ``[2, MAX_SKETCH_POINTS]``, and
    sampler knobs are checked by the samplers' constructors. What an action may be
    is said in :meth:`interaction`.

    An :class:`OutputPerturbation` without a collision check gets the env's
    ``is_wall`` (when it has one), so the agent stops before the sketch's first wall.
    The constructor arguments are recorded (``env.spec``) by reference, not
    copied: the policy is shared, not duplicated.

    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import steer_envs
    >>> from steer_envs.core.interaction import Sketch
    >>> from steer_envs.steering import PostHocRanking
    >>> class Straight:  # a stand-in policy: 8 waypoints from the agent toward the maze's top-left free cell
    ...     horizon, action_dim = 8, 2
    ...     def sample(self, obs, n, *, generator=None):
    ...         path = np.linspace(obs[:2], [1.0, 1.0], self.horizon)
    ...         return np.repeat(path[None], n, axis=0) + generator.normal(0.0, 0.05, (n, self.horizon, 2))
    >>> env = SteeringWrapper(gym.make("steer_envs/Maze2D-Umaze-v0"), Straight(), PostHocRanking(), batch=4)
    >>> obs, info = env.reset(seed=0)
    >>> obs, reward, terminated, truncated, info = env.step(Sketch([obs, [1.0, 1.0]]))
    >>> info["plans"].shape, info["sampler"], len(info["executed"])
    ((4, 8, 2), 'PR', 8)
    >>> env.spec.additional_wrappers[0].name
    'SteeringWrapper'
    """

    def __init__(
        self,
        env: gym.Env[Any, Any],
        policy: TrajectoryPolicy,
        sampler: Sampler,
        *,
        batch: int = 32,
        execute: int | None = None,
        sketch_points: int | None = None,
        unsteered: Sampler | None = None,
        threads: int | None = 1,
    ) -> None:
        record_constructor_args(self, locals(), deepcopy=False)
        gym.Wrapper.__init__(self, env)
        _check_arguments(policy, sampler, unsteered, batch, execute, sketch_points)
        inner = env.action_space
        if not isinstance(inner, spaces.Box) or inner.shape != (int(policy.action_dim),):
            raise ValueError(
                f"`env.action_space` must be a Box of shape ({policy.action_dim},) matching policy.action_dim, "
                f"got {inner}"
            )
        base = env.unwrapped
        is_wall = getattr(base, "is_wall", None)  # an optional extra of maze envs, not part of the contract
        if isinstance(sampler, OutputPerturbation) and sampler.collides is None and callable(is_wall):
            sampler = OutputPerturbation(sampler.index, collides=is_wall, obs_at=sampler.obs_at)
        self.policy = policy
        self.sampler = sampler
        self.unsteered = unsteered if unsteered is not None else RandomSampling()
        self.batch = int(batch)
        self.execute = None if execute is None else int(execute)
        self.sketch_points = None if sketch_points is None else int(sketch_points)
        d = int(policy.action_dim)
        declared = base.interaction_kinds if isinstance(base, HasInteractionKinds) else tuple(_KIND_CLASSES)
        self._kinds: tuple[str, ...] = tuple(k for k in declared if k in _KIND_CLASSES) or tuple(_KIND_CLASSES)
        if self.sketch_points is not None:
            self.action_space = spaces.Box(
                np.tile(inner.low, self.sketch_points), np.tile(inner.high, self.sketch_points), dtype=np.float32
            )
        else:
            self.action_space = InteractionSpace(inner.low, inner.high, self._kinds)
        start = getattr(policy, "exec_start", 0)
        if isinstance(start, bool) or not isinstance(start, (int, np.integer)) or not 0 <= start < int(policy.horizon):
            raise ValueError(f"policy.exec_start must be an int in [0, horizon), got {start!r}")
        self._exec_start = int(start)
        self.threads = None if threads is None else integer(threads, "`threads`", low=1, owner="SteeringWrapper")
        self._inner_box: spaces.Box = inner
        self._history: list[Any] = []
        self._rng = np.random.default_rng()
        self._dim = d

    # ------------------------------------------------------------------- API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset the env; ``seed`` also seeds the wrapper's sampling generator (reproducible steering)."""
        obs, info = self.env.reset(seed=seed, options=options)
        if seed is not None:
            self._rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x17B5]))
            self.action_space.seed(int(seed))
        self._history = [obs]
        return obs, info

    def interaction(self, action: Any) -> Interaction | None:
        """The interaction an action stands for (``None``: unsteered); ``TypeError``/``ValueError`` otherwise.

        Accepted: ``None``, or a :class:`Point`, :class:`Sketch` or :class:`Nudge` of the
        env's action dimension whose kind the env declares (``env.unwrapped.interaction_kinds``).
        With ``sketch_points=G`` also a raw array of ``G * d`` finite real numbers (a list,
        numpy array or torch tensor), clipped to the action box and read as a ``(G, d)`` sketch;
        strings, complex numbers, booleans and NaN/inf are refused, not converted.
        """
        if self.sketch_points is not None and action is not None and not isinstance(action, Point | Sketch | Nudge):
            box = self.action_space
            assert isinstance(box, spaces.Box)
            shape = box.shape
            raw = real_array(action, "`action`", finite=False, owner="SteeringWrapper")
            if raw.shape != shape:
                raise ValueError(
                    f"SteeringWrapper: `action` must have shape {shape} (a flattened sketch), got {raw.shape}"
                )
            if not np.all(np.isfinite(raw)):
                raise ValueError("SteeringWrapper: `action` (a flattened sketch) must be finite (no NaN or inf)")
            return Sketch(np.clip(raw, box.low, box.high).reshape(self.sketch_points, self._dim))
        if action is None:
            return None
        if not isinstance(action, Point | Sketch | Nudge):
            raise TypeError(f"`action` must be a Point, Sketch, Nudge or None, got {type(action).__name__}")
        if action.kind not in self._kinds:
            raise ValueError(
                f"SteeringWrapper: the env takes interactions of kinds {list(self._kinds)}, got a {action.kind}"
            )
        return action.validate(self._dim)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Steer one plan with ``action`` and execute its waypoints (see the module docstring)."""
        if not self._history:
            raise gym.error.ResetNeeded("SteeringWrapper.step called before reset()")
        interaction = self.interaction(action)
        sampler = self.sampler if interaction is not None else self.unsteered
        obs_in = policy_observation(self.policy, self._history)
        with limit_threads(blas_threads=None, torch_threads=self.threads):
            result = sampler(self.policy, obs_in, interaction, self.batch, generator=self._rng)
        base = self.env.unwrapped
        if result.perturbed_state is not None:
            pushable = perturbable_env(self.env, who=f"SteeringWrapper ({result.sampler} moves the agent)")
            pushable.perturb(to=result.perturbed_state)
            self._history.append(place_observation(self._history[-1], pushable.state))
        plan = result.plan[self._exec_start :]
        waypoints = plan if self.execute is None else plan[: self.execute]
        box = self._inner_box
        total, violated = 0.0, False
        terminated = truncated = False
        info: dict[str, Any] = {}
        executed = []
        for wp in waypoints:
            a = np.clip(wp, box.low, box.high).astype(box.dtype)
            obs, reward, terminated, truncated, info = self.env.step(a)
            executed.append(a)
            self._history.append(obs)
            total += float(reward)
            violated |= bool(info.get("constraint_violation", False))
            if terminated or truncated:
                break
        self._history = self._history[-max(2, int(getattr(self.policy, "n_obs_steps", 1))) :]
        collides = getattr(base, "plan_collides", None)
        info = dict(info)
        info.update(
            plans=result.plans,
            costs=result.costs,
            chosen=result.chosen,
            plan_collides=np.asarray(collides(result.plans)) if callable(collides) else None,
            executed=np.asarray(executed),
            sampler=result.sampler,
            latency_ms=float(result.timings.get("total_ms", float("nan"))),
            perturbed_state=result.perturbed_state,
            constraint_violation=violated,
        )
        return self._history[-1], total, bool(terminated), bool(truncated), info
