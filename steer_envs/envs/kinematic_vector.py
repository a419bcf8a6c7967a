"""The batched vector env of the 2D kinematic domains: ``num_envs`` agents stepped in one numpy call.

:class:`Kinematic2DVectorEnv` runs a :class:`~steer_envs.envs.kinematic.KinematicTaskModel`
with ``N = num_envs`` (``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``);
:func:`vector_factory` makes a domain's ``vector_entry_point``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from steer_envs.core.validation import bool_array, describe, integer, real_array
from steer_envs.envs.checks import check_options, check_vector_seed
from steer_envs.envs.kinematic import RESET_OPTIONS, Kinematic2DEnv, PotentialMemo, observe

#: largest ``num_envs`` of a vector env (its state arrays are allocated up front).
MAX_NUM_ENVS = 1_000_000


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
        self._potential = PotentialMemo(self.model)
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
        options = check_options(options, RESET_OPTIONS, owner)
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


def vector_factory(env_cls: type[Kinematic2DEnv]) -> Any:
    """A ``vector_entry_point`` for ``gymnasium.make_vec`` that batches ``env_cls``."""

    def make_vector_env(num_envs: int = 1, max_episode_steps: int | None = None, **kwargs: Any) -> Kinematic2DVectorEnv:
        mode = kwargs.get("render_mode")
        if isinstance(mode, str) and mode not in Kinematic2DVectorEnv.metadata["render_modes"]:  # before a window
            raise ValueError(f"make_vector_env: render_mode={mode!r} is single-env only; use 'rgb_array' or None")
        return Kinematic2DVectorEnv(env_cls(**kwargs), num_envs, max_episode_steps)

    make_vector_env.__doc__ = f"Batched {env_cls.__name__}: ``num_envs`` agents stepped in one numpy call."
    return make_vector_env
