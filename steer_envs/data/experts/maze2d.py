"""Scripted expert of Maze2D: D4RL's waypoint controller driving to the goal cell.

The expert plans a cell path to ``env.goal_cell`` by Q-iteration and returns
the current waypoint as the action; the env's PD law tracks it (exactly the
controller that generates the random-walk data, here without waypoint jitter
and run at the env rate). It replans when the goal changes or when the agent
was pushed off its path (``perturb``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.control.waypoint import WaypointController
from steer_envs.envs.maze2d import Maze2DEnv


class Maze2DExpert:
    """Waypoint controller to the goal cell of a :class:`Maze2DEnv`.

    Args:
        env: the unwrapped env (the true state and goal are read from it).
        jitter: waypoint jitter ``-U(0, jitter)`` (0: cell centres; D4RL data: 0.2).
        seed: seed of the jitter.
        solve_thresh: distance at which a waypoint counts as reached.

    Without a goal (``env.goal_cell is None``) the expert holds its position.
    """

    def __init__(self, env: Maze2DEnv, jitter: float = 0.0, seed: int = 0, solve_thresh: float = 0.1) -> None:
        if not isinstance(env, Maze2DEnv):
            raise TypeError(f"env must be an unwrapped Maze2DEnv, got {type(env).__name__}")
        self.env = env
        # D4RL's "slow enough" test is 0.1 per 0.01 s physics step; scale it to one env step
        self.controller = WaypointController(
            env.grid,
            np.random.default_rng(seed),
            jitter=jitter,
            solve_thresh=solve_thresh,
            vel_thresh=0.1 * env.frame_skip,
        )
        self._goal: tuple[int, int] | None = None

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Plan from the start to the episode's goal."""
        self._goal = None
        self._replan_if_needed()

    def _replan_if_needed(self) -> None:
        goal = self.env.goal_cell
        if goal is None:
            self._goal = None
            return
        pos = self.env.state
        if goal != self._goal:
            self.controller.plan(pos, np.array(goal, dtype=np.float64))
            self._goal = goal
            return
        # pushed off the path: the current waypoint is no longer in this or a neighbouring cell
        wp_cell = self.env.xy_to_cell(np.asarray(self.controller.waypoints[self.controller.index]))
        if int(np.abs(wp_cell - self.env.xy_to_cell(pos)).sum()) > 1:
            self.controller.plan(pos, np.array(goal, dtype=np.float64))

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The waypoint to track next (absolute xy, float32)."""
        self._replan_if_needed()
        pos = self.env.state
        if self._goal is None:
            return pos.astype(np.float32)
        waypoint, _ = self.controller.update(float(pos[0]), float(pos[1]))
        return np.asarray(waypoint, dtype=np.float32)
