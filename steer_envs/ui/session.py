"""One person's steering loop, without a browser: an env, a frozen policy, a sampler and its knobs.

A :class:`Session` is what ``steer-ui`` keeps per browser tab, and what a
notebook or a test drives directly::

    session = Session(seed=3)                        # Maze2D-Large + the shipped DP, SS at batch 32
    outcome = session.steer(Sketch([[2, 1], [2, 6], [5, 6]]))  # plans, costs, collisions, timings
    session.execute()                                # run the chosen plan in the env

Interactions come in world coordinates (:meth:`Session.steer`) or as pixels of
the rendered view (:meth:`Session.steer_pixels`, :meth:`Session.nudge_pixel`).
A view converts between the two: :class:`PixelMap` for an env with an affine
``pixel_to_xy`` (Maze2D's top-down image), :class:`CameraView` for a camera
with depth (BlockStack: a click lands on the first surface the pixel sees).
:data:`DOMAINS` names what steer-ui can open (the domains that push a
controller instead are :class:`~steer_envs.ui.push_session.PushSession`'s).
Every call that changes a session is logged: :meth:`Session.recording` saves
it for a replay to the same frames (:mod:`steer_envs.ui.recording`). A
session is not thread-safe: one call at a time.
"""

from __future__ import annotations

import copy
import io
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, replace
from typing import Any

import gymnasium as gym
import numpy as np

from steer_envs.core.env import PerturbableEnv
from steer_envs.core.interaction import Point, Sketch
from steer_envs.core.policy import DiffusionPolicyLike, TrajectoryPolicy
from steer_envs.core.validation import describe, integer, one_of, real_array
from steer_envs.steering import (
    OutputPerturbation,
    interaction_dims,
    make_sampler,
    place_observation,
    policy_observation,
)
from steer_envs.ui.domains import DEFAULT_ENV, DOMAINS, Domain, domain_named
from steer_envs.ui.outcomes import SteerOutcome, StepOutcome
from steer_envs.ui.recording import Recording, SessionLog, interaction_json, recording_of
from steer_envs.ui.settings import MAX_BATCH, SteerSettings
from steer_envs.ui.views import (
    CameraView,
    PixelMap,
    PlaneView,
    SessionError,
    make_view,
    rendered_frame,
    resample_by_arclength,
)
from steer_envs.utils.threads import limit_threads

__all__ = [
    "DEFAULT_ENV",
    "DOMAINS",
    "MAX_BATCH",
    "POLICY_KINDS",
    "Domain",
    "Session",
    "SteerOutcome",
    "SteerSettings",
    "StepOutcome",
    "shared_policy",
]

#: the sketch the samplers get: this many points, evenly spaced along the drawn path
SKETCH_POINTS = 64
#: the shipped policies a session can load by name
POLICY_KINDS: tuple[str, ...] = ("dp", "act", "blockstack", "kitchen")


# ----------------------------------------------------------------- policies
def shared_policy(kind: str = "dp", checkpoint: str | None = None, accelerate: str = "fastest") -> TrajectoryPolicy:
    """A shipped policy (or ``checkpoint``), loaded once per process and shared.

    ``kind``: ``"dp"`` / ``"act"`` (Maze2D-Large), ``"blockstack"`` or ``"kitchen"`` (the skill DPs).
    ``accelerate`` is :meth:`DiffusionPolicy.accelerate`'s mode (``"fastest"``:
    OpenVINO where installed, else ONNX Runtime or a trace); ACT ignores it.
    The cache is :func:`steer_envs.baselines.pretrained.shared_policy`'s.
    """
    from steer_envs.baselines.diffusion.acceleration import resolve_acceleration
    from steer_envs.baselines.pretrained import shared_policy as load_shared

    kind = one_of(kind, "policy", POLICY_KINDS, owner="steer-ui")
    mode = "none" if kind == "act" else resolve_acceleration(accelerate, owner="steer-ui")
    policy: TrajectoryPolicy = load_shared(kind, checkpoint or "", mode, owner="steer-ui")
    return policy


