"""Shared machinery of the 2D kinematic domains (SoupScoop, ConvexMode, Cooking, PolygonNav).

A domain is written once as a :class:`KinematicTaskModel`: *batched*, pure-numpy
task physics over ``N`` agents (geometry, task memory, sensors, success,
violations). :class:`Kinematic2DEnv` runs it with ``N = 1`` behind the
Gymnasium ``Env`` API; :class:`~steer_envs.envs.kinematic_vector.Kinematic2DVectorEnv`
runs ``N = num_envs`` in one numpy call per step (``gymnasium.make_vec(..., vectorization_mode=
"vector_entry_point")``), which is what makes large rollouts cheap.

Dynamics (thesis ch. 3/4): single integrator ``x' = x + dt * u`` with the speed
``|u|`` clipped to ``max_speed`` and the state clipped to the workspace.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypedDict

import numpy as np
from gymnasium import spaces

from steer_envs.core.env import ClosableEnv
from steer_envs.core.interaction import InteractionKind
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import boolean, describe, integer, real_scalar
from steer_envs.envs.checks import (
    RewardType,
    check_action,
    check_options,
    check_render_mode,
    check_reward_type,
    check_seed,
    check_xy,
)
from steer_envs.envs.human_view import HumanView
from steer_envs.envs.render import REGION_PALETTE, Canvas

#: accepted ``render_size`` (pixels per side): a region map above this size costs hundreds of MB to draw.
RENDER_SIZE_RANGE = (8, 1024)
#: largest accepted step length (s) and speed limit: beyond them a step leaves every workspace and the
#: action space's float32 bounds overflow
MAX_DT = 1e3
MAX_SPEED = 1e6
#: dense reward: the reward of one mode advanced (the potential's unit, see :meth:`KinematicTaskModel.potential`).
#: Large enough that moving toward a sub-goal earns a per-step reward
#: SAC's default entropy bonus does not drown (PolygonNav: ~0.4 a step at full speed).
DENSE_REWARD_SCALE = 100.0


class EnvOptions(TypedDict, total=False):
    """The keyword options every 2D kinematic env passes on to :class:`Kinematic2DEnv` (its ``Args``)."""

    render_mode: str | None
    render_size: int
    reward_type: RewardType
    observe_sensors: bool
    normalize_actions: bool


@dataclass
class TaskReading:
    """What the sensors say for a batch of ``N`` agents."""

    mode: np.ndarray  # (N,) int, index into task.modes
    sensors: np.ndarray  # (N, num_aps) bool, columns in task.sensors order
    success: np.ndarray  # (N,) bool


class KinematicTaskModel(ABC):
    """Batched task physics of one 2D domain; subclasses fill in the geometry.

    Attributes every subclass sets in ``__init__``:
        task: the domain's :class:`TaskSpec`.
        low, high: workspace corners, shape ``(2,)``.
        region_names: names of the geometric regions ``regions()`` returns
            (index 0 is drawn white; see ``REGION_PALETTE``).
        memory_size: number of int64 task-memory slots per agent (e.g. "soup on
            spoon", "chicken added"); 0 for memoryless tasks.
    """

    task: TaskSpec
    low: np.ndarray
    high: np.ndarray
    region_names: tuple[str, ...]
    memory_size: int = 0
    #: colours of regions in ``region_names`` order (defaults to REGION_PALETTE).
    region_palette: np.ndarray = REGION_PALETTE

    @abstractmethod
    def regions(self, pos: np.ndarray) -> np.ndarray:
        """Geometric region label of each point ``(N, 2) -> (N,) int``."""

    @abstractmethod
    def sample_start(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` start states ``(n, 2)`` from the task's start distribution."""

    def reset_memory(self, pos: np.ndarray) -> np.ndarray:
        """Task memory at the start of an episode, ``(N, memory_size)`` int64."""
        return np.zeros((len(pos), self.memory_size), dtype=np.int64)

    @abstractmethod
    def advance(self, memory: np.ndarray, prev_pos: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Update task memory for a move ``prev_pos -> pos``.

        Returns the new memory and a ``(N,)`` bool *violation* flag (invalid
        mode transition, spill, leaving the mode: the CS signal). Must not
        modify its inputs.
        """

    @abstractmethod
    def read(self, memory: np.ndarray, pos: np.ndarray) -> TaskReading:
        """Mode, sensor APs and success for agents at ``pos`` with ``memory``."""

    #: mode advances from the start to the goal along the task's plan (the stages of :meth:`progress`).
    num_stages: int = 1

    @abstractmethod
    def progress(self, memory: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """How far each agent is through the task, for the dense reward.

        Returns ``(stage, distance)``: ``stage`` ``(N,)`` int in ``[0, num_stages]``, the
        number of modes advanced along the task's plan (``num_stages`` at the
        goal); ``distance`` ``(N,)`` float, the distance to the current stage's
        sub-goal (0 at the goal; the workspace diagonal after an unrecoverable failure).
        """

    @property
    def diagonal(self) -> float:
        """Length of the workspace diagonal: distances of the dense reward are measured in it."""
        return float(np.linalg.norm(np.asarray(self.high) - np.asarray(self.low)))

    def potential(self, memory: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """Dense-reward potential ``stage - min(distance / diagonal, 1)``, ``(N,)`` float in ``[-1, num_stages]``."""
        stage, distance = self.progress(memory, pos)
        return stage.astype(np.float64) - np.minimum(np.asarray(distance, dtype=np.float64) / self.diagonal, 1.0)

    def teleport(self, memory: np.ndarray, prev_pos: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """Task memory after an external displacement (``perturb``).

        Default: the same update as a move, violations ignored (an external
        push is the world's doing, not the policy's).
        """
        memory, _ = self.advance(memory, prev_pos, pos)
        return memory

    def draw(self, canvas: Canvas) -> None:  # noqa: B027 - optional hook
        """Extra drawing on top of the region map (attractors, outlines)."""


class ViolationLatchModel(KinematicTaskModel):
    """A :class:`KinematicTaskModel` whose one memory slot latches whether the agent ever moved invalidly.

    Subclasses say which moves are invalid (:meth:`violates`); a push (:meth:`teleport`) is not
    the agent's move, so it keeps the memory as it was.
    """

    memory_size = 1

    @abstractmethod
    def violates(self, prev_pos: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """Whether each move ``prev_pos -> pos`` is invalid, ``(N,)`` bool."""

    def advance(self, memory: np.ndarray, prev_pos: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        violation = self.violates(prev_pos, pos)
        new_memory = memory.copy()
        new_memory[:, 0] |= violation
        return new_memory, violation

    def teleport(self, memory: np.ndarray, prev_pos: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """A push is not a move made by the agent: the memory is kept as it was."""
        return memory.copy()


class RectRegionsModel(KinematicTaskModel):
    """A :class:`KinematicTaskModel` on a square workspace whose regions are closed rectangles.

    :meth:`set_geometry` sets ``low`` / ``high``, ``rects`` (name -> ``(x0, y0, x1, y1)``)
    and the uniform start box ``start_low`` / ``start_high``; region ``i + 1`` is
    the ``i``-th rectangle of ``order`` (the later one wins where they overlap),
    0 lies outside all of them.
    """

    rects: dict[str, np.ndarray]
    start_low: np.ndarray
    start_high: np.ndarray

    def set_geometry(
        self,
        half_width: float,
        rects: Mapping[str, Sequence[float]],
        order: Sequence[str],
        start_box: tuple[Sequence[float], Sequence[float]],
    ) -> None:
        """The workspace ``[-half_width, half_width]^2``, the rectangles (labelled in ``order``), the start box."""
        self.low = np.full(2, -half_width)
        self.high = np.full(2, half_width)
        self.rects = {k: np.asarray(v, dtype=np.float64) for k, v in rects.items()}
        self._rect_stack = np.stack([self.rects[n] for n in order])
        self.start_low = np.asarray(start_box[0], dtype=np.float64)
        self.start_high = np.asarray(start_box[1], dtype=np.float64)

    def in_rects(self, pos: np.ndarray) -> np.ndarray:
        """Whether each point lies in each labelled rectangle: ``(N, 2) -> (N, R)`` bool."""
        p = np.asarray(pos, dtype=np.float64).reshape(-1, 1, 2)
        r = self._rect_stack
        return (p[..., 0] >= r[:, 0]) & (p[..., 1] >= r[:, 1]) & (p[..., 0] <= r[:, 2]) & (p[..., 1] <= r[:, 3])

    @staticmethod
    def last_label(inside: np.ndarray) -> np.ndarray:
        """The label ``i + 1`` of the last region ``i`` holding each point (``(N, R)`` bool), 0 for none."""
        # labels grow in drawing order, so "the later region wins" is a max over the matches
        return np.max(inside * np.arange(1, inside.shape[1] + 1), axis=1, initial=0).astype(np.int64)

    def regions(self, pos: np.ndarray) -> np.ndarray:
        return self.last_label(self.in_rects(pos))

    def sample_start(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return rng.uniform(self.start_low, self.start_high, size=(n, 2))


class PotentialMemo:
    """``model.potential(memory, pos)``, reusing the last value for the same state.

    A dense step asks for the potential before and after it, and its "before"
    is the previous step's "after"; a push or a reset changes the state, so
    it is recomputed then.
    """

    def __init__(self, model: KinematicTaskModel) -> None:
        self.model = model
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def __call__(self, memory: np.ndarray, pos: np.ndarray) -> np.ndarray:
        last = self._last
        if last is not None and np.array_equal(last[0], pos) and np.array_equal(last[1], memory):
            return last[2]
        value = self.model.potential(memory, pos)
        self._last = (pos.copy(), memory.copy(), value)
        return value


class Kinematic2DEnv(ClosableEnv[np.ndarray, np.ndarray]):
    """Gymnasium env around a :class:`KinematicTaskModel` (one agent).

    Observation: the agent's xy (float32); with ``observe_sensors=True`` followed
    by the task's sensor APs as 0/1 (``task.sensors`` order), which makes task
    memory such as "soup on the spoon" observable. Action: a velocity
    (float32), whose norm is clipped to ``max_speed``; with
    ``normalize_actions=True`` the action space is ``[-1, 1]^2`` and the
    velocity is ``max_speed * action``. ``info`` carries ``mode`` (int),
    ``mode_name``, ``sensors`` (AP -> bool), ``success`` (and ``is_success``) and
    ``constraint_violation``.

    Reward (``reward_type``): ``"sparse"`` (default) +1 on success, -1 on a
    violation, else 0. ``"dense"``: the sparse reward plus potential-based
    shaping, ``DENSE_REWARD_SCALE * (phi(s') - phi(s))`` with ``phi = stage -
    min(distance / diagonal, 1)`` (:meth:`KinematicTaskModel.potential`: modes
    advanced along the task's plan, minus the distance to the current mode's
    sub-goal in workspace diagonals). So each mode advanced earns
    ``DENSE_REWARD_SCALE`` and a mode lost costs as much (a violation costs
    the modes it loses and the sparse -1, no extra penalty), moving toward the
    sub-goal earns a little every step, and the shaping of a whole episode
    telescopes (it cannot be farmed by going back and forth).

    Accepted inputs (anything else raises ``TypeError`` for the wrong kind,
    ``ValueError`` for a wrong value, naming the argument): ``dt`` and
    ``max_speed`` positive finite reals (at most :data:`MAX_DT` / :data:`MAX_SPEED`); ``terminate_on_violation``,
    ``observe_sensors`` and ``normalize_actions`` bools; ``reward_type`` ``"sparse"`` or ``"dense"``;
    ``render_mode`` ``None``, ``"rgb_array"`` or ``"human"`` (the same frames in a
    pygame window at ``metadata["render_fps"]``, shown by every ``reset`` and ``step``;
    needs the ``human`` extra); ``render_size`` an int in :data:`RENDER_SIZE_RANGE`.
    Actions, ``perturb`` displacements/targets and ``options["state"]`` are arrays of 2
    finite real numbers (lists, numpy arrays, torch tensors, read detached); strings (also ``"1"``), bools,
    complex numbers and objects are refused, never converted. A finite
    action outside the action space is clipped to ``max_speed`` (its
    direction kept) and a state outside the workspace onto it.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array", "human"], "render_fps": 30}  # noqa: RUF012 - Env's type
    interaction_kinds: tuple[InteractionKind, ...] = ("point", "sketch", "nudge")

    def __init__(
        self,
        model: KinematicTaskModel,
        *,
        dt: float,
        max_speed: float,
        terminate_on_violation: bool,
        render_mode: str | None = None,
        render_size: int = 256,
        reward_type: RewardType = "sparse",
        observe_sensors: bool = False,
        normalize_actions: bool = False,
    ) -> None:
        owner = type(self).__name__
        if not isinstance(model, KinematicTaskModel):
            raise TypeError(f"{owner}: model must be a KinematicTaskModel, got {describe(model)}")
        self.dt = real_scalar(dt, "dt", low=0.0, low_inclusive=False, high=MAX_DT, owner=owner)
        self.max_speed = real_scalar(max_speed, "max_speed", low=0.0, low_inclusive=False, high=MAX_SPEED, owner=owner)
        self.terminate_on_violation = boolean(terminate_on_violation, "terminate_on_violation", owner=owner)
        self.render_mode = check_render_mode(render_mode, self.metadata["render_modes"], owner)
        low, high = RENDER_SIZE_RANGE
        self.render_size = integer(render_size, "render_size", low=low, high=high, owner=owner)
        self._view = HumanView(self.metadata["render_fps"], owner) if self.render_mode == "human" else None
        self.reward_type: RewardType = check_reward_type(reward_type, owner)
        self.observe_sensors = boolean(observe_sensors, "observe_sensors", owner=owner)
        self.normalize_actions = boolean(normalize_actions, "normalize_actions", owner=owner)
        self.model = model
        self.task: TaskSpec = model.task
        obs_low, obs_high = model.low.astype(np.float32), model.high.astype(np.float32)
        if self.observe_sensors:
            k = len(model.task.sensors)
            obs_low = np.concatenate([obs_low, np.zeros(k, dtype=np.float32)])
            obs_high = np.concatenate([obs_high, np.ones(k, dtype=np.float32)])
        self.observation_space = spaces.Box(obs_low, obs_high, dtype=np.float32)
        bound = 1.0 if self.normalize_actions else self.max_speed
        self.action_space = spaces.Box(-bound, bound, shape=(2,), dtype=np.float32)
        self._pos = np.zeros((1, 2))
        self._memory = np.zeros((1, model.memory_size), dtype=np.int64)
        self._trail: list[np.ndarray] = []
        self._background: np.ndarray | None = None
        self._potential = PotentialMemo(model)

    # ----------------------------------------------------------------- state
    @property
    def state(self) -> np.ndarray:
        """The agent's xy (a copy, float64)."""
        return self._pos[0].copy()

    def _info(self, violation: bool, perturbed: bool = False) -> dict[str, Any]:
        reading = self.model.read(self._memory, self._pos)
        mode = int(reading.mode[0])
        success = bool(reading.success[0])
        return {
            "mode": mode,
            "mode_name": self.task.modes[mode],
            "sensors": {ap: bool(v) for ap, v in zip(self.task.sensors, reading.sensors[0], strict=True)},
            "success": success,
            "is_success": success,  # stable-baselines3's name (Monitor, ep_success_buffer)
            "constraint_violation": bool(violation),
            "perturbed": perturbed,
        }

    def _obs(self) -> np.ndarray:
        sensors = self.model.read(self._memory, self._pos).sensors if self.observe_sensors else None
        return observe(self._pos, sensors)[0]

    def velocity_of(self, actions: np.ndarray) -> np.ndarray:
        """The velocities ``(..., 2)`` that actions ask for: scaled by ``max_speed`` if normalised, speed clipped."""
        return _clip_speed(actions * self.max_speed if self.normalize_actions else actions, self.max_speed)

    def rewards(
        self, success: np.ndarray, violation: np.ndarray, potential_before: np.ndarray, potential_after: np.ndarray
    ) -> np.ndarray:
        """Batched rewards of this env's ``reward_type`` (see the class docstring), ``(N,)`` float64."""
        sparse = np.where(success, 1.0, np.where(violation, -1.0, 0.0))
        if self.reward_type == "sparse":
            return sparse
        return sparse + DENSE_REWARD_SCALE * (potential_after - potential_before)

    # ------------------------------------------------------------------- API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode; ``options={"state": xy}`` starts from a given state (clipped onto the workspace).

        ``seed`` is None or an int >= 0; ``options`` None or a dict whose only key is ``"state"``.
        """
        owner = f"{type(self).__name__}.reset"
        seed = check_seed(seed, owner)
        options = check_options(options, RESET_OPTIONS, owner)
        start = None if options.get("state") is None else check_xy(options["state"], "options['state']", owner)
        super().reset(seed=seed)  # every argument is checked first: a refused reset leaves the episode as it was
        if start is not None:
            self._pos = np.clip(start[None, :], self.model.low, self.model.high)
        else:
            self._pos = self.model.sample_start(self.np_random, 1).astype(np.float64)
        self._memory = self.model.reset_memory(self._pos)
        self._trail = [self._pos[0].copy()]
        if self.render_mode == "human":
            self.render()
        return self._obs(), self._info(False)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Move by ``dt * action``; the action (2 finite reals) is clipped to speed ``max_speed``."""
        velocity = self.velocity_of(check_action(action, self.action_space, f"{type(self).__name__}.step"))
        prev, prev_memory = self._pos, self._memory
        self._pos = np.clip(prev + self.dt * velocity[None, :], self.model.low, self.model.high)
        self._memory, violation = self.model.advance(self._memory, prev, self._pos)
        self._trail.append(self._pos[0].copy())
        info = self._info(bool(violation[0]))
        if self.reward_type == "dense":
            before, after = self._potential(prev_memory, prev), self._potential(self._memory, self._pos)
        else:
            before = after = np.zeros(1)
        reward = float(self.rewards(np.array([info["success"]]), violation, before, after)[0])
        terminated = info["success"] or (self.terminate_on_violation and info["constraint_violation"])
        if self.render_mode == "human":
            self.render()
        return self._obs(), reward, bool(terminated), False, info

    def perturb(self, delta: np.ndarray | None = None, *, to: np.ndarray | None = None) -> dict[str, Any]:
        """Displace the agent by ``delta`` (or move it ``to`` a state): a push from outside.

        The task memory follows the new state (soup falls off a tilted spoon,
        ...). The push itself is not a constraint violation of the policy.
        ``delta``/``to`` are 2 finite reals (see the class docstring); a target
        outside the workspace is clipped onto it. Returns the new ``info``.
        """
        owner = f"{type(self).__name__}.perturb"
        if (delta is None) == (to is None):
            raise ValueError(f"{owner}: pass exactly one of `delta` (displacement) or `to` (target state)")
        target = self._pos[0] + check_xy(delta, "delta", owner) if to is None else check_xy(to, "to", owner)
        prev = self._pos
        self._pos = np.clip(target, self.model.low, self.model.high)[None, :]
        self._memory = self.model.teleport(self._memory, prev, self._pos)
        self._trail.append(self._pos[0].copy())
        return self._info(False, perturbed=True)

    def render(self) -> np.ndarray | None:
        """The ``rgb_array`` frame (see :meth:`draw_frame`); with ``"human"`` it is shown in the window (None)."""
        if self.render_mode is None:
            return None
        frame = self.draw_frame(self._pos[0], self._trail)
        if self._view is not None:
            self._view.show(frame)
            return None
        return frame

    def close(self) -> None:
        """Close the ``"human"`` window, if one is open."""
        if self._view is not None:
            self._view.close()
        super().close()

    def draw_frame(self, pos: np.ndarray, trail: Sequence[np.ndarray]) -> np.ndarray:
        """One ``rgb_array`` frame: the region map, the path ``trail`` and the agent at ``pos`` (uint8 HxWx3).

        :meth:`render` draws this env's state with it,
        :meth:`~steer_envs.envs.kinematic_vector.Kinematic2DVectorEnv.render` each agent's.
        """
        canvas = Canvas(self.model.low, self.model.high, self.render_size, self.render_size)
        if self._background is None:
            canvas.fill_labels(self.model.regions(canvas.pixel_centers()), self.model.region_palette)
            self._background = canvas.image.copy()
        canvas.image[:] = self._background
        self.model.draw(canvas)
        if len(trail) > 1:
            canvas.polyline(np.asarray(trail), (40, 40, 200), thickness=2)
        canvas.disc(pos, max(3, self.render_size // 64), (220, 30, 30))
        return canvas.image


#: the ``reset`` options of the kinematic envs
RESET_OPTIONS = frozenset({"state"})


def observe(pos: np.ndarray, sensors: np.ndarray | None) -> np.ndarray:
    """Observations ``(N, 2 [+ k])`` float32: xy, then the sensor bits as 0/1 when ``sensors`` ``(N, k)`` is given."""
    if sensors is None:
        return pos.astype(np.float32)
    return np.concatenate([pos, sensors], axis=1).astype(np.float32)


def sensor_columns(sensors: Mapping[str, Any], aps: Sequence[str]) -> np.ndarray:
    """An info's ``sensors`` as an ``(N, len(aps))`` bool array, columns in ``aps`` order.

    ``sensors`` is a single env's reading (AP -> bool, ``N = 1``) or a vector env's
    (AP -> ``(N,)`` bool array; ``_AP`` masks are ignored). A missing AP is a ``KeyError``.

    >>> sensor_columns({"r": True, "s": False}, ("r", "s")).tolist()
    [[True, False]]
    >>> batch = {"r": np.array([True, False]), "_r": np.ones(2, bool), "s": np.array([False, False])}
    >>> sensor_columns(batch, ("r", "s")).tolist()
    [[True, False], [False, False]]
    """
    if not isinstance(sensors, Mapping):
        raise TypeError(f"sensor_columns: sensors must be a mapping AP -> bool(s), got {describe(sensors)}")
    if not aps:
        return np.zeros((1, 0), dtype=bool)
    return np.stack([np.atleast_1d(np.asarray(sensors[ap], dtype=bool)) for ap in aps], axis=1)


def _clip_speed(velocity: np.ndarray, max_speed: float) -> np.ndarray:
    """Scale each row of ``velocity`` down to norm ``max_speed`` where it is faster (direction kept)."""
    v = np.atleast_2d(velocity)
    with np.errstate(over="ignore"):
        norm = np.linalg.norm(v, axis=-1, keepdims=True)
    scale = np.minimum(1.0, max_speed / np.maximum(norm, 1e-12))
    out = v * scale
    huge = ~np.isfinite(norm[:, 0])
    if huge.any():  # finite rows whose norm overflows float64 (|u| ~ 1e308): normalise them scaled down first
        u = v[huge] / np.max(np.abs(v[huge]), axis=-1, keepdims=True)
        out[huge] = u / np.linalg.norm(u, axis=-1, keepdims=True) * max_speed
    return out if velocity.ndim == 2 else out[0]
