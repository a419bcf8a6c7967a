"""Maze2D: the D4RL point-mass maze in MuJoCo, in the ITPS coordinate convention.

The maze maps are gymnasium-robotics' ``U_MAZE`` (5x5), ``MEDIUM_MAZE`` (8x8)
and ``LARGE_MAZE`` (9x12, the ITPS maze). Coordinates are *cell units* with
``x = row`` and ``y = column`` (ITPS / D4RL): cell ``(r, c)`` is the square
``[r - 0.5, r + 0.5) x [c - 0.5, c + 0.5)`` centred on ``xy = (r, c)``.

Physics (D4RL ``maze2d``, also gymnasium-robotics' ``assets/point/point.xml``):
a sphere of radius 0.1 and density 1000 on two slide joints (damping 1),
timestep 0.01 s, Euler, frictionless contacts, no gravity; walls are boxes of
half-size 0.5. Unlike D4RL, the walls sit exactly on the cell grid: D4RL puts
the particle body at (1.2, 1.2) and the walls at ``(r + 1, c + 1)``, so its
``qpos`` cells are shifted by -0.2; here the ITPS collision rule (round to the
nearest cell) and the physical walls agree exactly.

Action = the next absolute xy *waypoint*. It is tracked by D4RL's PD law
``u = clip(10 (wp - pos) - 1 vel, -1, 1)``, force ``100 u`` (the D4RL motor
gear), implemented as a MuJoCo affine actuator so it is re-evaluated at every
physics step. One env step is ``frame_skip`` physics steps (default 4:
0.04 s, the ITPS data rate, which is D4RL's 100 Hz subsampled x4).

Description
    Navigate a point mass to a goal cell drawn at every reset (``sample_goal=True``,
    the registered default); one mode, ``navigate``. Coordinates: ``x`` is the *row*
    (pointing down the map as printed) and ``y`` the *column*, in cell units with cell
    ``(r, c)`` centred on ``(r, c)``. This differs from gymnasium-robotics' PointMaze,
    whose ``(x, y)`` are metric, centred on the maze and ``x`` runs along the columns:
    PointMaze's ``(x, y)`` is our ``(rows - 1) / 2 - y_pm, x_pm + (cols - 1) / 2``
    (with its default ``maze_size_scaling=1``).

Observation
    ``Box(float32)``: ``(x, y)`` (``observe_velocity=True``: ``(x, y, vx, vy)``; with
    ``observe_sensors=True`` followed by ``at_goal``, ``in_wall_contact`` as 0/1; with
    ``observe_goal=True`` followed by the goal cell's centre xy).
    ``goal_conditioned=True`` (:class:`Maze2DGoalEnv`): a Dict of ``observation`` (that
    box), ``achieved_goal`` (the agent's xy) and ``desired_goal`` (the goal cell's
    centre). The goal is in ``info["goal"]`` either way.

Action
    ``Box(float32)``: the next absolute waypoint in ``[0, rows-1] x [0, cols-1]``,
    tracked by the PD law; ``normalize_actions=True``: ``[-1, 1]^2`` mapped linearly onto it;
    ``relative_actions=True``: the waypoint's offset from the agent, ``[-1, 1]^2`` cells.

Rewards
    ``reward_type="sparse"`` (default): 1 in the goal cell, else 0 (D4RL). ``"dense"``:
    ``-MazeGrid.path_distance(xy, goal) / extent``, the distance along the maze's free
    cells in maze heights (never positive). Both are :meth:`Maze2DEnv.goal_reward` of the
    achieved and desired goal (``compute_reward`` of the goal-conditioned env).

Termination
    On reaching the goal cell (``info["success"]``); wall contacts are reported
    (``constraint_violation``), never terminal; truncation at 300 / 600 / 800 steps (Umaze /
    Medium / Large, registered; the dense RL variants below 150 / 300 / 400 steps of 0.08 s,
    the same time).

Registered ids
    ``steer_envs/Maze2D-{Umaze,Medium,Large}-v0`` and, for each maze, ``...Dense-v0``
    (``reward_type="dense"``, ``observe_goal=True``: the goal the reward measures is in the
    observation, ``normalize_actions=True``), ``...Goal-v0`` (goal-conditioned, sparse, the
    plain ids' waypoint actions) and ``...GoalDense-v0`` (dense, ``normalize_actions=True``),
    e.g. ``steer_envs/Maze2D-UmazeGoalDense-v0``. Gymnasium-Robotics
    names its dense variant ``PointMaze_UMazeDense-v3`` and has no separate goal id (its
    mazes are always goal-conditioned); here the plain ids keep the ITPS Box observation.
    The RL variants (``...Dense``, ``...Goal``, ``...GoalDense``) observe the velocity; the dense
    ones (``...Dense``, ``...GoalDense``) also act at half the ITPS rate (``frame_skip=8``, 0.08 s
    a step: half as many decisions for the same motion, which lets SAC learn the Large maze
    within 100k steps), while ``...Goal`` keeps 0.04 s, at which HER learns Umaze fastest.

    No vector entry point: use ``gymnasium.make_vec(id, n, vectorization_mode="sync")``. The
    physics is one MuJoCo ``MjData`` per agent, so it cannot be batched in numpy as the 2D domains
    are. Measured on one core (2026-12, Umaze): a single env runs 3.8k steps/s, the sync vector env
    3.5k agent-steps/s with 64 envs, and four bare ``mj_step`` calls (one env step without the
    per-substep contact check or the info) 14.7k/s. So a batched Maze2D could win at most ~4x, and
    only with the contact check and info moved into C (``mujoco.rollout``); the numpy machinery
    would not help.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from steer_envs.core.env import ClosableEnv
from steer_envs.core.interaction import InteractionKind
from steer_envs.core.regions import Boxes
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import boolean, describe, integer, one_of, real_scalar
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
from steer_envs.envs.maze_grid import AGENT_RADIUS, MAZE_NAMES, MazeGrid, check_points, maze_map
from steer_envs.envs.maze_physics import GEAR, TIMESTEP, MazePhysics
from steer_envs.envs.render import Canvas

#: accepted ``frame_skip`` (physics steps per env step) and ``cell_px`` (rendered pixels per cell).
FRAME_SKIP_RANGE = (1, 1000)
CELL_PX_RANGE = (4, 256)

_WALL_RGB = (90, 90, 100)
_FREE_RGB = (250, 250, 250)
_GRID_RGB = (225, 225, 232)
_GOAL_RGB = (170, 230, 170)


class Maze2DEnv(ClosableEnv[Any, np.ndarray]):
    """MuJoCo point mass in a D4RL maze; the action is the next absolute xy waypoint.

    Args:
        maze: ``"umaze"``, ``"medium"``, ``"large"`` (gymnasium-robotics maps) or
            a custom map (rows of the int 1 = wall, 0 / "r" / "g" / "c" = free;
            see :class:`~steer_envs.envs.maze_grid.MazeGrid`).
        frame_skip: physics steps (0.01 s each) per env step, an int in
            :data:`FRAME_SKIP_RANGE`; 4 = the ITPS data rate.
        observe_velocity: observation is ``(x, y, vx, vy)`` instead of ``(x, y)`` (a bool).
        sample_goal: draw a random goal cell at every reset (``info["success"]``
            = agent in the goal cell, which ends the episode). With False,
            there is no goal unless ``reset(options={"goal_cell": ...})`` sets one
            (the ITPS setting: free navigation, never "successful"). A bool.
        render_mode: ``"rgb_array"``, ``"human"`` (the same frames in a pygame window at
            ``metadata["render_fps"]``, shown by every ``reset`` and ``step``; needs the
            ``human`` extra) or None.
        cell_px: rendered pixels per cell, an int in :data:`CELL_PX_RANGE`.
        reward_type: ``"sparse"`` (default: 1 in the goal cell, else 0) or ``"dense"``
            (``-path_distance / extent``, see below).
        goal_conditioned: a ``GoalEnv``-style Dict observation (``observation``,
            ``achieved_goal`` = the agent's xy, ``desired_goal`` = the goal cell's centre)
            and ``compute_reward`` for hindsight relabelling (stable-baselines3's
            ``HerReplayBuffer``); needs ``sample_goal=True``. A bool. ``True`` makes a
            :class:`Maze2DGoalEnv` (stable-baselines3 takes any env with a
            ``compute_reward`` for a goal env, so only that subclass has one).
        observe_sensors: append the sensor APs (``at_goal``, ``in_wall_contact``) as 0/1
            to the (inner) observation. A bool.
        observe_goal: append the goal cell's centre xy to the flat observation (the
            agent's own xy where there is no goal), so a flat-observation RL agent can
            see the goal the reward measures; the ``...Dense-v0`` Maze2D ids set it.
            Needs ``goal_conditioned=False`` (the Dict already has ``desired_goal``). A bool.
        normalize_actions: the action space is ``[-1, 1]^2``, mapped linearly onto the
            waypoint box ``[0, rows-1] x [0, cols-1]``. A bool.
        relative_actions: the action is the waypoint's offset from the agent, in
            ``[-1, 1]^2`` cells (clipped into it; already normalised, so
            ``normalize_actions`` changes nothing): "head this way" instead of "go
            to that point", which a goal-conditioned RL policy learns far more easily.
            A bool.

    Booleans must be real bools (``"no"`` is refused, not read as True);
    numbers are never parsed from strings. Actions, ``perturb`` arguments and
    ``options["state"]`` are 2 finite reals (lists, numpy arrays, torch
    tensors, read detached); strings, bools, complex numbers and objects
    raise ``TypeError``, NaN/inf and wrong shapes ``ValueError``.

    Observation: ``float32`` xy (ITPS policies use xy) or xy + velocity (+ sensors)
    (+ the goal's xy); with ``goal_conditioned`` a Dict of it and the achieved / desired goal.
    Action: ``float32`` waypoint in ``[0, rows-1] x [0, cols-1]`` (clipped into it); with
    ``relative_actions`` its offset from the agent in ``[-1, 1]^2`` cells.
    Reward: ``"sparse"``: 1 when the goal cell is reached, else 0 (D4RL sparse).
    ``"dense"``: ``-MazeGrid.path_distance(xy, goal) / extent`` (the distance along
    the maze, in maze heights; 0 without a goal): non-positive, so reaching the goal
    (which ends the episode) soon is best. Both are :meth:`goal_reward` of the
    achieved and desired goal.
    ``info``: ``mode`` (always 0, ``"navigate"``), ``sensors``
    (``at_goal``, ``in_wall_contact``), ``success``, ``constraint_violation``
    (the agent had a MuJoCo contact with a wall during the step), ``perturbed``,
    ``goal`` (the goal cell's centre xy, float64, or None without a goal).
    Reset options: ``state`` (xy start; must not be in a wall cell, it is nudged
    off walls closer than the agent's radius), ``goal_cell`` ((row, col) or None).
    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import steer_envs
    >>> env = gym.make("steer_envs/Maze2D-Umaze-v0")
    >>> obs, info = env.reset(seed=0, options={"state": [1.0, 1.0], "goal_cell": (3, 1)})
    >>> obs, reward, terminated, truncated, info = env.step(np.array([1.0, 2.0], dtype=np.float32))
    >>> env.unwrapped.xy_to_cell(obs).tolist(), info["constraint_violation"]
    ([1, 1], False)
    >>> bool(env.unwrapped.is_wall(np.array([2.0, 1.0])))
    True
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array", "human"], "render_fps": 25}  # noqa: RUF012 - Env's type
    interaction_kinds: tuple[InteractionKind, ...] = ("point", "sketch", "nudge")
    _OPTION_KEYS = frozenset({"state", "goal_cell"})

    def __new__(cls, *args: Any, **kwargs: Any) -> Maze2DEnv:
        """``Maze2DEnv(..., goal_conditioned=True)`` makes a :class:`Maze2DGoalEnv`."""
        if cls is Maze2DEnv and kwargs.get("goal_conditioned") is True:
            cls = Maze2DGoalEnv
        return super().__new__(cls)

    def __init__(
        self,
        maze: str | Sequence[Sequence[int | str]] = "large",
        *,
        frame_skip: int = 4,
        observe_velocity: bool = False,
        sample_goal: bool = True,
        render_mode: str | None = None,
        cell_px: int = 32,
        reward_type: RewardType = "sparse",
        goal_conditioned: bool = False,
        observe_sensors: bool = False,
        observe_goal: bool = False,
        normalize_actions: bool = False,
        relative_actions: bool = False,
    ) -> None:
        owner = type(self).__name__
        layout: Sequence[Sequence[int | str]]
        if isinstance(maze, str):
            self.maze_name = one_of(maze, "maze", MAZE_NAMES, owner=owner)
            layout = maze_map(maze)
        else:
            self.maze_name = "custom"
            layout = maze
        self.frame_skip = integer(
            frame_skip, "frame_skip", low=FRAME_SKIP_RANGE[0], high=FRAME_SKIP_RANGE[1], owner=owner
        )
        self.observe_velocity = boolean(observe_velocity, "observe_velocity", owner=owner)
        self.sample_goal = boolean(sample_goal, "sample_goal", owner=owner)
        self.render_mode = check_render_mode(render_mode, self.metadata["render_modes"], owner)
        self.cell_px = integer(cell_px, "cell_px", low=CELL_PX_RANGE[0], high=CELL_PX_RANGE[1], owner=owner)
        self._view = HumanView(self.metadata["render_fps"], owner) if self.render_mode == "human" else None
        self.reward_type: RewardType = check_reward_type(reward_type, owner)
        self.goal_conditioned = boolean(goal_conditioned, "goal_conditioned", owner=owner)
        self.observe_sensors = boolean(observe_sensors, "observe_sensors", owner=owner)
        self.observe_goal = boolean(observe_goal, "observe_goal", owner=owner)
        self.normalize_actions = boolean(normalize_actions, "normalize_actions", owner=owner)
        self.relative_actions = boolean(relative_actions, "relative_actions", owner=owner)
        if self.goal_conditioned and not self.sample_goal:
            raise ValueError(f"{owner}: goal_conditioned=True needs sample_goal=True (a goal every episode)")
        if self.goal_conditioned and self.observe_goal:
            raise ValueError(f"{owner}: observe_goal=True needs goal_conditioned=False (its Dict has desired_goal)")
        self.grid = MazeGrid(layout)
        self.physics = MazePhysics(self.grid, name=f"maze2d_{self.maze_name}")
        self.dt = TIMESTEP * self.frame_skip
        self.task = _maze_task(self.maze_name, self.grid)
        self.observation_space: spaces.Space[Any] = self._make_observation_space()
        self.action_space = self._make_action_space()
        self.goal_cell: tuple[int, int] | None = None
        self._contact = False
        self._trail: list[np.ndarray] = []
        self._background: np.ndarray | None = None

    def _make_observation_space(self) -> spaces.Space[Any]:
        """The flat Box of the observed parts, or the goal-conditioned Dict around it."""
        rows, cols = self.grid.shape
        pos_lo, pos_hi = np.array([-0.5, -0.5]), np.array([rows - 0.5, cols - 0.5])
        if self.observe_velocity:
            # |force| <= GEAR and joint damping 1: from rest no speed component can exceed GEAR
            lo = np.concatenate([pos_lo, [-GEAR, -GEAR]]).astype(np.float32)
            hi = np.concatenate([pos_hi, [GEAR, GEAR]]).astype(np.float32)
        else:
            lo, hi = pos_lo.astype(np.float32), pos_hi.astype(np.float32)
        if self.observe_sensors:
            lo = np.concatenate([lo, np.zeros(2, dtype=np.float32)])
            hi = np.concatenate([hi, np.ones(2, dtype=np.float32)])
        if self.observe_goal:
            lo = np.concatenate([lo, pos_lo.astype(np.float32)])
            hi = np.concatenate([hi, pos_hi.astype(np.float32)])
        inner = spaces.Box(lo, hi, dtype=np.float32)
        if not self.goal_conditioned:
            return inner
        goal_space = spaces.Box(pos_lo.astype(np.float32), pos_hi.astype(np.float32), dtype=np.float32)
        return spaces.Dict({"observation": inner, "achieved_goal": goal_space, "desired_goal": goal_space})

    def _make_action_space(self) -> spaces.Box:
        """``[-1, 1]^2`` (normalised or relative actions), else the waypoint box of the grid."""
        if self.normalize_actions or self.relative_actions:
            return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        return spaces.Box(self.grid.low.astype(np.float32), self.grid.high.astype(np.float32), dtype=np.float32)

    # -------------------------------------------------------------- geometry
    @property
    def extent(self) -> float:
        """Maze height in cells: distances are divided by it (ITPS Table 2.1)."""
        return self.grid.extent

    def cell_to_xy(self, cells: np.ndarray) -> np.ndarray:
        """Cell centres of integer cells ``(..., 2)`` (row, col)."""
        return self.grid.cell_to_xy(cells)

    def xy_to_cell(self, xy: np.ndarray) -> np.ndarray:
        """Cell of each point ``(..., 2)``: clipped to the grid, rounded to the nearest cell."""
        return self.grid.xy_to_cell(xy)

    def is_wall(self, xy: np.ndarray) -> np.ndarray:
        """Whether each point ``(..., 2)`` lies in a wall cell."""
        return self.grid.is_wall(xy)

    def plan_collides(self, plans: np.ndarray) -> np.ndarray:
        """ITPS rule: plans ``(..., H, 2)`` collide if any waypoint is in a wall cell."""
        return self.grid.plan_collides(plans)

    # ----------------------------------------------------------------- state
    @property
    def state(self) -> np.ndarray:
        """The agent's xy (a copy, float64)."""
        return self.physics.pos

    @property
    def velocity(self) -> np.ndarray:
        """The agent's velocity in cells per second (a copy)."""
        return self.physics.vel

    @property
    def goal_xy(self) -> np.ndarray | None:
        """Centre of the goal cell, or None without a goal."""
        return None if self.goal_cell is None else np.array(self.goal_cell, dtype=np.float64)

    def _obs(self) -> Any:
        d = self.physics.data
        state = np.concatenate([d.qpos[:2], d.qvel[:2]]) if self.observe_velocity else d.qpos[:2]
        if self.observe_sensors:
            state = np.concatenate([state, [float(self._at_goal()), float(self.physics.in_contact())]])
        goal = self.goal_xy
        if self.observe_goal:
            state = np.concatenate([state, d.qpos[:2] if goal is None else goal])
        if not self.goal_conditioned:
            return state.astype(np.float32)
        return {
            "observation": state.astype(np.float32),
            "achieved_goal": d.qpos[:2].astype(np.float32),
            "desired_goal": (d.qpos[:2] if goal is None else goal).astype(np.float32),
        }

    def goal_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any = None) -> np.ndarray:
        """The reward (of this env's ``reward_type``) of reaching ``achieved_goal`` when ``desired_goal`` is asked.

        Vectorised (``GoalEnv`` / hindsight relabelling): goals are xy ``(2,)`` or
        ``(..., 2)``; returns float64 of shape ``(...)`` (a 0-d array for single goals).
        ``info`` is not used. Sparse: 1 where both lie in the same cell, else 0.
        Dense: ``-MazeGrid.path_distance / extent``.
        """
        achieved = check_points(achieved_goal, "achieved_goal")
        desired = check_points(desired_goal, "desired_goal")
        if achieved.shape != desired.shape:
            raise ValueError(
                f"goal_reward: achieved_goal and desired_goal must have the same shape, "
                f"got {achieved.shape} and {desired.shape}"
            )
        batch = achieved.shape[:-1]
        if self.reward_type == "sparse":
            same = (self.grid.xy_to_cell(achieved) == self.grid.xy_to_cell(desired)).all(axis=-1)
            return same.astype(np.float64)
        flat = self.grid.path_distance(achieved.reshape(-1, 2), desired.reshape(-1, 2))
        return (-flat / self.extent).reshape(batch)

    def _at_goal(self) -> bool:
        if self.goal_cell is None:
            return False
        return tuple(self.grid.xy_to_cell(self.physics.data.qpos[:2]).tolist()) == self.goal_cell

    def _info(self, violation: bool, perturbed: bool = False) -> dict[str, Any]:
        at_goal = self._at_goal()
        return {
            "mode": 0,
            "mode_name": "navigate",
            "sensors": {"at_goal": at_goal, "in_wall_contact": self.physics.in_contact()},
            "success": at_goal,
            "is_success": at_goal,  # stable-baselines3's name (Monitor, ep_success_buffer)
            "constraint_violation": bool(violation),
            "perturbed": perturbed,
            "goal": self.goal_xy,
        }

    def _check_cell(self, value: Any, name: str) -> tuple[int, int]:
        owner = f"{type(self).__name__}.reset"
        if not isinstance(value, (tuple, list, np.ndarray)):
            raise TypeError(f"{owner}: {name} must be a (row, col) pair of ints, got {describe(value)}")
        if len(value) != 2:
            raise ValueError(f"{owner}: {name} must be a (row, col) pair of ints, got {describe(value)}")
        r, c = (integer(v, f"{name}[{i}]", owner=owner) for i, v in enumerate(value))
        if not (0 <= r < self.grid.shape[0] and 0 <= c < self.grid.shape[1]):
            raise ValueError(f"{owner}: {name} {describe(value)} lies outside the {self.grid.shape} grid")
        if self.grid.walls[r, c]:
            raise ValueError(f"{owner}: {name} {describe(value)} is a wall cell")
        return r, c

    # ------------------------------------------------------------------- API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Start an episode at a random free cell (+-U(0.1) noise, D4RL) at rest.

        ``seed``: None or an int >= 0. ``options``: None or a dict with ``state``
        (xy start, 2 finite reals, not in a wall cell), ``goal_cell`` ((row, col)
        ints of a free cell, or None for no goal); other keys are refused.
        """
        owner = f"{type(self).__name__}.reset"
        # every argument is checked before anything changes: a refused reset leaves the episode as it was
        seed = check_seed(seed, owner)
        options = check_options(options, self._OPTION_KEYS, owner)
        given = None
        if options.get("state") is not None:
            given = check_xy(options["state"], "options['state']", owner)
            if bool(self.grid.is_wall(given)):
                raise ValueError(f"{owner}: options['state'] {given.tolist()} lies in a wall cell")
        goal: tuple[int, int] | None = None
        if "goal_cell" in options:
            if options["goal_cell"] is None and self.goal_conditioned:
                raise ValueError(
                    f"{owner}: options['goal_cell'] must be a (row, col) cell, not None, when goal_conditioned"
                )
            if options["goal_cell"] is not None:
                goal = self._check_cell(options["goal_cell"], "options['goal_cell']")
        super().reset(seed=seed)
        rng = self.np_random
        if given is not None:
            start = self.grid.project_free(given)
        else:
            cell = self.grid.free_cells[rng.integers(len(self.grid.free_cells))]
            start = self.grid.project_free(cell + rng.uniform(-0.1, 0.1, size=2))
        self.physics.set_state(start)
        if "goal_cell" in options:
            self.goal_cell = goal
        elif self.sample_goal:
            start_cell = tuple(self.grid.xy_to_cell(start).tolist())
            choices = [tuple(c) for c in self.grid.free_cells.tolist() if tuple(c) != start_cell]
            self.goal_cell = choices[int(rng.integers(len(choices)))] if choices else None
        else:
            self.goal_cell = None
        self._trail = [self.state]
        if self.render_mode == "human":
            self.render()
        return self._obs(), self._info(False)

    def step(self, action: np.ndarray) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Track the waypoint ``action`` (2 finite reals, clipped into the grid) for ``frame_skip`` physics steps.

        With ``normalize_actions`` the action is in ``[-1, 1]^2`` (clipped into it) and mapped onto the grid;
        with ``relative_actions`` it is the offset from the agent in ``[-1, 1]^2`` cells (clipped into it).
        """
        action = check_action(action, self.action_space, f"{type(self).__name__}.step")
        if self.relative_actions:
            action = self.state + np.clip(action, -1.0, 1.0)
        elif self.normalize_actions:
            action = self.grid.low + (np.clip(action, -1.0, 1.0) + 1.0) / 2.0 * (self.grid.high - self.grid.low)
        waypoint = np.clip(action, self.grid.low, self.grid.high)
        touched = self.physics.step(waypoint, self.frame_skip)
        self._trail.append(self.state)
        info = self._info(touched)
        goal = self.goal_xy
        if goal is None:
            reward = 0.0
        elif self.reward_type == "sparse":
            reward = 1.0 if info["success"] else 0.0
        else:
            # from the float32 goals the observation shows, so compute_reward(obs goals) is this reward exactly
            reward = float(self.goal_reward(self.state.astype(np.float32), goal.astype(np.float32), info))
        if self.render_mode == "human":
            self.render()
        return self._obs(), reward, bool(info["success"]), False, info

    def perturb(self, delta: np.ndarray | None = None, *, to: np.ndarray | None = None) -> dict[str, Any]:
        """Displace the agent by ``delta`` (or move it ``to`` a position): a push from outside.

        The simulator state is moved and the velocity zeroed. A target in or
        against a wall is projected to the closest position where the agent
        touches no wall (the push stops at the wall). ``delta``/``to`` are 2
        finite reals. Returns the new ``info``.
        """
        owner = f"{type(self).__name__}.perturb"
        if (delta is None) == (to is None):
            raise ValueError(f"{owner}: pass exactly one of `delta` (displacement) or `to` (target state)")
        target = self.state + check_xy(delta, "delta", owner) if to is None else check_xy(to, "to", owner)
        self.physics.set_state(self.grid.project_free(target))
        self._trail.append(self.state)
        return self._info(False, perturbed=True)

    # ------------------------------------------------------------- rendering
    def _canvas(self) -> Canvas:
        rows, cols = self.grid.shape
        # display coordinates: u = column (right), v = -row (up), so row 0 is drawn at the top
        return Canvas(
            np.array([-0.5, -(rows - 0.5)]), np.array([cols - 0.5, 0.5]), cols * self.cell_px, rows * self.cell_px
        )

    @staticmethod
    def _display(xy: np.ndarray) -> np.ndarray:
        arr = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return np.stack([arr[:, 1], -arr[:, 0]], axis=1)

    def _scene(self) -> Canvas:
        canvas = self._canvas()
        if self._background is None:
            px = self.cell_px
            walls = np.repeat(np.repeat(self.grid.walls, px, axis=0), px, axis=1)
            lines = np.zeros_like(walls)
            lines[::px] = True
            lines[:, ::px] = True
            image = np.empty((*walls.shape, 3), dtype=np.uint8)
            image[:] = _FREE_RGB
            image[lines & ~walls] = _GRID_RGB
            image[walls] = _WALL_RGB
            self._background = image
        canvas.image[:] = self._background
        if self.goal_cell is not None:
            r, c = self.goal_cell
            px = self.cell_px
            canvas.image[r * px + 1 : (r + 1) * px, c * px + 1 : (c + 1) * px] = _GOAL_RGB
        if len(self._trail) > 1:
            canvas.polyline(self._display(np.asarray(self._trail)), (40, 40, 200), thickness=2)
        return canvas

    def _draw_agent(self, canvas: Canvas) -> None:
        radius = max(3, round(AGENT_RADIUS * self.cell_px * 1.5))
        canvas.disc(self._display(self.state)[0], radius, (220, 30, 30))

    def render(self) -> np.ndarray | None:
        """Top-down RGB image: walls, goal cell (green), trail (blue), agent (red); shown in the window with "human".

        Returns the image with ``render_mode="rgb_array"``, else None.
        """
        if self.render_mode is None:
            return None
        canvas = self._scene()
        self._draw_agent(canvas)
        if self._view is not None:
            self._view.show(canvas.image)
            return None
        return canvas.image

    def close(self) -> None:
        """Close the ``"human"`` window, if one is open."""
        if self._view is not None:
            self._view.close()
        super().close()

    def render_overlay(self, sketch: np.ndarray | None = None, plans: np.ndarray | None = None) -> np.ndarray:
        """The scene with sampled ``plans`` ``(B, H, 2)`` and a user ``sketch`` ``(G, 2)`` drawn on top.

        Plans in collision (ITPS rule) are drawn orange, the others teal; the
        sketch is magenta with a dot at its start. Works in any ``render_mode``.
        """
        canvas = self._scene()
        if plans is not None:
            arr = check_points(plans, "plans")
            if arr.ndim == 2:
                arr = arr[None]
            if arr.ndim != 3:
                raise ValueError(f"plans must have shape (B, H, 2) or (H, 2), got {arr.shape}")
            collides = self.grid.plan_collides(arr)
            for plan, hit in zip(arr, collides, strict=True):
                canvas.polyline(self._display(plan), (240, 140, 30) if hit else (20, 160, 160), thickness=1)
        if sketch is not None:
            pts = check_points(sketch, "sketch")
            if pts.ndim != 2 or len(pts) == 0:
                raise ValueError(f"sketch must have shape (G, 2) with G >= 1, got {pts.shape}")
            canvas.polyline(self._display(pts), (200, 30, 200), thickness=3)
            canvas.disc(self._display(pts[0])[0], max(2, self.cell_px // 8), (200, 30, 200))
        self._draw_agent(canvas)
        return canvas.image

    def pixel_to_xy(self, u: float, v: float) -> np.ndarray:
        """Maze xy of image pixel column ``u``, row ``v`` of :meth:`render` (e.g. a mouse sketch); finite reals."""
        u = real_scalar(u, "u", owner="Maze2DEnv.pixel_to_xy")
        v = real_scalar(v, "v", owner="Maze2DEnv.pixel_to_xy")
        return np.array([v / self.cell_px - 0.5, u / self.cell_px - 0.5])


def _wall_boxes(grid: MazeGrid) -> Boxes:
    """The wall cells as unit boxes; those on the grid's border reach far outward.

    :meth:`MazeGrid.is_wall` clips a point to the grid first, so everything
    beyond the border is wall: a box that stopped at the border would let a
    safety cost push a waypoint out of the maze instead of back in.
    """
    cells = np.argwhere(grid.walls).astype(np.float64)
    low, high = cells - 0.5, cells + 0.5
    top = np.asarray(grid.walls.shape, dtype=np.float64) - 1
    low[cells == 0] -= _BEYOND
    high[cells == top] += _BEYOND
    return Boxes(low, high)


#: how far border wall boxes reach beyond the grid (cells)
_BEYOND = 1e3


def _maze_task(maze_name: str, grid: MazeGrid) -> TaskSpec:
    """The one-mode task of a maze: ``navigate``, whatever the sensors read; its wall cells are forbidden."""
    return TaskSpec(
        name=f"maze2d-{maze_name}",
        modes=("navigate",),
        sensors=("at_goal", "in_wall_contact"),
        sensor_modes={
            frozenset(): "navigate",
            frozenset({"at_goal"}): "navigate",
            frozenset({"in_wall_contact"}): "navigate",
            frozenset({"at_goal", "in_wall_contact"}): "navigate",
        },
        regions={"walls": _wall_boxes(grid)},
        forbidden=("walls",),
    )


class Maze2DGoalEnv(Maze2DEnv):
    """Goal-conditioned Maze2D (``Maze2D-<maze>Goal-v0``, ``...GoalDense-v0``): a ``GoalEnv``-style env.

    The observation is a Dict: ``observation`` (the :class:`Maze2DEnv` observation),
    ``achieved_goal`` (the agent's xy) and ``desired_goal`` (the goal cell's centre),
    as gymnasium-robotics' ``PointMaze`` (in this package's coordinates: ``x = row``,
    ``y = column``). :meth:`compute_reward` is vectorised, so stable-baselines3's
    ``HerReplayBuffer`` relabels goals with it. Takes :class:`Maze2DEnv`'s arguments
    (``goal_conditioned`` must stay True, ``sample_goal`` True).

    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import steer_envs
    >>> env = gym.make("steer_envs/Maze2D-UmazeGoal-v0")
    >>> obs, info = env.reset(seed=0)
    >>> sorted(obs), bool(np.allclose(obs["desired_goal"], info["goal"]))
    (['achieved_goal', 'desired_goal', 'observation'], True)
    >>> env.unwrapped.compute_reward(np.array([[1.0, 1.0], [3.0, 3.0]]), np.array([[1.2, 0.9], [1.0, 1.0]]), None)
    array([1., 0.])
    """

    def __init__(self, *args: Any, goal_conditioned: bool = True, **kwargs: Any) -> None:
        if goal_conditioned is not True:
            raise ValueError(f"Maze2DGoalEnv: goal_conditioned must be True, got {describe(goal_conditioned)}")
        super().__init__(*args, goal_conditioned=True, **kwargs)

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any = None) -> np.ndarray:
        """:meth:`Maze2DEnv.goal_reward` under ``GoalEnv``'s name (vectorised over leading axes)."""
        return self.goal_reward(achieved_goal, desired_goal, info)
