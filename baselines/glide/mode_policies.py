"""Policies of GLiDE's 2D navigation study (thesis §4.2 "Mode-based motion generation", Table 4.1).

All policies are batched: ``act(states (N, 2)) -> velocities (N, 2)`` for the
``N`` agents of a vector env, and ``reset(mask)`` forgets the per-agent plan of
the agents whose episodes restart.

* BC -- mode-agnostic behaviour cloning: a
  :class:`~steer_envs.baselines.bc.modeling.BCPolicy` with
  :class:`GlideBCConfig`, fitted to every (state, action) pair of the
  successful demonstrations (:func:`train_bc`).
* :class:`GlideBCPolicy` -- GLiDE+BC: the classifier labels the demos' states
  with modes, one BC policy per mode, chosen by the classifier's current mode,
  plus a pseudo-attractor (the mean state where the demos enter the next mode;
  in the final mode, the mean state where they end) that pulls the agent back
  toward the demonstrations when it is farther from the attractor than most
  demo states of its mode. Built on GLiDE+BC's shared core
  (:class:`~steer_envs.baselines.glide.glide_bc.GlideBC`), as the arms'
  :class:`~steer_envs.baselines.glide.arm_policies.GlideArmPolicy` is.
* :class:`GlidePlanningPolicy` -- GLiDE+Planning: a waypoint per mode (the
  mean first-entry state of the mode in the demos); from mode ``k`` the agent
  moves to the waypoint of mode ``k + 1`` staying inside the learned modes
  ``{k, k + 1}``, so the only transition it makes is the allowed ``k -> k + 1``:
  a straight line where the learned modes allow it, otherwise a path through
  the learned free space (:mod:`~steer_envs.baselines.glide.planners`: the
  exposure-weighted costmap path by default, or the thesis's RRT), and the
  potential field when neither finds one. In the final mode it heads for the
  demos' goal (their mean last state) inside that mode, so a learned boundary
  short of the true one does not stop the agent early.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from steer_envs.baselines.bc import modeling as bc
from steer_envs.baselines.glide.glide_bc import GlideBC
from steer_envs.baselines.glide.modes import ModePredictor, label_demonstrations
from steer_envs.baselines.glide.planners import LearnedModeMap, PlannerConfig, potential_field, rrt
from steer_envs.core.validation import integer, real_array, real_scalar
from steer_envs.data.segmentation import segment_demonstration

__all__ = [
    "GlideBCConfig",
    "GlideBCPolicy",
    "GlidePlanningPolicy",
    "mean_end_state",
    "mode_entry_points",
    "train_bc",
]


# --------------------------------------------------------------------------------- BC
@dataclass(frozen=True)
class GlideBCConfig(bc.BCConfig):
    """:class:`~steer_envs.baselines.bc.modeling.BCConfig` with the settings of GLiDE's BC policies as defaults.

    A 2 x 128 ReLU MLP on standardised states predicts the action in units of
    the env's speed limit, whose norm is clipped to it (``output="clip"``;
    :func:`train_bc` sets ``output_scale`` to the env's limit and the
    dimensions from the data); training draws ``steps`` minibatches of 256 with
    replacement.

    >>> GlideBCConfig().hidden, GlideBCConfig(steps=600).steps, GlideBCConfig().epochs
    ((128, 128), 600, None)
    """

    hidden: tuple[int, ...] = (128, 128)
    output: bc.BCOutput = "clip"
    output_scale: float = 1.0
    standardize: bool = True
    batch_size: int = 256
    epochs: int | None = None
    steps: int | None = 1500


def train_bc(
    states: np.ndarray,
    actions: np.ndarray,
    *,
    max_speed: float,
    seed: int = 0,
    config: bc.BCConfig | None = None,
) -> bc.BCPolicy:
    """A BC policy fitted to pairs ``(N, d)`` / ``(N, a)``, its output limited to ``max_speed``.

    ``config`` (default :class:`GlideBCConfig`) gets the data's dimensions and
    ``output_scale = max_speed``.

    >>> import numpy as np
    >>> s = np.random.default_rng(0).uniform(-1, 1, (50, 2))
    >>> policy = train_bc(s, -0.1 * s, max_speed=0.1, config=GlideBCConfig(steps=20))
    >>> bool(np.all(np.linalg.norm(policy.act(10 * s), axis=1) <= 0.1 + 1e-12))
    True
    """
    max_speed = real_scalar(max_speed, "max_speed", low=0.0, low_inclusive=False, owner="train_bc")
    real_array(states, "states", owner="train_bc")  # real, finite numbers; the data keep their own dtype
    real_array(actions, "actions", owner="train_bc")
    s, a = np.asarray(states), np.asarray(actions)
    if s.ndim != 2 or a.ndim != 2:
        raise ValueError(f"states and actions must be (N, d) and (N, a) arrays, got shapes {s.shape} and {a.shape}")
    base = config if config is not None else GlideBCConfig()
    cfg = replace(base, state_dim=s.shape[1], action_dim=a.shape[1], output_scale=float(max_speed))
    policy = bc.BCPolicy(cfg, seed=seed)
    policy.fit(s, a)
    return policy


def _check_predictor(classifier: object, who: str) -> None:
    if not callable(getattr(classifier, "predict", None)):
        raise TypeError(f"{who}: classifier must have predict(states) -> modes, got {type(classifier).__name__}")


# ----------------------------------------------------------------- demo statistics
def mode_entry_points(demos: Sequence[np.ndarray], modes: Sequence[np.ndarray], num_modes: int) -> np.ndarray:
    """Mean first-entry state of each mode ``(K, d)`` over the demos (NaN where never entered).

    Each demo is segmented by its per-step ``modes``
    (:func:`~steer_envs.data.segmentation.segment_demonstration`); row ``k`` is
    the mean, over the demos that enter mode ``k`` from another mode, of the
    first state of their first such segment (GLiDE+Planning's waypoints, the
    pseudo-attractors of GLiDE+BC). A demo's initial segment is not an entry.

    >>> import numpy as np
    >>> demo = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    >>> mode_entry_points([demo], [np.array([0, 1, 1, 2])], 3)
    array([[nan, nan],
           [ 1.,  0.],
           [ 3.,  0.]])
    """
    if len(demos) == 0:
        raise ValueError("demos must not be empty")
    dim = np.asarray(demos[0]).shape[1]
    sums, counts = np.zeros((num_modes, dim)), np.zeros(num_modes)
    for i, (d, m) in enumerate(zip(demos, modes, strict=True)):
        seen: set[int] = set()
        for segment in segment_demonstration(d, np.asarray(m), demo=i)[1:]:
            k = int(segment.mode)  # type: ignore[call-overload]
            if k not in seen:
                seen.add(k)
                sums[k] += segment.entry
                counts[k] += 1
    out = np.full((num_modes, dim), np.nan)
    ok = counts > 0
    out[ok] = sums[ok] / counts[ok, None]
    return out


def mean_end_state(demos: Sequence[np.ndarray]) -> np.ndarray:
    """The mean of the demos' last states ``(d,)``: where they reach the goal (the final mode's target).

    >>> mean_end_state([np.array([[0.0, 0.0], [1.0, 2.0]]), np.array([[3.0, 0.0]])])
    array([2., 1.])
    """
    return np.asarray(np.mean([np.asarray(d, dtype=np.float64)[-1] for d in demos], axis=0))


# --------------------------------------------------------------------------- GLiDE+BC
class GlideBCPolicy(GlideBC[bc.BCPolicy]):
    """GLiDE+BC on PolygonNav: per-mode BC policies chosen by the classifier, with pseudo-attractors.

    The shared part (per-mode training, threshold, blend) is
    :class:`~steer_envs.baselines.glide.glide_bc.GlideBC`; this domain's part:
    the attractor of mode ``k`` is a point, the mean state where the demos
    first enter mode ``k + 1`` (:func:`mode_entry_points`; in the final mode
    the mean end state, :func:`mean_end_state`), and the pull a step of the
    full speed limit toward it. A mode with fewer than 2 demo pairs gets no
    BC policy: the attractor alone moves the agent there.

    Args:
        classifier: the learned mode classifier.
        demos: demo states ``(T_i, d)``; actions: demo actions ``(T_i - 1, 2)``.
        num_modes: ``K``.
        max_speed: the env's speed limit.
        attractor_weight: ``w`` in ``(1 - w) pi_k(s) + w * (step toward the attractor)``.
        attractor_quantile: the attractor acts only beyond this quantile of the
            distances from mode ``k``'s demo states to its attractor.
        seed: seeds the BC training (mode ``k``'s policy gets ``seed + k``).
        config: BC settings (default :class:`GlideBCConfig`).

    >>> import numpy as np
    >>> class LeftRight:  # mode 1 right of x = 0
    ...     def predict(self, s): return (np.asarray(s)[:, 0] > 0).astype(int)
    >>> demo = np.stack([np.linspace(-1, 1, 21), np.zeros(21)], axis=1)
    >>> policy = GlideBCPolicy(LeftRight(), [demo], [np.diff(demo, axis=0)], 2, max_speed=0.1,
    ...                        config=GlideBCConfig(steps=20))
    >>> policy.act(demo[:3]).shape
    (3, 2)
    """

    def __init__(
        self,
        classifier: ModePredictor,
        demos: Sequence[np.ndarray],
        actions: Sequence[np.ndarray],
        num_modes: int,
        *,
        max_speed: float,
        attractor_weight: float = 0.5,
        attractor_quantile: float = 0.9,
        seed: int = 0,
        config: bc.BCConfig | None = None,
    ) -> None:
        if len(demos) != len(actions) or not demos:
            raise ValueError(
                f"demos and actions must be non-empty and of equal length, got {len(demos)} and {len(actions)}"
            )
        who = "GlideBCPolicy"
        super().__init__(num_modes, attractor_weight=attractor_weight, owner=who)
        attractor_quantile = real_scalar(
            attractor_quantile, "attractor_quantile", low=0.0, high=1.0, low_inclusive=False, owner=who
        )
        _check_predictor(classifier, who)
        self.classifier = classifier
        self.max_speed = real_scalar(max_speed, "max_speed", low=0.0, low_inclusive=False, owner=who)
        seed = integer(seed, "seed", owner=who)
        modes = label_demonstrations(classifier, demos, self.num_modes)
        states = np.concatenate([np.asarray(d, dtype=np.float64)[:-1] for d in demos])
        acts = np.concatenate([np.asarray(a, dtype=np.float64) for a in actions])
        state_modes = np.concatenate([m[:-1] for m in modes])
        if len(states) != len(acts):
            raise ValueError(f"every demo needs T - 1 actions for its T states, got {len(acts)} for {len(states)}")

        def fit(s: np.ndarray, a: np.ndarray, k: int) -> bc.BCPolicy | None:
            return train_bc(s, a, max_speed=max_speed, seed=seed + k, config=config) if len(s) >= 2 else None

        self.fit_modes(states, acts, state_modes, fit)
        self._set_attractors(demos, modes, states, state_modes, attractor_quantile)

    def _set_attractors(
        self,
        demos: Sequence[np.ndarray],
        modes: Sequence[np.ndarray],
        states: np.ndarray,
        state_modes: np.ndarray,
        quantile: float,
    ) -> None:
        """Mode ``k``'s attractor: where the demos enter mode ``k + 1``; in the final mode, where they end."""
        entries = mode_entry_points(demos, modes, self.num_modes)
        goal = mean_end_state(demos)
        self.attractors = np.full((self.num_modes, states.shape[1]), np.nan)
        self.thresholds = np.full(self.num_modes, np.inf)
        for k in range(self.num_modes):
            sel = state_modes == k
            target = entries[k + 1] if k + 1 < self.num_modes else goal
            if np.all(np.isfinite(target)):
                self.attractors[k] = target
                if sel.any():
                    self.thresholds[k] = self.threshold(np.linalg.norm(states[sel] - target, axis=1), quantile)

    def act(self, states: np.ndarray) -> np.ndarray:
        """Velocities ``(N, 2)``: each agent's mode policy, pulled toward its attractor when far from the demos."""
        x = np.asarray(states, dtype=np.float64)
        mode = np.asarray(self.classifier.predict(x), dtype=np.int64)
        out = np.zeros_like(x)
        for k in np.unique(mode):
            sel = mode == k
            policy = self.policies[k]
            v = policy.act(x[sel]) if policy is not None else np.zeros((int(sel.sum()), x.shape[1]))
            attractor = self.attractors[k]
            if np.all(np.isfinite(attractor)):
                delta = attractor - x[sel]
                dist = np.linalg.norm(delta, axis=1, keepdims=True)
                pull = delta / np.maximum(dist, 1e-12) * self.max_speed
                far = dist[:, 0] > self.thresholds[k]
                v[far] = self.blend(v[far], pull[far])
                if policy is None:  # no demo states in this mode: the attractor alone
                    v = pull
            out[sel] = v
        return bc.clip_speed(out, self.max_speed)

    def reset(self, mask: np.ndarray | None = None) -> None:
        """Stateless: the mode is read from the classifier at every step."""


# ---------------------------------------------------------------------- GLiDE+Planning
class GlidePlanningPolicy:
    """GLiDE+Planning over the learned modes (see the module docstring).

    Args:
        classifier: the learned mode classifier.
        demos: demo states (labelled by the classifier for the waypoints).
        num_modes: ``K``.
        low, high: workspace corners.
        max_speed: the env's speed limit (one env step moves at most this far).
        seed: seeds the RRT.
        config: planner settings.

    Attributes:
        stats: how often each planner produced the plan (``straight``, ``costmap``, ``rrt``, ``field``).

    >>> import numpy as np
    >>> class LeftRight:  # mode 1 right of x = 0
    ...     def predict(self, s): return (np.asarray(s)[:, 0] > 0).astype(int)
    >>> demo = np.stack([np.linspace(-1, 1, 21), np.zeros(21)], axis=1)
    >>> policy = GlidePlanningPolicy(LeftRight(), [demo], 2, low=np.full(2, -2.0), high=np.full(2, 2.0),
    ...                              max_speed=0.1, config=PlannerConfig(grid_resolution=0.1))
    >>> v = policy.act(np.array([[-1.0, 0.5]]))
    >>> bool(v[0, 0] > 0), bool(np.linalg.norm(v) <= 0.1 + 1e-12)  # heads right, to mode 1's waypoint
    (True, True)
    """

    def __init__(
        self,
        classifier: ModePredictor,
        demos: Sequence[np.ndarray],
        num_modes: int,
        *,
        low: np.ndarray,
        high: np.ndarray,
        max_speed: float,
        seed: int = 0,
        config: PlannerConfig | None = None,
    ) -> None:
        who = "GlidePlanningPolicy"
        if config is not None and not isinstance(config, PlannerConfig):
            raise TypeError(f"{who}: config must be a PlannerConfig or None, got {type(config).__name__}")
        _check_predictor(classifier, who)
        if len(demos) == 0:
            raise ValueError(f"{who}: demos must not be empty")
        self.config = config or PlannerConfig()
        self.num_modes = integer(num_modes, "num_modes", low=1, owner=who)
        self.max_speed = real_scalar(max_speed, "max_speed", low=0.0, low_inclusive=False, owner=who)
        self.low = real_array(low, "low", shape=(2,), owner=who)
        self.high = real_array(high, "high", shape=(2,), owner=who)
        seed = integer(seed, "seed", owner=who)
        self.map = LearnedModeMap(classifier, self.low, self.high, self.config.grid_resolution)
        modes = label_demonstrations(classifier, demos, self.num_modes)
        self.waypoints = mode_entry_points(demos, modes, self.num_modes)
        # a mode the demos never entered (a wrong plan, a poor classifier): aim at the demos' end
        ends = mean_end_state(demos)
        for k in range(1, self.num_modes):
            if not np.all(np.isfinite(self.waypoints[k])):
                self.waypoints[k] = ends
            # the mean of entry points can fall outside a curved learned region: an agent would reach it
            # still in mode k - 1 and stop there; aim at the nearest point the classifier labels k instead
            self.waypoints[k] = self.map.nearest_in(self.waypoints[k], k)
        #: where the demos end (the mean of their last states): the target inside the final mode, so an
        #: agent that the classifier already places in the final mode still walks into the demos' goal
        #: region instead of stopping on a learned boundary that lies short of the true one
        self.goal = ends
        self.rng = np.random.default_rng(seed)
        self._plans: list[list[np.ndarray]] = []
        self._plan_mode: np.ndarray = np.zeros(0, dtype=np.int64)
        self._expected: np.ndarray = np.zeros((0, 2))
        self.stats = {"straight": 0, "costmap": 0, "rrt": 0, "field": 0}

    def planned_path(self, agent: int = 0) -> np.ndarray:
        """The waypoints agent ``agent`` still has to follow, ``(P, 2)`` (a copy; ``(0, 2)``: none, e.g. before
        the first :meth:`act`, after :meth:`reset`, or while the potential field steers).

        The path is planned on a mode change or a push and shortened as waypoints are reached; a viewer
        draws it (steer-ui's PolygonNav domain).

        >>> class AllOne:
        ...     def predict(self, s): return np.ones(len(s), dtype=int)
        >>> demo = np.stack([np.linspace(-1, 1, 5), np.zeros(5)], axis=1)
        >>> policy = GlidePlanningPolicy(AllOne(), [demo], 2, low=np.full(2, -2.0), high=np.full(2, 2.0), max_speed=0.1)
        >>> policy.planned_path().shape
        (0, 2)
        >>> _ = policy.act(np.array([[-1.0, 0.5]]))  # in the final mode: straight to where the demos end
        >>> policy.planned_path().tolist()
        [[1.0, 0.0]]
        """
        agent = integer(agent, "agent", low=0, owner="GlidePlanningPolicy.planned_path")
        if agent >= len(self._plans) or not self._plans[agent]:
            return np.zeros((0, 2))
        return np.array(self._plans[agent], dtype=np.float64).reshape(-1, 2)

    def reset(self, mask: np.ndarray | None = None) -> None:
        """Forget the plans of the agents in ``mask`` (all when None)."""
        if mask is None:
            self._plans = []
            return
        for i in np.flatnonzero(np.asarray(mask, dtype=bool)):
            if i < len(self._plans):
                self._plans[i] = []
                self._plan_mode[i] = -1

    def _target(self, mode: int) -> tuple[np.ndarray, frozenset[int]]:
        """The point an agent in ``mode`` heads for and the learned modes it may cross on the way."""
        if mode >= self.num_modes - 1:
            return self.goal, frozenset({self.num_modes - 1})
        return self.waypoints[mode + 1], frozenset({mode, mode + 1})

    def _plan(self, x: np.ndarray, mode: int) -> list[np.ndarray]:
        goal, allowed = self._target(mode)
        cfg = self.config
        if mode == 0 and cfg.free_space_planner == "costmap":
            path = self.map.shortest_path(x, goal, allowed, cfg.exposure_weight, cfg.exposure_radius, cfg.check_spacing)
            if path is not None:
                self.stats["costmap"] += 1
                return path
            # no grid path inside the allowed learned modes (a poor map): the RRT below still tries
        # the clearance the path keeps: the configured one, or less where the start or the goal is closer
        # (a cell inside ``allowed`` is at least one cell from its outside: below that, only stay inside)
        margin = min(cfg.clearance, float(self.map.clearance(np.stack([x, goal]), allowed).min()))
        if margin <= self.map.resolution:
            margin = 0.0

        def seg(a: np.ndarray, b: np.ndarray) -> bool:
            return self.map.segment_ok(a, b, allowed, cfg.check_spacing, margin)

        if seg(x, goal):
            self.stats["straight"] += 1
            return [goal]
        for _ in range(cfg.rrt_restarts):
            path = rrt(
                x,
                goal,
                lambda p: bool(self.map.clearance(p[None, :], allowed)[0] >= max(margin, 1e-9)),
                seg,
                self.low,
                self.high,
                self.rng,
                iterations=cfg.rrt_iterations,
                goal_bias=cfg.rrt_goal_bias,
                step=cfg.rrt_step,
                tolerance=cfg.rrt_tolerance,
            )
            if path is not None:
                self.stats["rrt"] += 1
                return path[1:]
        self.stats["field"] += 1
        return []  # potential field

    def _field_step(self, x: np.ndarray, mode: int) -> np.ndarray:
        goal, allowed = self._target(mode)
        cfg = self.config
        return potential_field(self.map, x, goal, allowed, k_att=cfg.k_att, k_rep=cfg.k_rep, d0=cfg.d0)

    def act(self, states: np.ndarray) -> np.ndarray:
        """Velocities ``(N, 2)``: each agent follows its plan, replanned on a mode change or a push."""
        x = np.asarray(states, dtype=np.float64)
        n = len(x)
        if len(self._plans) != n:
            self._plans = [[] for _ in range(n)]
            self._plan_mode = np.full(n, -1, dtype=np.int64)
            self._expected = x.copy()
        modes = self.map.mode(x)
        out = np.zeros_like(x)
        jumped = np.linalg.norm(x - self._expected, axis=1) > self.max_speed + 1e-6
        for i in range(n):
            m = int(modes[i])
            if self._plan_mode[i] != m or jumped[i]:  # new mode, or pushed: plan again
                self._plans[i] = self._plan(x[i], m)
                self._plan_mode[i] = m
            plan = self._plans[i]
            while plan and np.linalg.norm(plan[0] - x[i]) <= self.config.waypoint_tolerance:
                plan.pop(0)
            out[i] = plan[0] - x[i] if plan else self._field_step(x[i], m)
        out = bc.clip_speed(out, self.max_speed)
        self._expected = x + out
        return out
