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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from steer_envs.core.interaction import InteractionKind
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import bool_array, boolean, describe, integer, one_of, real_array, real_scalar
from steer_envs.envs.human_view import HumanView
from steer_envs.envs.render import REGION_PALETTE, Canvas

#: accepted ``render_size`` (pixels per side): a region map above this size costs hundreds of MB to draw.
RENDER_SIZE_RANGE = (8, 1024)
#: largest ``num_envs`` of a vector env (its state arrays are allocated up front).
MAX_NUM_ENVS = 1_000_000
#: largest accepted step length (s) and speed limit: beyond them a step leaves every workspace and the
#: action space's float32 bounds overflow
MAX_DT = 1e3
MAX_SPEED = 1e6
#: accepted ``reward_type`` values (Gymnasium-Robotics' names): ``"sparse"`` (the default) or ``"dense"``.
REWARD_TYPES: tuple[str, ...] = ("sparse", "dense")
RewardType = Literal["sparse", "dense"]
#: dense reward: the reward of one mode advanced (the potential's unit, see :meth:`KinematicTaskModel.potential`).
#: Large enough that moving toward a sub-goal earns a per-step reward
#: SAC's default entropy bonus does not drown (PolygonNav: ~0.4 a step at full speed).
DENSE_REWARD_SCALE = 100.0


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


class _PotentialMemo:
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