class _NetworkClock:
    """Adds up the wall time a policy spends in its network (``predict_noise``, ``encode_obs``, ``sample``)."""

    def __init__(self) -> None:
        self.seconds = 0.0

    def wrap(self, fn: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - t0

        return timed


def _session_view(policy: TrajectoryPolicy, clock: _NetworkClock) -> TrajectoryPolicy:
    """A shallow copy of ``policy`` with its own scheduler (sessions share the weights, not the sampler state)."""
    view = copy.copy(policy)
    scheduler = getattr(policy, "scheduler", None)
    if scheduler is not None:
        view.scheduler = copy.deepcopy(scheduler)  # type: ignore[attr-defined]
    if isinstance(policy, DiffusionPolicyLike):
        for name in ("predict_noise", "encode_obs"):
            setattr(view, name, clock.wrap(getattr(view, name)))
    else:
        view.sample = clock.wrap(view.sample)  # type: ignore[method-assign]
    return view


# ------------------------------------------------------------------ session
def _session_policy(policy: str | TrajectoryPolicy, checkpoint: str | None, accelerate: str) -> TrajectoryPolicy:
    """The policy a :class:`Session` steers: a kind's shared policy (:func:`shared_policy`) or ``policy`` itself."""
    if isinstance(policy, str):
        return shared_policy(policy, checkpoint, accelerate)
    if isinstance(policy, TrajectoryPolicy):
        if checkpoint is not None:
            raise TypeError("Session: `checkpoint` goes with a policy kind, not a policy object")
        return policy
    raise TypeError(f"Session: `policy` must be a policy kind or a TrajectoryPolicy, got {describe(policy)}")


def _session_env(
    domain: Domain, env: str | gym.Env[Any, Any] | None, env_kwargs: Mapping[str, Any] | None
) -> gym.Env[Any, Any]:
    """The env a :class:`Session` steers in: ``env`` (the domain's by default) made from its id, or ``env`` itself."""
    env = domain.env_id if env is None else env
    if isinstance(env, str):
        kwargs = dict(domain.env_kwargs if env_kwargs is None and env == domain.env_id else {})
        kwargs.update(env_kwargs or {})
        return gym.make(env, render_mode="rgb_array", **kwargs)
    if isinstance(env, gym.Env):
        if env_kwargs:
            raise TypeError("Session: `env_kwargs` goes with an env id, not an env object")
        return env
    raise TypeError(f"Session: `env` must be an env id or a gymnasium.Env, got {describe(env)}")


class Session:
    """An env, a frozen policy and steering settings: steer, look at the plans, execute, nudge.

    Args:
        domain: a steered domain of :data:`DOMAINS` (``"maze2d"``, ``"blockstack"``, ``"kitchen"``): the env,
            policy, default settings, view and executor below default to its.
        env: an env id, or an env made with ``render_mode="rgb_array"``.
        policy: a policy kind of :func:`shared_policy` (shared by all sessions of the
            process) or any :class:`~steer_envs.core.policy.TrajectoryPolicy`.
        checkpoint: a checkpoint file of ``policy`` (with a kind only).
        settings: the sampler and knobs (default: the domain's).
        seed: the first reset's seed (start state and sampling noise).
        env_kwargs: passed to ``gymnasium.make`` with an id (default: the domain's).
        accelerate: the network's inference mode for a named policy (``"fastest"`` by default:
            OpenVINO where installed, else ONNX Runtime or a trace).
        threads: torch threads for a steering call (default 1; ``None``: leave torch's setting,
            as the server does after setting it once per process).
    """

    def __init__(
        self,
        domain: str = "maze2d",
        *,
        env: str | gym.Env[Any, Any] | None = None,
        policy: str | TrajectoryPolicy | None = None,
        checkpoint: str | None = None,
        settings: SteerSettings | None = None,
        seed: int = 0,
        env_kwargs: Mapping[str, Any] | None = None,
        accelerate: str = "fastest",
        threads: int | None = 1,
    ) -> None:
        self.name = one_of(domain, "domain", tuple(DOMAINS), owner="Session")
        #: the calls that changed the session, for :meth:`recording` (:class:`~steer_envs.ui.recording.SessionLog`)
        self.log = SessionLog()
        self._logging = False
        unrecordable = [n for n, v in (("env", env), ("policy", policy)) if v is not None and not isinstance(v, str)]
        self._opened: dict[str, Any] = {
            "kind": "steer",
            "seed": seed,
            "env": env if isinstance(env, str) else None,
            "env_kwargs": None if env_kwargs is None else dict(env_kwargs),
            "policy": policy if isinstance(policy, str) else None,
            "checkpoint": checkpoint,
            "accelerate": accelerate,
            "unrecordable": unrecordable,
        }
        self.domain = domain_named(domain, owner="Session")
        if not self.domain.steering:
            raise SessionError(f"the {domain!r} domain pushes a controller: open it with PushSession, not Session")
        self.threads = None if threads is None else integer(threads, "`threads`", low=1)
        shared = _session_policy(self.domain.policies[0] if policy is None else policy, checkpoint, accelerate)
        if settings is not None and not isinstance(settings, SteerSettings):
            raise TypeError(f"Session: `settings` must be SteerSettings or None, got {describe(settings)}")
        self.settings = (settings or self.domain.settings).checked()
        self._clock = _NetworkClock()
        self.policy = _session_view(shared, self._clock)
        self.dims = interaction_dims(self.policy)
        self.env = _session_env(self.domain, env, env_kwargs)
        box = self.env.action_space
        if self.domain.execute == "waypoints" and (
            not isinstance(box, gym.spaces.Box) or box.shape != (int(self.policy.action_dim),)
        ):
            raise SessionError(
                f"the env's action space must be a Box of shape ({self.policy.action_dim},) like the policy's plans, "
                f"got {box}"
            )
        self._box: Any = box
        base = self.env.unwrapped
        kinds = getattr(base, "interaction_kinds", ("point", "sketch", "nudge"))
        #: the interactions offered: the domain's that the env takes
        self.kinds: tuple[str, ...] = tuple(k for k in self.domain.interactions if k in kinds)
        self._sampler = self.settings.make_sampler()
        self._sampler.check_policy(self.policy)
        self._history: list[Any] = []
        self._rng = np.random.default_rng(0)
        self._last: SteerOutcome | None = None
        self._done = False
        self._home_yaw = 0.0
        self._seed = integer(seed, "`seed`", low=0, high=2**31 - 1)
        self.reset(seed=self._seed)
        image = self.frame()
        view = make_view(self.domain.view, base, image)
        if isinstance(view, PlaneView):
            self.env.close()
            raise SessionError("a steered domain's view is 'pixels', 'box' or 'camera' (clicks land on the scene)")
        self.pixels: PixelMap | CameraView = view
        self._opened["settings"] = asdict(self.settings)
        self._logging = True

    # -------------------------------------------------------------- state
    @property
    def seed(self) -> int:
        """The seed of the last reset."""
        return self._seed

    @property
    def state(self) -> np.ndarray:
        """The agent's world position (the dimensions interactions live in)."""
        raw = np.asarray(getattr(self.env.unwrapped, "state", self._history[-1]), dtype=np.float64)
        return raw[list(self.dims)].copy()

    @property
    def last(self) -> SteerOutcome | None:
        """The latest steering outcome not yet executed (``None`` after a step, nudge or reset)."""
        return self._last

    @property
    def done(self) -> bool:
        """The episode ended (terminated or truncated): :meth:`reset` to go on."""
        return self._done

    def configure(self, **knobs: Any) -> SteerSettings:
        """Change sampler / knobs (``SteerSettings`` fields; ``None``: the domain's default for that knob).

        Unknown names give ``TypeError``.
        """
        unknown = sorted(set(knobs) - set(SteerSettings.__dataclass_fields__))
        if unknown:
            raise TypeError(
                f"Session.configure: unknown knob(s) {unknown}; known: {list(SteerSettings.__dataclass_fields__)}"
            )
        defaults = self.domain.settings
        knobs = {name: getattr(defaults, name) if value is None else value for name, value in knobs.items()}
        settings = replace(self.settings, **knobs).checked()
        sampler = settings.make_sampler()
        sampler.check_policy(self.policy)  # BI/GD/SS need a diffusion policy: refuse here, not at the next call
        self.settings, self._sampler = settings, sampler
        self._record("configure", knobs=knobs)
        return settings

    def reset(self, seed: int | None = None) -> dict[str, Any]:
        """Reset the env (``seed``: start state and sampling noise); returns the env's info."""
        if seed is not None:
            self._seed = integer(seed, "`seed`", low=0, high=2**31 - 1)
        obs, info = self.env.reset(seed=self._seed)
        if self.domain.execute == "skill":
            from steer_envs.control.blockstack import yaw_of

            base: Any = self.env.unwrapped
            self._home_yaw = yaw_of(base.robosuite_obs["robot0_eef_quat"])
        self._rng = np.random.default_rng(np.random.SeedSequence([self._seed, 0x5E55]))
        self._history = [obs]
        self._last = None
        self._done = False
        self._record("reset", seed=self._seed)
        return dict(info)

    # ------------------------------------------------------------ steering
    def steer(self, interaction: Point | Sketch | None) -> SteerOutcome:
        """Sample a batch of plans from the current state, steered by ``interaction`` (``None``: unsteered)."""
        if interaction is not None and not isinstance(interaction, Point | Sketch):
            raise TypeError(
                f"Session.steer: `interaction` must be a Point, Sketch or None, got {describe(interaction)}"
            )
        if self._done:
            raise SessionError("the episode has ended: reset to steer again")
        sampler = self._sampler if interaction is not None else make_sampler("RS")
        if isinstance(sampler, OutputPerturbation):
            if not isinstance(interaction, Sketch):
                raise SessionError("OP moves the agent onto a sketch: draw a sketch (a point does not work with OP)")
            is_wall = getattr(self.env.unwrapped, "is_wall", None)
            if sampler.collides is None and callable(is_wall):
                sampler = OutputPerturbation(sampler.index, collides=is_wall, obs_at=sampler.obs_at)
        obs = policy_observation(self.policy, self._history)
        self._clock.seconds = 0.0
        try:
            with limit_threads(blas_threads=None, torch_threads=self.threads):
                result = sampler(self.policy, obs, interaction, self.settings.batch, generator=self._rng)
        except TypeError as exc:  # e.g. BI/GD/SS with a policy that has no denoiser
            raise SessionError(str(exc)) from exc
        start = int(getattr(self.policy, "exec_start", 0))
        plans = np.asarray(result.plans, dtype=np.float64)[:, start:]
        plans = plans if self._skills else plans[..., list(self.dims)]
        collide = getattr(self.env.unwrapped, "plan_collides", None)
        total = float(result.timings.get("total_ms", float("nan")))
        network = self._clock.seconds * 1e3
        timings = {
            "network_ms": network,
            "sampler_ms": max(0.0, total - network),
            "total_ms": total,
            "network_evals": float(result.timings.get("network_evals", 0.0)),
        }
        outcome = SteerOutcome(
            plans=plans,
            chosen=int(result.chosen),
            costs=np.asarray(result.costs, dtype=np.float64),
            collides=np.asarray(collide(plans), dtype=bool) if callable(collide) and len(self.dims) == 2 else None,
            interaction=interaction,
            timings=timings,
            settings=self.settings,
            perturbed_state=result.perturbed_state,
        )
        self._last = outcome
        self._record("steer", interaction=interaction_json(interaction))
        return outcome

    def steer_pixels(self, kind: str, pixels: Any) -> SteerOutcome:
        """Steer with mouse input on the rendered view: ``kind`` ``"sketch"`` (a path), ``"point"`` or ``"none"``."""
        kind = one_of(kind, "kind", ("sketch", "point", "none"), owner="Session.steer_pixels")
        if kind == "none":
            return self.steer(None)
        arr = self.pixels.check_pixels(pixels, "points")
        world = self.pixels.to_world(arr)
        if kind == "point":
            if len(world) != 1:
                raise SessionError(f"a point is one [u, v] pair, got {len(world)} points")
            return self.steer(Point(world[0]))
        return self.steer(Sketch(resample_by_arclength(world, SKETCH_POINTS)))

    # ------------------------------------------------------------ execution
    def execute(self) -> StepOutcome:
        """Run the chosen plan of the last :meth:`steer` (unsteered if none) in the env; the plans then expire."""
        if self._done:
            raise SessionError("the episode has ended: reset to go on")
        step = self._execute()
        self._record("step")
        return step

    def _execute(self) -> StepOutcome:
        outcome = self._last if self._last is not None else self.steer(None)
        perturbed = outcome.perturbed_state
        if perturbed is not None:  # OP moved the agent onto the sketch before sampling
            self._perturbable().perturb(to=perturbed)
            self._history.append(place_observation(self._history[-1], self.state))
        if self.domain.execute == "skill":
            return self._execute_skill(outcome.plan)
        if self.domain.execute == "kitchen-skill":
            return self._execute_kitchen_skill(outcome.plan)
        plan = outcome.plan
        if self.settings.execute is not None:
            plan = plan[: self.settings.execute]
        reward, terminated, truncated = 0.0, False, False
        info: dict[str, Any] = {}
        executed: list[np.ndarray] = []
        for waypoint in plan:
            action = np.clip(waypoint, self._box.low, self._box.high).astype(self._box.dtype)
            obs, r, terminated, truncated, info = self.env.step(action)
            executed.append(action)
            self._history.append(obs)
            reward += float(r)
            if terminated or truncated:
                break
        keep = max(2, int(getattr(self.policy, "n_obs_steps", 1)))
        self._history = self._history[-keep:]
        self._last = None
        self._done = bool(terminated or truncated)
        return StepOutcome(np.asarray(executed), reward, bool(terminated), bool(truncated), dict(info))

    def _execute_skill(self, plan: np.ndarray) -> StepOutcome:
        """A whole pick / place skill plan, run open-loop on the arm (BlockStack)."""
        from steer_envs.control.blockstack import execute_plan

        base: Any = self.env.unwrapped
        result = execute_plan(base, plan, home_yaw=self._home_yaw)
        self._history.append(result.obs)
        self._history = self._history[-max(2, int(getattr(self.policy, "n_obs_steps", 1))) :]
        self._last = None
        info = dict(base._info()) if callable(getattr(base, "_info", None)) else {}
        info["skill"] = result.executed
        info["constraint_violation"] = bool(result.violation or info.get("constraint_violation", False))
        return StepOutcome(result.trail, 0.0, False, False, info)

    def _execute_kitchen_skill(self, plan: np.ndarray) -> StepOutcome:
        """A whole door / bowl skill plan, run open-loop on the Kitchen arm; the episode ends at the goal or a loss."""
        from steer_envs.control.kitchen import execute_kitchen_plan

        base: Any = self.env.unwrapped
        result = execute_kitchen_plan(base, plan)
        self._history.append(result.obs)
        self._history = self._history[-max(2, int(getattr(self.policy, "n_obs_steps", 1))) :]
        self._last = None
        goal = result.mode_after in base.task.goal
        self._done = bool(goal or result.mode_after == "lost")
        info = dict(base._info())
        info["skill"] = result.executed
        info["constraint_violation"] = bool(result.violation or info.get("constraint_violation", False))
        return StepOutcome(result.trail, 0.0, bool(goal), False, info)

    @property
    def _skills(self) -> bool:
        """Plans are whole skills (positions, yaw, gripper: kept whole, drawn by their xyz)."""
        return self.domain.execute in ("skill", "kitchen-skill")

    def panel(self, outcome: SteerOutcome | None = None) -> list[tuple[str, str]]:
        """Rows the page shows beside the view: the task's modes (Kitchen), and what the chosen plan would do."""
        if self.domain.execute != "kitchen-skill":
            return []
        from steer_envs.ui.kitchen_panel import kitchen_rows

        return kitchen_rows(self.env.unwrapped, None if outcome is None else outcome.plan)

    def nudge(self, to: Any) -> dict[str, Any]:
        """Move the agent to world point ``to`` (a physical correction through ``perturb``); plans expire."""
        target = real_array(to, "to", owner="Session.nudge")
        if target.shape != (len(self.dims),):
            raise SessionError(f"`to` must be a world point of {len(self.dims)} numbers, got shape {target.shape}")
        if self._done:
            raise SessionError("the episode has ended: reset to go on")
        if "nudge" not in self.kinds:
            raise SessionError(
                f"{type(self.env.unwrapped).__name__} takes no nudges (its interaction kinds: {list(self.kinds)})"
            )
        info = self._perturbable().perturb(to=target)
        self._history.append(place_observation(self._history[-1], self.state))
        self._last = None
        self._record("nudge", to=target)
        return dict(info)

    def nudge_pixel(self, u: Any, v: Any) -> dict[str, Any]:
        """:meth:`nudge` to the world point under pixel ``(u, v)`` of the view."""
        pixel = self.pixels.check_pixels([[u, v]], "to")
        return self.nudge(self.pixels.to_world(pixel)[0])

    def _perturbable(self) -> PerturbableEnv:
        base = self.env.unwrapped
        if not isinstance(base, PerturbableEnv):
            raise SessionError(f"{type(base).__name__} cannot be nudged (it has no perturb())")
        return base

    # ------------------------------------------------------------ recording
    def _record(self, op: str, **fields: Any) -> None:
        if self._logging:
            self.log.add(op, **fields)

    def recording(self) -> Recording:
        """This session as a :class:`~steer_envs.ui.recording.Recording` (save it with ``save_recording``).

        ``SessionError`` for a session opened with an env or policy object (a recording names them).
        """
        opened = dict(self._opened)
        if opened.pop("unrecordable"):
            raise SessionError("a session opened with an env or policy object cannot be recorded: open it by name")
        return recording_of(self, opened, self.log)

    # ------------------------------------------------------------- drawing
    def frame(self) -> np.ndarray:
        """The env's rendered view ``(H, W, 3)`` uint8 (walls, trail, agent)."""
        image = rendered_frame(self.env)
        self.log.frame(image)
        return image

    def frame_png(self) -> bytes:
        """:meth:`frame` as PNG bytes."""
        from PIL import Image

        buffer = io.BytesIO()
        Image.fromarray(self.frame()).save(buffer, format="PNG", optimize=False, compress_level=1)
        return buffer.getvalue()

    def close(self) -> None:
        """Close the env."""
        self.env.close()
