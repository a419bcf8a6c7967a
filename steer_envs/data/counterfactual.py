"""Counterfactual replays of demonstrations: GLiDE's training data generator (thesis §4.2).

GLiDE learns where the modes of a task are from a few successful
demonstrations plus *perturbed replays* labelled only by task success.
Perturbations of inconsequential parts of a demo add state coverage; those
that break an implicit constraint (skipping a mode) fail and reveal it.

Three perturbation kinds, each a pure function of a reference path
(:mod:`steer_envs.data.perturbations`):

* ``"segment"`` (thesis text): pick two points X, Y on the demo and a random
  Z in the state space; the segment XY is replaced by the straight lines XZ
  and ZY.
* ``"kernel"`` (public GLiDE code): a window ``[s, e]`` of the demo is pulled
  toward a random target Z with a Gaussian kernel, each point moving by
  ``(Z - p_t) * exp(-5 (t - c)^2 / (s - c)^2)``, ``c = (s + e) / 2``.
* ``"gripper"``: the gripper command is toggled (or forced) for 5-20 steps
  while the path is kept (only for envs whose replays carry a gripper).

:class:`CounterfactualReplayer` replays a perturbed reference in an env with a
trajectory-following controller and records the visited states, the env's own
ground-truth modes (for evaluation only) and the env's own success flag (the
training label). Replays are batched through the env's vector entry point when
it has one (the 2D kinematic envs), which keeps the thousands of replays GLiDE needs cheap.
:func:`steer_envs.data.counterfactual_dataset.build_counterfactual_dataset`
packs them into a data set.

>>> import gymnasium as gym
>>> import numpy as np
>>> import steer_envs
>>> from steer_envs.data.demos import collect_demonstrations
>>> env_id = "steer_envs/PolygonNav-3Mode-v0"
>>> demos = [d.states for d in collect_demonstrations(env_id, n=1, seed=0, layout_seed=0)]
>>> env = gym.make(env_id, layout_seed=0, terminate_on_violation=False, max_episode_steps=5000)
>>> replayer = CounterfactualReplayer(env, "segment", execution="jump")
>>> replays = replayer.rollouts(demos, 4, seed=0)
>>> [r.reference.kind for r in replays]
['segment', 'segment', 'segment', 'segment']
>>> all(isinstance(r.success, bool) for r in replays)
True
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import gymnasium as gym
import numpy as np

from steer_envs.core.progress import check_progress, progress_bar
from steer_envs.core.validation import BoundExceeded, boolean, integer, real_scalar
from steer_envs.data.perturbations import (
    PERTURBATION_KINDS,
    PerturbationKind,
    PerturbedReference,
    check_path,
    gripper_toggle,
    kernel_perturbation,
    segment_perturbation,
)
from steer_envs.envs.kinematic import Kinematic2DEnv
from steer_envs.envs.kinematic_vector import Kinematic2DVectorEnv

#: how a reference is executed (see :class:`CounterfactualReplayer`).
Execution = Literal["tracking", "jump"]
EXECUTIONS: tuple[str, ...] = ("tracking", "jump")
#: a waypoint closer than this (in state units) counts as reached by the tracking controller.
WAYPOINT_TOLERANCE = 1e-4
#: the most env steps one replay may take with a custom controller (whose reach is unknown) when
#: ``max_steps`` is not given; with the default controller the bound is derived from the reference.
DEFAULT_MAX_REPLAY_STEPS = 100_000

Controller = Callable[[np.ndarray, np.ndarray], np.ndarray]


# ---------------------------------------------------------------------- records
@dataclass(frozen=True)
class Replay:
    """What a replay of a :class:`~steer_envs.data.perturbations.PerturbedReference` did in the env.

    Attributes:
        states: ``(T, d)`` visited states, the start included.
        modes: ``(T,)`` the env's ground-truth mode at each state (evaluation only).
        success: the thesis's success criterion from the env's own signals: no step reported
            ``constraint_violation`` and ``info["success"]`` held at the end of the replay.
        violation_step: index into ``states`` of the first invalid transition, ``-1`` if none.
        truncated: the episode hit its step limit before the reference was followed
            (the label is then not a statement about the reference).
        reference: the replayed reference.
    """

    states: np.ndarray
    modes: np.ndarray
    success: bool
    violation_step: int
    truncated: bool
    reference: PerturbedReference


def _kind_weights(kind: str | Mapping[str, float] | Sequence[str]) -> dict[str, float]:
    if isinstance(kind, str):
        weights = {kind: 1.0}
    elif isinstance(kind, Mapping):
        weights = {str(k): float(v) for k, v in kind.items()}
    elif isinstance(kind, Iterable):
        weights = {str(k): 1.0 for k in kind}
    else:
        raise TypeError(f"kind must be a str, a sequence of str or a mapping str -> weight, got {type(kind).__name__}")
    if not weights:
        raise ValueError("kind must name at least one perturbation kind")
    for k, w in weights.items():
        if k not in PERTURBATION_KINDS:
            raise ValueError(f"unknown perturbation kind {k!r}; expected one of {PERTURBATION_KINDS}")
        if not (np.isfinite(w) and w >= 0):
            raise ValueError(f"weight of kind {k!r} must be a finite float >= 0, got {w!r}")
    total = sum(weights.values())
    if total <= 0:
        raise ValueError("the kind weights must not all be zero")
    return {k: w / total for k, w in weights.items() if w > 0}


class _Track:
    """Book-keeping of one replay across episodes (see ``replay_batch``)."""

    def __init__(self, ref: PerturbedReference, index: int = 0, max_steps: int | None = None) -> None:
        self.ref = ref
        self.index = index  # position in the batch (for error messages)
        self.max_steps = max_steps
        self.steps = 0  # env steps taken (all episodes)
        self.idx = 1  # next waypoint
        self.states: list[np.ndarray] = []
        self.modes: list[int] = []
        self.violation_step = -1
        self.success = False
        self.truncated = False
        self.done = len(ref.waypoints) < 2
        self.paused = False
        self.start = ref.waypoints[0]

    def begin(self, state: np.ndarray, mode: int, success: bool) -> None:
        """Start the replay at ``state`` (the env's first observation)."""
        self.states.append(state)
        self.modes.append(mode)
        self.success = success
        self._skip_reached()
        if self.idx >= len(self.ref.waypoints):
            self.done = True

    def _skip_reached(self) -> None:
        wps = self.ref.waypoints
        while self.idx < len(wps) and np.linalg.norm(wps[self.idx] - self.states[-1]) <= WAYPOINT_TOLERANCE:
            self.idx += 1

    def record(
        self, state: np.ndarray, mode: int, violation: bool, success: bool, terminated: bool, truncated: bool
    ) -> None:
        """One env step of the replay."""
        self.steps += 1
        self.states.append(state)
        self.modes.append(mode)
        if violation and self.violation_step < 0:
            self.violation_step = len(self.states) - 1
        self.success = success and self.violation_step < 0
        self._skip_reached()
        exhausted = self.idx >= len(self.ref.waypoints)
        if exhausted:
            self.done = True
        elif terminated and success:  # the goal was reached mid-reference: go on in a new episode
            self.paused = True
        elif terminated:  # the env ended the episode on a violation
            self.done = True
            self.success = False
        elif truncated:
            self.done = True
            self.truncated = True
            self.success = False
        if not self.done and self.max_steps is not None and self.steps >= self.max_steps:
            raise BoundExceeded(
                f"CounterfactualReplayer: reference {self.index} ({self.ref.kind} of demo {self.ref.source}) did "
                f"not reach waypoint {self.idx} of {len(self.ref.waypoints)} within max_steps={self.max_steps} "
                f"env steps (at state {np.round(self.states[-1], 6).tolist()})"
            )

    def result(self) -> Replay:
        return Replay(
            np.asarray(self.states),
            np.asarray(self.modes, dtype=np.int64),
            bool(self.success and self.violation_step < 0),
            int(self.violation_step),
            bool(self.truncated),
            self.ref,
        )


# --------------------------------------------------------------------- replayer
class CounterfactualReplayer:
    """Perturbs demonstration replays in ``env`` and labels them with the env's success check.

    A data generator, not a wrapper: it never changes what ``env`` observes or
    does. Its replays run on ``env`` itself, on the registered vector env of
    ``env.spec``, or on a one-step-per-waypoint copy of the task model. It offers
    :meth:`sample` (a perturbed reference from a demo), :meth:`replay` (run one
    reference with the tracking controller), :meth:`replay_batch` (many at
    once, through the env's vector entry point when it has one) and
    :meth:`rollouts` (seeded random perturbations of a set of demos, with a
    progress bar).

    Every replay follows its reference to the end (see :meth:`replay_batch`).
    Make the env with ``terminate_on_violation=False`` to get thesis-style
    failures that run to the end of the reference too (their last state is
    the demo's last state, which the ``L_final`` loss relies on); with
    termination a failed replay stops at its first invalid transition.

    Two ways to execute a reference:

    * ``execution="tracking"``: the env's own dynamics; each step
      moves at most ``max_speed * dt`` toward the next waypoint, so a replay
      passes through every mode between two far-apart waypoints (a real
      robot's replay).
    * ``execution="jump"`` (2D kinematic envs): the same task model (geometry,
      transition rules, success check) with a step limit spanning the
      workspace, so each waypoint is reached in one step and consecutive
      waypoints are *directly* connected. This is the thesis's premise for
      fully actuated systems ("every state in the second mode is reachable
      from every state in the first mode") and the public code's labelling
      of perturbed paths; it is what makes the whole extent of each mode,
      not only a band along the demonstrated crossings, identifiable from
      success labels.

    Args:
        env: a steer-envs env whose observation is its state (the 2D kinematic envs).
        kind: a perturbation kind, a sequence of kinds (equally likely) or a
            mapping kind -> probability. ``"gripper"`` needs ``gripper=True``.
        execution: ``"tracking"`` or ``"jump"`` (see above).
        controller: ``(state, waypoint) -> action`` tracking controller;
            default: for the kinematic envs, a step of at most ``max_speed * dt``
            straight toward the waypoint.
        gripper: whether references carry a gripper command (none of the 2D envs do).
        kernel_sharpness, kernel_min_window: parameters of :func:`~steer_envs.data.perturbations.kernel_perturbation`.
        max_steps: the most env steps one replay may take before :class:`~steer_envs.core.validation.BoundExceeded`
            is raised (an env step limit, when the env has one, usually ends it first as a truncated
            replay). ``None``: with the default controller, twice the steps the reference needs
            plus 100 (each step covers ``max_speed * dt``); with a custom controller
            :data:`DEFAULT_MAX_REPLAY_STEPS`.

    With the default controller (and with ``execution="jump"``), a reference with a waypoint outside
    the workspace (the observation space's box, more than :data:`WAYPOINT_TOLERANCE` away) can never be
    followed to the end and is refused with ``ValueError`` before anything runs.
    """

    def __init__(
        self,
        env: gym.Env,
        kind: PerturbationKind | Sequence[str] | Mapping[str, float] = "segment",
        *,
        execution: Execution = "tracking",
        controller: Controller | None = None,
        gripper: bool = False,
        kernel_sharpness: float = 5.0,
        kernel_min_window: int = 2,
        max_steps: int | None = None,
    ) -> None:
        if not isinstance(env, gym.Env):
            raise TypeError(f"CounterfactualReplayer: `env` must be a gymnasium.Env, got {type(env).__name__}")
        self.env = env
        self.kind_weights = _kind_weights(kind)
        if "gripper" in self.kind_weights and not gripper:
            raise ValueError("kind 'gripper' needs an env whose replays carry a gripper command (gripper=True)")
        self.gripper = boolean(gripper, "gripper", owner="CounterfactualReplayer")
        self.kernel_sharpness = real_scalar(
            kernel_sharpness, "kernel_sharpness", low=0.0, low_inclusive=False, owner="CounterfactualReplayer"
        )
        self.kernel_min_window = integer(kernel_min_window, "kernel_min_window", low=2, owner="CounterfactualReplayer")
        self.max_steps = (
            None if max_steps is None else integer(max_steps, "max_steps", low=1, owner="CounterfactualReplayer")
        )
        self._set_bounds(env)
        if not isinstance(execution, str) or execution not in EXECUTIONS:
            raise ValueError(f"execution must be 'tracking' or 'jump', got {execution!r}")
        self.execution = execution
        self._replay_env: gym.Env = self.env
        self.controller: Controller
        if execution == "jump":
            self._set_jump(controller)
        else:
            self._set_tracking(controller)

    def _set_bounds(self, env: gym.Env) -> None:
        """``low`` / ``high`` (the observation box, where Z is drawn) and the workspace the state is clipped to."""
        space = env.observation_space
        if not isinstance(space, gym.spaces.Box) or len(space.shape) != 1:
            raise TypeError("CounterfactualReplayer needs a flat Box observation space (the state)")
        self.low = np.asarray(space.low, dtype=np.float64)
        self.high = np.asarray(space.high, dtype=np.float64)
        if not (np.all(np.isfinite(self.low)) and np.all(np.isfinite(self.high))):
            raise ValueError("the observation space must be bounded (Z is drawn uniformly inside it)")
        base = env.unwrapped
        # where the state can be: the kinematic envs clip it to their model's box
        model = getattr(base, "model", None) if isinstance(base, Kinematic2DEnv) else None
        self.workspace_low = np.asarray(model.low if model is not None else self.low, dtype=np.float64)
        self.workspace_high = np.asarray(model.high if model is not None else self.high, dtype=np.float64)

    def _set_jump(self, controller: Controller | None) -> None:
        """``execution="jump"``: replay on a copy of the task model whose step reaches any waypoint."""
        base = self.env.unwrapped
        if not isinstance(base, Kinematic2DEnv):
            raise TypeError(f"execution='jump' needs a 2D kinematic env, got {type(base).__name__}")
        if controller is not None:
            raise ValueError("execution='jump' uses its own controller (one waypoint per step)")
        # the same task model (geometry, transition rules, success) with a step limit that spans
        # the workspace: every waypoint is reached in one step, a transition between its modes
        span = float(np.linalg.norm(self.high - self.low)) + 1.0
        self._replay_env = Kinematic2DEnv(
            base.model, dt=1.0, max_speed=span, terminate_on_violation=base.terminate_on_violation
        )
        self._reach, self._dt = span, 1.0
        self._default_controller = True
        self.controller = self._velocity_toward

    def _set_tracking(self, controller: Controller | None) -> None:
        """``execution="tracking"``: the env's own dynamics, with ``controller`` or the default one."""
        base = self.env.unwrapped
        if controller is None:
            if not (hasattr(base, "max_speed") and hasattr(base, "dt")):
                raise TypeError(
                    f"no default tracking controller for {type(base).__name__}; "
                    "pass controller=(state, waypoint) -> action"
                )
            self._reach = float(base.max_speed) * float(base.dt)
            self._dt = float(base.dt)
            self._default_controller = True
            self.controller = self._velocity_toward
        else:
            if not callable(controller):
                raise TypeError("controller must be callable (state, waypoint) -> action")
            self._default_controller = False
            self.controller = controller

    # ----------------------------------------------------------- controller
    def _velocity_toward(self, state: np.ndarray, waypoint: np.ndarray) -> np.ndarray:
        """A step of at most ``max_speed * dt`` straight toward ``waypoint`` (batched over rows)."""
        delta = np.asarray(waypoint, dtype=np.float64) - np.asarray(state, dtype=np.float64)
        norm = np.linalg.norm(delta, axis=-1, keepdims=True)
        scale = np.minimum(1.0, self._reach / np.maximum(norm, 1e-12))
        return (delta * scale / self._dt).astype(np.float32)

    # ------------------------------------------------------------- sampling
    def sample(
        self,
        demo: np.ndarray,
        rng: np.random.Generator,
        *,
        source: int = 0,
        kind: str | None = None,
        gripper: np.ndarray | None = None,
    ) -> PerturbedReference:
        """A random perturbation of one demo's states ``(T, d)`` (kind drawn from the weights)."""
        path = check_path(demo, "demo")
        if path.shape[1] != len(self.low):
            raise ValueError(f"demo states must have dimension {len(self.low)}, got {path.shape[1]}")
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy Generator, got {type(rng).__name__}")
        if kind is None:
            kinds = list(self.kind_weights)
            kind = kinds[int(rng.choice(len(kinds), p=list(self.kind_weights.values())))]
        nan = np.full(path.shape[1], np.nan)
        if kind == "segment":
            waypoints, window, z = segment_perturbation(path, rng, self.low, self.high)
            g = None
            if gripper is not None:  # Z keeps the gripper command of X
                g = np.asarray(gripper, dtype=np.float64)
                g = np.concatenate([g[: window[0] + 1], g[window[0] : window[0] + 1], g[window[1] :]])
            return PerturbedReference(waypoints, "segment", source, window, z, g)
        if kind == "kernel":
            waypoints, window, z = kernel_perturbation(
                path, rng, self.low, self.high, sharpness=self.kernel_sharpness, min_window=self.kernel_min_window
            )
            return PerturbedReference(waypoints, "kernel", source, window, z, gripper)
        if kind == "gripper":
            if gripper is None:
                raise ValueError("kind 'gripper' needs the demo's gripper commands (gripper=...)")
            g, window = gripper_toggle(gripper, rng)
            return PerturbedReference(path, "gripper", source, window, nan, g)
        raise ValueError(f"unknown perturbation kind {kind!r}; expected one of {PERTURBATION_KINDS}")

    def unperturbed(self, demo: np.ndarray, *, source: int = 0) -> PerturbedReference:
        """The demo itself as a reference (replaying it checks the demo succeeds)."""
        path = check_path(demo, "demo")
        return PerturbedReference(path, "demo", source, (-1, -1), np.full(path.shape[1], np.nan))

    # -------------------------------------------------------------- replays
    def replay(self, reference: PerturbedReference) -> Replay:
        """Replay one reference in ``env`` with the tracking controller."""
        return self.replay_batch([reference], vectorized=False)[0]

    def _vector_env(self, num_envs: int) -> gym.vector.VectorEnv | None:
        if self.execution == "jump":
            assert isinstance(self._replay_env, Kinematic2DEnv)
            return Kinematic2DVectorEnv(self._replay_env, num_envs)
        spec = self.env.spec
        if spec is None or spec.vector_entry_point is None or not self._default_controller:
            return None
        kwargs = dict(spec.kwargs)
        if spec.max_episode_steps is not None:
            kwargs["max_episode_steps"] = spec.max_episode_steps
        return gym.make_vec(spec.id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)

    def replay_batch(self, references: Sequence[PerturbedReference], *, vectorized: bool = True) -> list[Replay]:
        """Replay many references; one numpy call per step through the env's vector entry point.

        Each reference is followed to its last waypoint. Its label is the
        thesis's success criterion read from the env's own signals: no step
        reported ``constraint_violation`` and the env reported ``success`` at
        the end. Where the env ends an episode in success before the reference
        is exhausted (the agent reached the goal mode and the perturbation
        takes it out again), the replay goes on from that state in a new
        episode (``reset(options={"state": ...})``), so what happens after the
        goal is checked too; in the vector path every agent starts a new
        episode at that step. Violations are tracked across episodes here, so
        the labels are exact for task memories that record nothing but
        violations (PolygonNav); envs with richer task memory should replay
        references that end at the goal. Without a vector entry point (or with a custom
        controller, or ``vectorized=False``) the references are replayed one
        by one on ``env``; both paths give the same replays.
        """
        if isinstance(references, PerturbedReference):
            raise TypeError("references must be a sequence of PerturbedReference objects (use replay() for one)")
        refs = list(references)
        for i, r in enumerate(refs):
            if not isinstance(r, PerturbedReference):
                raise TypeError(f"references must be PerturbedReference objects, got {type(r).__name__}")
            if r.gripper is not None and self._default_controller:
                raise ValueError("the default kinematic controller cannot replay gripper commands")
            if r.waypoints.shape[1] != len(self.low):
                raise ValueError(
                    f"references[{i}]: waypoints must have state dimension {len(self.low)}, got {r.waypoints.shape}"
                )
            if self._default_controller:
                self._check_reachable(r, i)
        tracks = [_Track(r, i, self._step_bound(r)) for i, r in enumerate(refs)]
        venv = self._vector_env(len(tracks)) if vectorized and tracks else None
        if venv is None:
            for t in tracks:
                self._run_single(t)
        else:
            try:
                self._run_vector(venv, tracks)
            finally:
                venv.close()
        return [t.result() for t in tracks]

    def _check_reachable(self, ref: PerturbedReference, i: int) -> None:
        """``ValueError`` for a waypoint the default controller can never reach (outside the workspace)."""
        wps = ref.waypoints
        with np.errstate(over="ignore"):  # a waypoint near the float limit is simply far out
            gap = np.linalg.norm(wps - np.clip(wps, self.workspace_low, self.workspace_high), axis=1)
        far = np.flatnonzero(gap > WAYPOINT_TOLERANCE)
        if len(far):
            k = int(far[0])
            raise ValueError(
                f"CounterfactualReplayer: references[{i}] waypoint {k} {wps[k].tolist()} lies outside the workspace "
                f"[{self.workspace_low.tolist()}, {self.workspace_high.tolist()}] and can never be reached"
            )

    def _step_bound(self, ref: PerturbedReference) -> int:
        """The most env steps a replay of ``ref`` may take (see ``max_steps``)."""
        if self.max_steps is not None:
            return self.max_steps
        if not self._default_controller:
            return DEFAULT_MAX_REPLAY_STEPS
        seg = np.linalg.norm(np.diff(ref.waypoints, axis=0), axis=1)
        needed = len(ref.waypoints) + int(np.sum(np.ceil(seg / self._reach)))
        return 2 * needed + 100

    def _run_single(self, t: _Track) -> None:
        wps = t.ref.waypoints
        env = self._replay_env
        obs, info = env.reset(options={"state": t.start})
        t.begin(np.asarray(obs, dtype=np.float64), int(info["mode"]), bool(info["success"]))
        while not t.done:
            if t.paused:  # the env ended the episode in success: go on from here in a new one
                obs, info = env.reset(options={"state": t.states[-1]})
                t.paused = False
            x = t.states[-1]
            obs, _, terminated, truncated, info = env.step(self.controller(x, wps[t.idx]))
            t.record(
                np.asarray(obs, dtype=np.float64),
                int(info["mode"]),
                bool(info["constraint_violation"]),
                bool(info["success"]),
                bool(terminated),
                bool(truncated),
            )

    def _run_vector(self, venv: gym.vector.VectorEnv, tracks: list[_Track]) -> None:
        obs, info = venv.reset(options={"state": np.stack([t.start for t in tracks])})
        for i, t in enumerate(tracks):
            t.begin(np.asarray(obs[i], dtype=np.float64), int(info["mode"][i]), bool(info["success"][i]))
        x = np.asarray(obs, dtype=np.float64)
        while True:
            if any(t.paused for t in tracks):
                # some episode ended in success mid-reference: every agent starts a new episode where it
                # stands (the vector env cannot reset a subset; violations are tracked by the _Track)
                obs, info = venv.reset(options={"state": x})
                for t in tracks:
                    t.paused = False
            active = np.array([not t.done for t in tracks])
            if not active.any():
                break
            target = np.stack([t.ref.waypoints[min(t.idx, len(t.ref.waypoints) - 1)] for t in tracks])
            action = np.where(active[:, None], self._velocity_toward(x, target), 0.0).astype(np.float32)
            obs, _, terminated, truncated, info = venv.step(action)
            x = np.asarray(obs, dtype=np.float64)
            for i in np.flatnonzero(active):
                tracks[i].record(
                    x[i].copy(),
                    int(info["mode"][i]),
                    bool(info["constraint_violation"][i]),
                    bool(info["success"][i]),
                    bool(terminated[i]),
                    bool(truncated[i]),
                )

    def rollouts(
        self,
        demos: Sequence[np.ndarray],
        n: int,
        *,
        seed: int,
        batch_size: int = 256,
        progress: bool | None = False,
    ) -> list[Replay]:
        """``n`` replays of random perturbations of ``demos`` (demo drawn uniformly), seeded.

        ``progress``: ``True`` a bar, ``None`` a bar only when stderr is a terminal, ``False`` (default) none.
        """
        paths = [check_path(d, f"demos[{i}]") for i, d in enumerate(demos)]
        if not paths:
            raise ValueError("demos must hold at least one demonstration")
        n = integer(n, "n", low=0, owner="CounterfactualReplayer.rollouts")
        batch_size = integer(batch_size, "batch_size", low=1, owner="CounterfactualReplayer.rollouts")
        progress = check_progress(progress, owner="CounterfactualReplayer.rollouts")
        rng = np.random.default_rng(seed)
        out: list[Replay] = []
        with progress_bar(total=int(n), enabled=progress, desc="counterfactual replays", leave=False) as bar:
            while len(out) < n:
                m = min(int(batch_size), int(n) - len(out))
                sources = rng.integers(0, len(paths), size=m)
                refs = [self.sample(paths[s], rng, source=int(s)) for s in sources]
                out.extend(self.replay_batch(refs))
                bar.update(m)
        return out


__all__ = [
    "DEFAULT_MAX_REPLAY_STEPS",
    "EXECUTIONS",
    "CounterfactualReplayer",
    "Replay",
]
