"""Shared machinery of the 2D kinematic domains (SoupScoop, ConvexMode, Cooking, PolygonNav).

A domain is written once as a :class:`KinematicTaskModel`: *batched*, pure-numpy
task physics over ``N`` agents (geometry, task memory, sensors, success,
violations). :class:`Kinematic2DEnv` runs it with ``N = 1`` behind the
Gymnasium ``Env`` API; :class:`Kinematic2DVectorEnv` runs ``N = num_envs`` in
one numpy call per step (``gymnasium.make_vec(..., vectorization_mode=
"vector_entry_point")``), which is what makes large rollouts cheap.

Dynamics (thesis ch. 3/4): single integrator ``x' = x + dt * u`` with the speed
``|u|`` clipped to ``max_speed`` and the state clipped to the workspace.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from steer_envs.core.interaction import InteractionKind
from steer_envs.core.task import TaskSpec
from steer_envs.envs.render import REGION_PALETTE, Canvas


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

    def teleport(self, memory: np.ndarray, prev_pos: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """Task memory after an external displacement (``perturb``).

        Default: the same update as a move, violations ignored (an external
        push is the world's doing, not the policy's).
        """
        memory, _ = self.advance(memory, prev_pos, pos)
        return memory

    def draw(self, canvas: Canvas) -> None:  # noqa: B027 - optional hook
        """Extra drawing on top of the region map (attractors, outlines)."""


class Kinematic2DEnv(gym.Env[np.ndarray, np.ndarray]):
    """Gymnasium env around a :class:`KinematicTaskModel` (one agent).

    Observation: the agent's xy (float32). Action: a velocity (float32), whose
    norm is clipped to ``max_speed``. ``info`` carries ``mode`` (int),
    ``mode_name``, ``sensors`` (AP -> bool), ``success`` and
    ``constraint_violation``. Reward: +1 on success, -1 on a violation, else 0.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 30}  # noqa: RUF012 - Env's type
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
    ) -> None:
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive finite float, got {dt!r}")
        if not (np.isfinite(max_speed) and max_speed > 0):
            raise ValueError(f"max_speed must be a positive finite float, got {max_speed!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.model = model
        self.task: TaskSpec = model.task
        self.dt = float(dt)
        self.max_speed = float(max_speed)
        self.terminate_on_violation = bool(terminate_on_violation)
        self.render_mode = render_mode
        self.render_size = int(render_size)
        self.observation_space = spaces.Box(
            model.low.astype(np.float32), model.high.astype(np.float32), dtype=np.float32
        )
        self.action_space = spaces.Box(-self.max_speed, self.max_speed, shape=(2,), dtype=np.float32)
        self._pos = np.zeros((1, 2))
        self._memory = np.zeros((1, model.memory_size), dtype=np.int64)
        self._trail: list[np.ndarray] = []
        self._background: np.ndarray | None = None

    # ----------------------------------------------------------------- state
    @property
    def state(self) -> np.ndarray:
        """The agent's xy (a copy, float64)."""
        return self._pos[0].copy()

    def _info(self, violation: bool, perturbed: bool = False) -> dict[str, Any]:
        reading = self.model.read(self._memory, self._pos)
        mode = int(reading.mode[0])
        return {
            "mode": mode,
            "mode_name": self.task.modes[mode],
            "sensors": {ap: bool(v) for ap, v in zip(self.task.sensors, reading.sensors[0], strict=True)},
            "success": bool(reading.success[0]),
            "constraint_violation": bool(violation),
            "perturbed": perturbed,
        }

    def _obs(self) -> np.ndarray:
        return self._pos[0].astype(np.float32)

    # ------------------------------------------------------------------- API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode; ``options={"state": xy}`` starts from a given state."""
        super().reset(seed=seed)
        options = options or {}
        if "state" in options and options["state"] is not None:
            self._pos = _check_xy(options["state"], "options['state']")[None, :]
            self._pos = np.clip(self._pos, self.model.low, self.model.high)
        else:
            self._pos = self.model.sample_start(self.np_random, 1).astype(np.float64)
        self._memory = self.model.reset_memory(self._pos)
        self._trail = [self._pos[0].copy()]
        return self._obs(), self._info(False)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        velocity = _clip_speed(_check_action(action, self.action_space), self.max_speed)
        prev = self._pos
        self._pos = np.clip(prev + self.dt * velocity[None, :], self.model.low, self.model.high)
        self._memory, violation = self.model.advance(self._memory, prev, self._pos)
        self._trail.append(self._pos[0].copy())
        info = self._info(bool(violation[0]))
        reward = 1.0 if info["success"] else (-1.0 if info["constraint_violation"] else 0.0)
        terminated = info["success"] or (self.terminate_on_violation and info["constraint_violation"])
        return self._obs(), reward, bool(terminated), False, info

    def perturb(self, delta: np.ndarray | None = None, *, to: np.ndarray | None = None) -> dict[str, Any]:
        """Displace the agent by ``delta`` (or move it ``to`` a state): a push from outside.

        The task memory follows the new state (soup falls off a tilted spoon,
        ...). The push itself is not a constraint violation of the policy.
        Returns the new ``info``.
        """
        if (delta is None) == (to is None):
            raise ValueError("perturb: pass exactly one of `delta` (displacement) or `to` (target state)")
        target = self._pos[0] + _check_xy(delta, "delta") if to is None else _check_xy(to, "to")
        prev = self._pos
        self._pos = np.clip(target, self.model.low, self.model.high)[None, :]
        self._memory = self.model.teleport(self._memory, prev, self._pos)
        self._trail.append(self._pos[0].copy())
        return self._info(False, perturbed=True)

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        canvas = Canvas(self.model.low, self.model.high, self.render_size, self.render_size)
        if self._background is None:
            canvas.fill_labels(self.model.regions(canvas.pixel_centers()), self.model.region_palette)
            self._background = canvas.image.copy()
        canvas.image[:] = self._background
        self.model.draw(canvas)
        if len(self._trail) > 1:
            canvas.polyline(np.asarray(self._trail), (40, 40, 200), thickness=2)
        canvas.disc(self._pos[0], max(3, self.render_size // 64), (220, 30, 30))
        return canvas.image


class Kinematic2DVectorEnv(VectorEnv):
    """``num_envs`` agents of one domain stepped together in numpy.

    Same dynamics, rewards and termination as :class:`Kinematic2DEnv`;
    autoreset is ``NEXT_STEP`` (Gymnasium's default). ``infos`` holds arrays:
    ``mode``, ``success``, ``constraint_violation`` and ``sensors`` (an
    ``(num_envs, num_aps)`` bool array, columns in ``task.sensors`` order).
    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import steer_envs
    >>> venv = gym.make_vec("steer_envs/PolygonNav-3Mode-v0", num_envs=4, vectorization_mode="vector_entry_point")
    >>> obs, infos = venv.reset(seed=0)
    >>> obs, rewards, terminated, truncated, infos = venv.step(np.zeros((4, 2), dtype=np.float32))
    >>> obs.shape, infos["mode"].shape, infos["sensors"].shape
    ((4, 2), (4,), (4, 2))
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012 - VectorEnv's type

    def __init__(self, env: Kinematic2DEnv, num_envs: int, max_episode_steps: int | None = None) -> None:
        if not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive int, got {num_envs!r}")
        self.env = env
        self.model = env.model
        self.num_envs = int(num_envs)
        self.max_episode_steps = max_episode_steps
        self.single_observation_space = env.observation_space
        self.single_action_space = env.action_space
        self.observation_space = batch_space(env.observation_space, self.num_envs)
        self.action_space = batch_space(env.action_space, self.num_envs)
        self.render_mode = None
        n = self.num_envs
        self._pos = np.zeros((n, 2))
        self._memory = np.zeros((n, self.model.memory_size), dtype=np.int64)
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._needs_reset = np.zeros(n, dtype=bool)

    def _infos(self, violation: np.ndarray) -> dict[str, Any]:
        reading = self.model.read(self._memory, self._pos)
        return {
            "mode": reading.mode.astype(np.int64),
            "sensors": reading.sensors.astype(bool),
            "success": reading.success.astype(bool),
            "constraint_violation": violation.astype(bool),
        }

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start all episodes; ``options={"state": xy}`` with ``xy`` of shape ``(num_envs, 2)`` sets the starts."""
        super().reset(seed=seed)
        options = options or {}
        if options.get("state") is not None:
            states = np.asarray(options["state"], dtype=np.float64)
            if states.shape != (self.num_envs, 2) or not np.all(np.isfinite(states)):
                raise ValueError(
                    f"options['state'] must be a finite array of shape ({self.num_envs}, 2), got {states.shape}"
                )
            self._pos = np.clip(states, self.model.low, self.model.high)
        else:
            self._pos = self.model.sample_start(self.np_random, self.num_envs).astype(np.float64)
        self._memory = self.model.reset_memory(self._pos)
        self._elapsed[:] = 0
        self._needs_reset[:] = False
        return self._pos.astype(np.float32), self._infos(np.zeros(self.num_envs, dtype=bool))

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != (self.num_envs, 2):
            raise ValueError(f"actions must have shape ({self.num_envs}, 2), got {actions.shape}")
        if not np.all(np.isfinite(actions)):
            raise ValueError("actions must be finite (got NaN or inf)")
        velocity = _clip_speed(actions, self.env.max_speed)
        prev = self._pos
        moved = np.clip(prev + self.env.dt * velocity, self.model.low, self.model.high)
        memory, violation = self.model.advance(self._memory, prev, moved)
        # agents whose episode ended last step are reset instead of moved
        resetting = self._needs_reset
        if resetting.any():
            fresh = self.model.sample_start(self.np_random, int(resetting.sum()))
            moved[resetting] = fresh
            memory[resetting] = self.model.reset_memory(fresh)
            violation = violation & ~resetting
        self._pos, self._memory = moved, memory
        self._elapsed = np.where(resetting, 0, self._elapsed + 1)
        infos = self._infos(violation)
        rewards = np.where(infos["success"], 1.0, np.where(violation, -1.0, 0.0))
        terminated = infos["success"] | (self.env.terminate_on_violation & violation)
        truncated = np.zeros(self.num_envs, dtype=bool)
        if self.max_episode_steps is not None:
            truncated = self._elapsed >= self.max_episode_steps
        terminated &= ~resetting
        truncated &= ~resetting
        rewards = np.where(resetting, 0.0, rewards)
        self._needs_reset = terminated | truncated
        return self._pos.astype(np.float32), rewards, terminated, truncated, infos

    def perturb(self, to: np.ndarray, mask: np.ndarray) -> dict[str, Any]:
        """Move the agents selected by ``mask`` (``(num_envs,)`` bool) to ``to[mask]``: a push from outside.

        The batched counterpart of :meth:`Kinematic2DEnv.perturb` (``to=``): the
        task memory follows ``model.teleport`` and no violation is reported.
        Returns the new ``infos``.
        """
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (self.num_envs,):
            raise ValueError(f"mask must have shape ({self.num_envs},), got {mask.shape}")
        target = np.asarray(to, dtype=np.float64)
        if target.shape != (self.num_envs, 2) or not np.all(np.isfinite(target[mask])):
            raise ValueError(f"to must be a finite array of shape ({self.num_envs}, 2), got {target.shape}")
        prev = self._pos.copy()
        self._pos = np.where(mask[:, None], np.clip(target, self.model.low, self.model.high), self._pos)
        self._memory = np.where(mask[:, None], self.model.teleport(self._memory, prev, self._pos), self._memory)
        return self._infos(np.zeros(self.num_envs, dtype=bool))


def _check_xy(value: Any, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a length-2 array of floats, got {type(value).__name__}") from None
    if arr.shape != (2,):
        raise ValueError(f"{name} must have shape (2,), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return arr


def _check_action(action: Any, space: spaces.Space[Any]) -> np.ndarray:
    try:
        arr = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"action must be an array of shape {space.shape}, got {type(action).__name__}") from None
    if arr.shape != space.shape:
        raise ValueError(f"action must have shape {space.shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"action must be finite, got {arr.tolist()}")
    return arr


def _clip_speed(velocity: np.ndarray, max_speed: float) -> np.ndarray:
    """Scale each row of ``velocity`` down to norm ``max_speed`` where it is faster."""
    v = np.atleast_2d(velocity)
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    scale = np.minimum(1.0, max_speed / np.maximum(norm, 1e-12))
    out = v * scale
    return out if velocity.ndim == 2 else out[0]


def vector_factory(env_cls: type[Kinematic2DEnv]) -> Any:
    """A ``vector_entry_point`` for ``gymnasium.make_vec`` that batches ``env_cls``."""

    def make_vector_env(num_envs: int = 1, max_episode_steps: int | None = None, **kwargs: Any) -> Kinematic2DVectorEnv:
        kwargs.pop("render_mode", None)
        return Kinematic2DVectorEnv(env_cls(**kwargs), num_envs, max_episode_steps)

    make_vector_env.__doc__ = f"Batched {env_cls.__name__}: ``num_envs`` agents stepped in one numpy call."
    return make_vector_env