class Kinematic2DEnv(gym.Env[np.ndarray, np.ndarray]):
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
        self._potential = _PotentialMemo(model)

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
        super().reset(seed=check_seed(seed, owner))
        options = check_options(options, _KINEMATIC_OPTIONS, owner)
        if options.get("state") is not None:
            self._pos = _check_xy(options["state"], "options['state']", owner)[None, :]
            self._pos = np.clip(self._pos, self.model.low, self.model.high)
        else:
            self._pos = self.model.sample_start(self.np_random, 1).astype(np.float64)
        self._memory = self.model.reset_memory(self._pos)
        self._trail = [self._pos[0].copy()]
        if self.render_mode == "human":
            self.render()
        return self._obs(), self._info(False)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Move by ``dt * action``; the action (2 finite reals) is clipped to speed ``max_speed``."""
        velocity = self.velocity_of(_check_action(action, self.action_space, f"{type(self).__name__}.step"))
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
        target = self._pos[0] + _check_xy(delta, "delta", owner) if to is None else _check_xy(to, "to", owner)
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

        :meth:`render` draws this env's state with it, :meth:`Kinematic2DVectorEnv.render` each agent's.
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


class Kinematic2DVectorEnv(VectorEnv):
    """``num_envs`` agents of one domain stepped together in numpy.

    A drop-in for the sync vector env of the same id (``gymnasium.make_vec(...,
    vectorization_mode="sync")``), only faster: the same dynamics, rewards,
    termination and ``NEXT_STEP`` autoreset (Gymnasium's default), and the same
    ``infos`` key for key, as Gymnasium's ``VectorEnv._add_info`` batches the single
    env's info: ``mode`` (int64), ``mode_name`` (object array of str), ``sensors``
    (a dict AP -> ``(num_envs,)`` bool array, with its ``_AP`` masks), ``success``,
    ``is_success``, ``constraint_violation`` and ``perturbed`` (bool), each key with
    its all-True ``_key`` mask. Each agent draws its starts from its own random
    generator: ``reset(seed=s)`` seeds agent ``i`` with ``s + i`` (or takes a list
    of ``num_envs`` seeds), so agent ``i`` starts where a single env reset with
    ``seed=s + i`` starts and, given the same actions, follows the same path
    (autoresets included). ``render()`` returns a tuple of one frame per agent
    (each what the single env would draw), as the sync vector env does;
    ``render_mode="human"`` (one window) is single-env only and refused with a ``ValueError``.

    Unlike the sync vector env, ``reset(options={"state": xy})`` takes one start
    per agent, ``xy`` of shape ``(num_envs, 2)``; :meth:`perturb` pushes a subset.

    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import steer_envs
    >>> venv = gym.make_vec("steer_envs/PolygonNav-3Mode-v0", num_envs=4, vectorization_mode="vector_entry_point")
    >>> obs, infos = venv.reset(seed=0)
    >>> obs, rewards, terminated, truncated, infos = venv.step(np.zeros((4, 2), dtype=np.float32))
    >>> obs.shape, infos["mode"].shape, sorted(infos["sensors"]), infos["mode_name"][0]
    ((4, 2), (4,), ['_in_p1', '_in_p2', 'in_p1', 'in_p2'], 'free')
    """

    metadata: dict[str, Any] = {  # noqa: RUF012 - VectorEnv's type
        "render_modes": ["rgb_array"],
        "render_fps": 30,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(self, env: Kinematic2DEnv, num_envs: int, max_episode_steps: int | None = None) -> None:
        owner = type(self).__name__
        if not isinstance(env, Kinematic2DEnv):
            raise TypeError(f"{owner}: env must be a Kinematic2DEnv, got {describe(env)}")
        self.env = env
        self.model = env.model
        self.num_envs = integer(num_envs, "num_envs", low=1, high=MAX_NUM_ENVS, owner=owner)
        self.max_episode_steps = (
            None if max_episode_steps is None else integer(max_episode_steps, "max_episode_steps", low=1, owner=owner)
        )
        self.single_observation_space = env.observation_space
        self.single_action_space = env.action_space
        self.observation_space = batch_space(env.observation_space, self.num_envs)
        self.action_space = batch_space(env.action_space, self.num_envs)
        if env.render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"{owner}: render_mode={env.render_mode!r} is single-env only; use 'rgb_array' or None")
        self.render_mode = env.render_mode
        n = self.num_envs
        self._pos = np.zeros((n, 2))
        self._memory = np.zeros((n, self.model.memory_size), dtype=np.int64)
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._needs_reset = np.zeros(n, dtype=bool)
        self._mode_names = np.array(self.model.task.modes, dtype=object)
        self._potential = _PotentialMemo(self.model)
        # agent i's generator (a single env's ``np_random``), made when first needed from its pending seed
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._pending_seeds: list[int | None] = [None] * n
        self._trails: list[list[np.ndarray]] = [[] for _ in range(n)] if self.render_mode is not None else []

    def _rng(self, i: int) -> np.random.Generator:
        """Agent ``i``'s generator, seeded like a single env's ``np_random`` (its pending seed, else at random)."""
        rng = self._rngs[i]
        if rng is None:
            rng, _ = seeding.np_random(self._pending_seeds[i])
            self._rngs[i] = rng
        return rng

    def _starts(self, agents: np.ndarray) -> np.ndarray:
        """Fresh starts ``(len(agents), 2)``, each drawn as a single env's ``reset`` draws it (one per generator)."""
        return np.concatenate(
            [self.model.sample_start(self._rng(int(i)), 1) for i in agents], axis=0, dtype=np.float64
        ).reshape(-1, 2)

    def _obs(self) -> np.ndarray:
        sensors = self.model.read(self._memory, self._pos).sensors if self.env.observe_sensors else None
        return observe(self._pos, sensors)

    def _infos(self, violation: np.ndarray, perturbed: np.ndarray | None = None) -> dict[str, Any]:
        """The single env's info of every agent, batched as ``VectorEnv._add_info`` does (``_key`` masks)."""
        n = self.num_envs
        aps = self.model.task.sensors
        reading = self.model.read(self._memory, self._pos)
        mode = reading.mode.astype(np.int64)
        success = reading.success.astype(bool)
        # one allocation for every ``_key`` mask and one for the sensor columns (rows: separate arrays to the user)
        masks = np.ones((len(aps) + 7, n), dtype=bool)
        columns = np.ascontiguousarray(np.asarray(reading.sensors, dtype=bool).T)
        sensors: dict[str, np.ndarray] = {}
        for j, ap in enumerate(aps):
            sensors[ap], sensors[f"_{ap}"] = columns[j], masks[7 + j]
        values: dict[str, Any] = {
            "mode": mode,
            "mode_name": self._mode_names[mode],
            "sensors": sensors,
            "success": success,
            "is_success": success.copy(),  # stable-baselines3's name, as in the single env
            "constraint_violation": np.array(violation, dtype=bool),
            "perturbed": np.zeros(n, dtype=bool) if perturbed is None else perturbed.copy(),
        }
        infos: dict[str, Any] = {}
        for j, (key, value) in enumerate(values.items()):
            infos[key], infos[f"_{key}"] = value, masks[j]
        return infos

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start all episodes, agent ``i`` as a single env reset with ``seed + i`` (see the class docstring).

        ``seed``: None (each agent's generator goes on), an int >= 0, or a list of ``num_envs``
        seeds (None or int >= 0), as the sync vector env takes them. ``options={"state": xy}`` with
        ``xy`` of shape ``(num_envs, 2)`` sets the starts (clipped onto the workspace).
        """
        owner = f"{type(self).__name__}.reset"
        seeds = check_vector_seed(seed, self.num_envs, owner)
        options = check_options(options, _KINEMATIC_OPTIONS, owner)
        states = None
        if options.get("state") is not None:
            states = real_array(options["state"], "options['state']", shape=(self.num_envs, 2), owner=owner)
        if seed is not None and not isinstance(seed, list | tuple):  # the vector env's own ``np_random``
            super().reset(seed=seeds[0])
        for i, s in enumerate(seeds):
            if s is not None:
                self._rngs[i], self._pending_seeds[i] = None, s
        if states is not None:
            self._pos = np.clip(states, self.model.low, self.model.high)
        else:
            self._pos = self._starts(np.arange(self.num_envs))
        self._memory = self.model.reset_memory(self._pos)
        self._elapsed[:] = 0
        self._needs_reset[:] = False
        if self.render_mode is not None:
            self._trails = [[p.copy()] for p in self._pos]
        return self._obs(), self._infos(np.zeros(self.num_envs, dtype=bool))

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every agent; ``actions`` is ``(num_envs, 2)`` finite reals (the single env's rules, per row)."""
        actions = real_array(actions, "actions", shape=(self.num_envs, 2), owner=f"{type(self).__name__}.step")
        velocity = self.env.velocity_of(actions)
        prev = self._pos
        dense = self.env.reward_type == "dense"
        before = self._potential(self._memory, prev) if dense else np.zeros(self.num_envs)
        moved = np.clip(prev + self.env.dt * velocity, self.model.low, self.model.high)
        memory, violation = self.model.advance(self._memory, prev, moved)
        # agents whose episode ended last step are reset instead of moved (their own generator draws the start)
        resetting = self._needs_reset
        if resetting.any():
            agents = np.flatnonzero(resetting)
            fresh = self._starts(agents)
            moved[resetting] = fresh
            memory[resetting] = self.model.reset_memory(fresh)
            violation = violation & ~resetting
        self._pos, self._memory = moved, memory
        self._elapsed = np.where(resetting, 0, self._elapsed + 1)
        infos = self._infos(violation)
        after = self._potential(self._memory, self._pos) if dense else before
        rewards = self.env.rewards(infos["success"], violation, before, after)
        terminated = infos["success"] | (self.env.terminate_on_violation & violation)
        truncated = np.zeros(self.num_envs, dtype=bool)
        if self.max_episode_steps is not None:
            truncated = self._elapsed >= self.max_episode_steps
        terminated &= ~resetting
        truncated &= ~resetting
        rewards = np.where(resetting, 0.0, rewards)
        self._needs_reset = terminated | truncated
        if self.render_mode is not None:
            for i in range(self.num_envs):
                if resetting[i]:
                    self._trails[i] = [self._pos[i].copy()]
                else:
                    self._trails[i].append(self._pos[i].copy())
        return self._obs(), rewards, terminated, truncated, infos

    def perturb(self, to: np.ndarray, mask: np.ndarray) -> dict[str, Any]:
        """Move the agents selected by ``mask`` (``(num_envs,)`` bool) to ``to[mask]``: a push from outside.

        The batched counterpart of :meth:`Kinematic2DEnv.perturb` (``to=``): the
        task memory follows ``model.teleport`` and no violation is reported.
        ``mask`` must hold real bools (not 0/1); ``to`` is ``(num_envs, 2)``
        reals, finite in the selected rows. Returns the new ``infos`` (``perturbed`` is ``mask``).
        """
        owner = f"{type(self).__name__}.perturb"
        mask = bool_array(mask, "mask", shape=(self.num_envs,), owner=owner)
        target = real_array(to, "to", shape=(self.num_envs, 2), finite=False, owner=owner)
        if not np.all(np.isfinite(target[mask])):
            raise ValueError(f"{owner}: to must be finite in the rows selected by mask (no NaN or inf)")
        prev = self._pos.copy()
        self._pos = np.where(mask[:, None], np.clip(target, self.model.low, self.model.high), self._pos)
        self._memory = np.where(mask[:, None], self.model.teleport(self._memory, prev, self._pos), self._memory)
        if self.render_mode is not None:
            for i in np.flatnonzero(mask):
                self._trails[i].append(self._pos[i].copy())
        return self._infos(np.zeros(self.num_envs, dtype=bool), perturbed=mask)

    def render(self) -> tuple[Any, ...] | None:
        """One frame per agent (a tuple, as the sync vector env returns); Nones without ``render_mode``."""
        if self.render_mode != "rgb_array":
            return (None,) * self.num_envs
        return tuple(self.env.draw_frame(self._pos[i], self._trails[i]) for i in range(self.num_envs))


def check_vector_seed(seed: Any, num_envs: int, owner: str) -> list[int | None]:
    """A vector ``reset`` seed as one seed per agent: None (all None), an int ``s`` >= 0
    (``s, s + 1, ...``) or a list of ``num_envs`` seeds, each None or an int >= 0 (the sync vector env's rules).
    """
    if seed is None:
        return [None] * num_envs
    if isinstance(seed, list | tuple):
        if len(seed) != num_envs:
            raise ValueError(f"{owner}: seed as a list must hold num_envs={num_envs} seeds, got {len(seed)}")
        return [check_seed(s, owner) for s in seed]
    first = check_seed(seed, owner)
    assert first is not None
    return [first + i for i in range(num_envs)]


_KINEMATIC_OPTIONS = frozenset({"state"})


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


def check_reward_type(reward_type: Any, owner: str) -> RewardType:
    """``reward_type``: ``"sparse"`` or ``"dense"`` (:data:`REWARD_TYPES`); anything else is a ``ValueError``."""
    if not isinstance(reward_type, str):
        raise TypeError(f"{owner}: reward_type must be one of {list(REWARD_TYPES)}, got {describe(reward_type)}")
    one_of(reward_type, "reward_type", REWARD_TYPES, owner=owner)
    return "dense" if reward_type == "dense" else "sparse"


def check_seed(seed: Any, owner: str) -> int | None:
    """A ``reset`` seed: None or an int >= 0 (numpy ints too), as a Python int."""
    return None if seed is None else integer(seed, "seed", low=0, owner=owner)


def check_options(options: Any, keys: frozenset[str], owner: str) -> dict[str, Any]:
    """``reset`` options: None or a dict with only the known ``keys``; unknown keys are an error, not ignored."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise TypeError(f"{owner}: options must be a dict or None, got {describe(options)}")
    unknown = set(options) - keys
    if unknown:
        raise ValueError(f"{owner}: unknown reset options {sorted(map(str, unknown))}; expected some of {sorted(keys)}")
    return dict(options)


def check_render_mode(render_mode: Any, modes: list[str], owner: str) -> str | None:
    """``render_mode``: None or one of ``modes``."""
    if render_mode is None:
        return None
    if not isinstance(render_mode, str):
        raise TypeError(f"{owner}: render_mode must be one of {modes} or None, got {describe(render_mode)}")
    return one_of(render_mode, "render_mode", modes, owner=owner)


def _check_xy(value: Any, name: str, owner: str | None = None) -> np.ndarray:
    """A state or displacement: 2 finite real numbers (see :func:`steer_envs.core.validation.real_array`)."""
    return real_array(value, name, shape=(2,), owner=owner)


def _check_action(action: Any, space: spaces.Space[Any], owner: str | None = None) -> np.ndarray:
    """An action: finite real numbers of the action space's shape (not yet clipped)."""
    return real_array(action, "action", shape=space.shape, owner=owner)


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


def vector_factory(env_cls: type[Kinematic2DEnv]) -> Any:
    """A ``vector_entry_point`` for ``gymnasium.make_vec`` that batches ``env_cls``."""

    def make_vector_env(num_envs: int = 1, max_episode_steps: int | None = None, **kwargs: Any) -> Kinematic2DVectorEnv:
        mode = kwargs.get("render_mode")
        if isinstance(mode, str) and mode not in Kinematic2DVectorEnv.metadata["render_modes"]:  # before a window
            raise ValueError(f"make_vector_env: render_mode={mode!r} is single-env only; use 'rgb_array' or None")
        return Kinematic2DVectorEnv(env_cls(**kwargs), num_envs, max_episode_steps)

    make_vector_env.__doc__ = f"Batched {env_cls.__name__}: ``num_envs`` agents stepped in one numpy call."
    return make_vector_env
