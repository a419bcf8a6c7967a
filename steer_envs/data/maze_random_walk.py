"""D4RL maze2d random-walk data for the ITPS policies (thesis §2.4.1).

The walk is D4RL's ``generate_maze2d_datasets.py`` controller on the
:mod:`steer_envs.envs.maze2d` physics: Q-iteration over grid cells (50
iterations, gamma 0.99) gives a cell path to the goal; every waypoint except
the goal cell is jittered by ``-U(0, 0.2)`` per coordinate; the point mass
tracks the current waypoint with the PD law ``clip(10 (wp - pos) - vel, +-1)``
at 100 Hz, moving to the next waypoint once within 0.1 of it; when the goal is
reached (or after ``max_leg_steps`` raw steps, D4RL's timeout) a new goal is a
random free cell with ``+-U(0.1)`` noise, *without* resetting the agent. ITPS
uses the first ~1M raw steps subsampled x4 with observation ``xy[t]`` and
action ``xy[t + 1]``.

Dataset file (``.npz``, written atomically; see :class:`RandomWalkDataset`)::

    observations    float32 (N, 4)  x, y, vx, vy at every ``subsample``-th raw step
    actions         float32 (N, 2)  xy of the next observation (ITPS: absolute next waypoint)
    waypoints       float32 (N, 2)  the controller's jittered cell waypoint at that step
    goals           float32 (N, 2)  the walk's current goal
    wall_contact    bool    (N,)    the agent touched a wall in the raw steps of this sample
    episode_starts  int64   (E,)    first sample of each continuous episode ([0]: the walk never resets)
    leg_starts      int64   (L,)    samples where the walk picked a new goal
    meta            str             JSON: maze, seed, raw_steps, subsample, dt, format, ...

Policies train on :meth:`RandomWalkDataset.to_trajectories`, a
:class:`~steer_envs.data.trajectories.TrajectoryDataset` whose observation is
the position (entries 0, 1 of the env observation) and whose action is the
next position (a position target for those entries). :func:`to_minari`
stores a dataset as a Minari dataset (needs Minari's ``hdf5`` backend), cut
into goal episodes by :func:`goal_episodes`.

CLI: ``python -m steer_envs.data.maze_random_walk --out data/ --steps 1000000``; with
``--minari-id steer/maze2d-large-v0`` it also stores the walk as a Minari
dataset (one episode per goal, the env's reward; ``docs/minari.md``).

>>> walk = generate_random_walk("umaze", 400, seed=0, progress=False)
>>> traj = walk.to_trajectories()
>>> len(walk), traj.obs_dim, traj.action_dim, traj.action_obs_indices
(100, 2, 2, (0, 1))
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import re
import shlex
import shutil
import sys
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.core.progress import check_progress, progress_bar
from steer_envs.core.validation import integer, one_of, real_scalar
from steer_envs.data.trajectories import TrajectoryDataset
from steer_envs.envs.maze2d import TIMESTEP, MazeGrid, MazePhysics, maze_map
from steer_envs.io import DatasetError, atomic_directory, atomic_write_npz, npz_json, read_npz, require_arrays

FORMAT = "steer_envs.maze2d_random_walk/1"
#: the most raw steps one walk may have (the ITPS data uses 1M; D4RL's largest maze2d set 4M)
MAX_STEPS = 10**8
#: D4RL maze2d timeouts (raw steps per goal) by maze.
MAX_LEG_STEPS = {"umaze": 300, "medium": 600, "large": 800}
#: grid moves in Q-iteration's action order (ties go to the first): stay, -row, +row, -col, +col.
_MOVES = np.array([[0, 0], [-1, 0], [1, 0], [0, -1], [0, 1]], dtype=np.int64)


def q_iteration(walls: np.ndarray, target: tuple[int, int], iters: int = 50, gamma: float = 0.99) -> np.ndarray:
    """Q-values ``(rows, cols, 5)`` of the grid world with reward 1 for entering ``target``.

    Moves into walls or off the grid stay in place. With ``iters`` sweeps a
    cell farther than ``iters`` moves from the target keeps Q = 0 (D4RL).
    """
    walls = np.asarray(walls, dtype=bool)
    rows, cols = walls.shape
    tr, tc = target
    if not (0 <= tr < rows and 0 <= tc < cols) or walls[tr, tc]:
        raise ValueError(f"target {target} must be a free cell of the {walls.shape} grid")
    cells = np.stack(np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"), axis=-1)  # (R, C, 2)
    dest = cells[:, :, None, :] + _MOVES  # (R, C, 5, 2)
    inside = (dest[..., 0] >= 0) & (dest[..., 0] < rows) & (dest[..., 1] >= 0) & (dest[..., 1] < cols)
    dest = np.where(inside[..., None], dest, cells[:, :, None, :])
    blocked = walls[dest[..., 0], dest[..., 1]]
    dest = np.where(blocked[..., None], cells[:, :, None, :], dest)
    reward = ((dest[..., 0] == tr) & (dest[..., 1] == tc)).astype(np.float64)
    q = np.zeros((rows, cols, len(_MOVES)))
    for _ in range(int(iters)):
        v = q.max(axis=-1)
        q = reward + gamma * v[dest[..., 0], dest[..., 1]]
    return q


def cell_path(
    grid: MazeGrid, start: tuple[int, int], target: tuple[int, int], iters: int = 50
) -> list[tuple[int, int]]:
    """Greedy cell path ``start -> target`` (excluding ``start``) from :func:`q_iteration`."""
    if start == target:
        return [target]
    q = q_iteration(grid.walls, target, iters=iters)
    path, cell = [], start
    for _ in range(grid.walls.size):
        move = _MOVES[int(np.argmax(q[cell]))]
        nxt = (cell[0] + int(move[0]), cell[1] + int(move[1]))
        if nxt == cell:
            raise ValueError(f"no path from {start} to {target} within {iters} Q-iterations")
        path.append(nxt)
        cell = nxt
        if cell == target:
            return path
    raise ValueError(f"no path from {start} to {target}")


class WaypointController:
    """D4RL's maze2d waypoint controller, returning the waypoint the PD law tracks.

    Args:
        grid: the maze.
        rng: randomness of the waypoint jitter.
        jitter: waypoints (except the goal cell) are ``cell - U(0, jitter)`` per coordinate.
        solve_thresh: distance at which a waypoint (or the goal) counts as reached.
        vel_thresh: bound on the displacement between two calls for reaching
            (D4RL: 0.1 per 0.01 s step; scale it with the call period).
    """

    def __init__(
        self,
        grid: MazeGrid,
        rng: np.random.Generator | None = None,
        *,
        jitter: float = 0.2,
        solve_thresh: float = 0.1,
        vel_thresh: float = 0.1,
    ) -> None:
        owner = "WaypointController"
        if not isinstance(grid, MazeGrid):
            raise TypeError(f"{owner}: grid must be a MazeGrid, got {type(grid).__name__}")
        if rng is not None and not isinstance(rng, np.random.Generator):
            raise TypeError(f"{owner}: rng must be a numpy Generator or None, got {type(rng).__name__}")
        self.grid = grid
        self.rng = rng if rng is not None else np.random.default_rng()
        self.jitter = real_scalar(jitter, "jitter", low=0.0, owner=owner)
        self.solve_thresh = real_scalar(solve_thresh, "solve_thresh", low=0.0, owner=owner)
        self.vel_thresh = real_scalar(vel_thresh, "vel_thresh", low=0.0, owner=owner)
        self.target: tuple[int, int] | None = None
        self.waypoints: list[tuple[float, float]] = []
        self.index = 0
        self._prev = (0.0, 0.0)

    def plan(self, pos: np.ndarray, goal_xy: np.ndarray) -> None:
        """Waypoints from the cell of ``pos`` to the cell of ``goal_xy``."""
        start = tuple(int(v) for v in self.grid.xy_to_cell(pos))
        target = tuple(int(v) for v in self.grid.xy_to_cell(goal_xy))
        if self.grid.walls[target]:
            raise ValueError(f"goal {np.asarray(goal_xy).tolist()} lies in a wall cell")
        waypoints = []
        for cell in cell_path(self.grid, start, target):  # type: ignore[arg-type]
            wp = np.array(cell, dtype=np.float64)
            if cell != target:
                wp = wp - self.rng.uniform(size=2) * self.jitter
            waypoints.append((float(wp[0]), float(wp[1])))
        self.target = target  # type: ignore[assignment]
        self.waypoints = waypoints
        self.index = 0
        self._prev = (float(pos[0]), float(pos[1]))

    def update(self, x: float, y: float) -> tuple[tuple[float, float], bool]:
        """The waypoint to track from ``(x, y)`` and whether the goal is solved (D4RL ``get_action``)."""
        if self.target is None:
            raise RuntimeError("WaypointController.update called before plan()")
        tx, ty = self.target
        moved = math.hypot(self._prev[0] - x, self._prev[1] - y)
        solved = math.hypot(x - tx, y - ty) < self.solve_thresh and moved < self.vel_thresh
        wp = (float(tx), float(ty)) if solved else self.waypoints[self.index]
        if not solved and math.hypot(x - wp[0], y - wp[1]) < self.solve_thresh and moved < self.vel_thresh:
            self.index = min(self.index + 1, len(self.waypoints) - 1)
        self._prev = (x, y)
        return wp, solved


@dataclass
class RandomWalkDataset:
    """A subsampled random walk (see the module docstring for every field)."""

    observations: np.ndarray
    actions: np.ndarray
    waypoints: np.ndarray
    goals: np.ndarray
    wall_contact: np.ndarray
    episode_starts: np.ndarray
    leg_starts: np.ndarray
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.observations)
        expected = {
            "observations": (n, 4),
            "actions": (n, 2),
            "waypoints": (n, 2),
            "goals": (n, 2),
            "wall_contact": (n,),
        }
        for name, shape in expected.items():
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"{name} must have shape {shape}, got {np.shape(getattr(self, name))}")
        starts = np.asarray(self.episode_starts)
        if n and (starts.ndim != 1 or len(starts) == 0 or starts[0] != 0 or np.any(np.diff(starts) <= 0)):
            raise ValueError("episode_starts must be increasing indices starting at 0")
        if len(starts) and starts[-1] >= max(n, 1):
            raise ValueError(f"episode_starts must be < {n}")

    def __len__(self) -> int:
        return len(self.observations)

    @property
    def xy(self) -> np.ndarray:
        """Positions ``(N, 2)`` (the ITPS policy state)."""
        return self.observations[:, :2]

    def episode_slices(self) -> list[slice]:
        """One slice per continuous episode."""
        ends = [*self.episode_starts[1:].tolist(), len(self)]
        return [slice(int(a), int(b)) for a, b in zip(self.episode_starts.tolist(), ends, strict=True)]

    def xy_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-coordinate min and max of all positions and actions (for min-max normalization)."""
        pts = np.concatenate([self.xy, self.actions])
        return pts.min(axis=0), pts.max(axis=0)

    def to_trajectories(self) -> TrajectoryDataset:
        """The policy training data: observation = position, action = next position (a position target).

        Declares ``obs_indices=(0, 1)`` (the xy of an ``(x, y)`` or ``(x, y, vx,
        vy)`` env observation) and ``action_obs_indices=(0, 1)``, so positions
        and plans share normalization statistics.
        """
        return TrajectoryDataset(
            self.xy,
            self.actions,
            self.episode_starts,
            obs_indices=(0, 1),
            action_obs_indices=(0, 1),
            meta=dict(self.meta),
        )


def generate_random_walk(
    maze: str = "large",
    steps: int = 1_000_000,
    seed: int = 0,
    *,
    subsample: int = 4,
    max_leg_steps: int | None = None,
    progress: bool | None = None,
) -> RandomWalkDataset:
    """Run the D4RL random walk for ``steps`` raw (0.01 s) steps and keep every ``subsample``-th state.

    Deterministic from ``seed``. ``max_leg_steps`` (default: D4RL's timeout of
    the maze) ends a leg whose goal was not reached. Accepted: ``maze`` one of
    :data:`MAX_LEG_STEPS`; ints ``subsample >= 1``, ``subsample <= steps <=``
    :data:`MAX_STEPS`, ``seed >= 0``, ``max_leg_steps >= 1`` (bools, floats
    and strings are a ``TypeError``). ``progress``: ``None`` a bar only when
    stderr is a terminal, ``True`` always, ``False`` never.
    """
    owner = "generate_random_walk"
    subsample = integer(subsample, "subsample", low=1, owner=owner)
    steps = integer(steps, "steps", low=subsample, high=MAX_STEPS, owner=owner)
    seed = integer(seed, "seed", low=0, owner=owner)
    one_of(maze, "maze", tuple(MAX_LEG_STEPS), owner=owner)
    leg_limit = MAX_LEG_STEPS[maze] if max_leg_steps is None else integer(max_leg_steps, "max_leg_steps", low=1)
    progress = check_progress(progress, owner=owner)

    grid = MazeGrid(maze_map(maze))
    physics = MazePhysics(grid, name=f"maze2d_{maze}")
    rng = np.random.default_rng(seed)
    controller = WaypointController(grid, rng)
    free = grid.free_cells

    def random_goal() -> np.ndarray:
        return free[rng.integers(len(free))] + rng.uniform(-0.1, 0.1, size=2)

    start = grid.project_free(free[rng.integers(len(free))] + rng.uniform(-0.1, 0.1, size=2))
    physics.set_state(start, rng.normal(size=2) * 0.1)  # D4RL reset: noisy velocity
    goal = random_goal()
    controller.plan(start, goal)

    n = int(steps) // int(subsample)
    obs = np.empty((n + 1, 4))
    wps = np.empty((n, 2))
    goals = np.empty((n, 2))
    contact = np.zeros(n, dtype=bool)
    leg_starts = [0]
    qpos, qvel = physics.data.qpos, physics.data.qvel
    model, data = physics.model, physics.data
    step = _mj_step()
    leg_t, replan = 0, False
    bar = progress_bar(total=n * subsample, enabled=progress, unit="step", unit_scale=True, desc="maze2d random walk")
    try:
        for k in range(n * subsample):
            x, y = float(qpos[0]), float(qpos[1])
            if replan:
                controller.plan(np.array([x, y]), goal)
                replan = False
            wp, solved = controller.update(x, y)
            done = solved or leg_t >= leg_limit
            i, phase = divmod(k, subsample)
            if phase == 0:
                obs[i] = (x, y, qvel[0], qvel[1])
                wps[i] = wp
                goals[i] = goal
            data.ctrl[0], data.ctrl[1] = wp
            step(model, data)
            if data.ncon and physics.in_contact():
                contact[i] = True
            leg_t += 1
            if done:
                goal, leg_t, replan = random_goal(), 0, True
                first = -(-(k + 1) // subsample)  # first sample whose state belongs to the new leg
                if first < n:
                    leg_starts.append(first)
            if k % 10_000 == 9_999:
                bar.update(10_000)
        obs[n] = (qpos[0], qpos[1], qvel[0], qvel[1])
    finally:
        bar.close()
    meta = {
        "format": FORMAT,
        "maze": maze,
        "seed": int(seed),
        "raw_steps": n * int(subsample),
        "subsample": int(subsample),
        "raw_dt": TIMESTEP,
        "dt": TIMESTEP * int(subsample),
        "max_leg_steps": leg_limit,
        "controller": {"q_iterations": 50, "gamma": 0.99, "jitter": 0.2, "solve_thresh": 0.1, "pd": [10.0, 1.0]},
        "coordinates": "cell units, x = row, y = column",
    }
    return RandomWalkDataset(
        observations=obs[:n].astype(np.float32),
        actions=obs[1:, :2].astype(np.float32),
        waypoints=wps.astype(np.float32),
        goals=goals.astype(np.float32),
        wall_contact=contact,
        episode_starts=np.zeros(1, dtype=np.int64),
        leg_starts=np.unique(np.asarray(leg_starts, dtype=np.int64)),
        meta=meta,
    )


def _mj_step() -> Any:
    import mujoco

    return mujoco.mj_step


# ------------------------------------------------------------------ file I/O
_ARRAYS = ("observations", "actions", "waypoints", "goals", "wall_contact", "episode_starts", "leg_starts")


def save_random_walk(dataset: RandomWalkDataset, path: str | os.PathLike[str]) -> Path:
    """Write ``dataset`` to ``path`` (``.npz``; temp file + ``os.replace``). Returns the path."""
    if not isinstance(dataset, RandomWalkDataset):
        raise TypeError(f"dataset must be a RandomWalkDataset, got {type(dataset).__name__}")
    out = Path(path)
    if out.suffix != ".npz":
        raise ValueError(f"path must end with .npz, got {str(out)!r}")
    arrays = {name: np.asarray(getattr(dataset, name)) for name in _ARRAYS}
    return atomic_write_npz(out, {"meta": np.array(json.dumps(dataset.meta)), **arrays})


#: array -> (dtype kinds, number of axes) of a saved walk
_SPECS = {
    "observations": ("f", 2),
    "actions": ("f", 2),
    "waypoints": ("f", 2),
    "goals": ("f", 2),
    "wall_contact": ("b", 1),
    "episode_starts": ("iu", 1),
    "leg_starts": ("iu", 1),
}


def load_random_walk(path: str | os.PathLike[str]) -> RandomWalkDataset:
    """Read a dataset written by :func:`save_random_walk`.

    :class:`~steer_envs.io.DatasetError` (a ``ValueError``) naming the file
    when it is missing, not an ``.npz`` of plain arrays, of another format, or
    holds arrays of the wrong dtype or shape, non-finite values or
    out-of-range indices.
    """
    src = Path(path)
    if not src.is_file():
        raise DatasetError(f"no dataset file at {str(src)!r}")
    return random_walk_from_arrays(src, read_npz(src))


def random_walk_from_arrays(src: Path, arrays: Mapping[str, np.ndarray]) -> RandomWalkDataset:
    """A :class:`RandomWalkDataset` from the arrays of the file ``src`` (checked; ``DatasetError`` naming it)."""
    missing = [k for k in (*_ARRAYS, "meta") if k not in arrays]
    if missing:
        raise DatasetError(f"{src} is not a maze2d random-walk dataset (missing {missing})")
    meta = npz_json(src, arrays, "meta")
    if meta.get("format") != FORMAT:
        raise DatasetError(f"{src} has format {meta.get('format')!r}, expected {FORMAT!r}")
    require_arrays(src, arrays, _SPECS, finite=True)
    n = len(arrays["observations"])
    legs = arrays["leg_starts"]
    if len(legs) and (legs[0] < 0 or legs[-1] >= max(n, 1) or np.any(np.diff(legs) <= 0)):
        raise DatasetError(f"{src}: leg_starts must be increasing indices in [0, {n})")
    try:
        return RandomWalkDataset(**{k: arrays[k] for k in _ARRAYS}, meta=meta)
    except (TypeError, ValueError) as err:
        raise DatasetError(f"{src}: {err}") from None


def load_transitions(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(observations (N, 4), actions (N, 2), episode_starts (E,))`` of a saved dataset."""
    ds = load_random_walk(path)
    return ds.observations, ds.actions, ds.episode_starts


# -------------------------------------------------------------------- Minari
def minari_root() -> Path:
    """The folder Minari keeps local datasets in: ``MINARI_DATASETS_PATH``, else ``~/.minari/datasets`` (absolute)."""
    root = os.environ.get("MINARI_DATASETS_PATH")
    return Path(os.path.abspath(os.path.expanduser(root))) if root else Path.home() / ".minari" / "datasets"


@dataclass(frozen=True)
class GoalEpisode:
    """One goal-reaching episode of a walk: samples ``start`` to ``stop - 1`` (and the next observation).

    ``rewards`` are the env's sparse reward of each step (1.0 on the step
    whose next position lies in the goal cell, else 0.0); ``terminated``: the
    last step reached the goal (the env ends the episode there), else the leg
    timed out or the walk ended (truncated).
    """

    start: int
    stop: int
    rewards: np.ndarray
    terminated: bool

    def __len__(self) -> int:
        return self.stop - self.start


def goal_rewards(dataset: RandomWalkDataset) -> np.ndarray:
    """The env's sparse reward ``(N,)`` of each sample: 1.0 when the next position is in the goal's cell.

    The rule of ``steer_envs/Maze2D-*`` (reward 1 and ``success`` when the
    agent is in the goal cell), with the walk's goal of that sample; the
    next position is the sample's action (the next xy).
    """
    if not isinstance(dataset, RandomWalkDataset):
        raise TypeError(f"dataset must be a RandomWalkDataset, got {type(dataset).__name__}")
    grid = MazeGrid(maze_map(str(dataset.meta.get("maze", "large"))))
    if len(dataset) == 0:
        return np.zeros(0, dtype=np.float64)
    reached = np.all(grid.xy_to_cell(dataset.actions) == grid.xy_to_cell(dataset.goals), axis=-1)
    return reached.astype(np.float64)


def goal_episodes(dataset: RandomWalkDataset) -> list[GoalEpisode]:
    """The walk cut into episodes as the env would run them: one per goal (leg), ending where it is reached.

    A leg starts where the walk drew a new goal (``leg_starts``, and every
    ``episode_starts``); its episode ends (terminated) at the first step whose
    reward is 1, so the samples the walk spent in the goal cell settling
    after that are not in any episode; a leg that never reaches its goal is
    truncated at its end. The last sample of each continuous walk is dropped
    (its next observation was not kept); empty episodes are skipped.

    >>> walk = generate_random_walk("umaze", 2000, seed=0, progress=False)
    >>> episodes = goal_episodes(walk)
    >>> all(e.rewards.sum() == float(e.terminated) for e in episodes)
    True
    """
    rewards = goal_rewards(dataset)
    n = len(dataset)
    walk_ends = {*(int(s) for s in dataset.episode_starts[1:].tolist()), n}
    cuts = sorted({0, *(int(s) for s in dataset.leg_starts.tolist()), *walk_ends} - {n})
    episodes = []
    for a, b in zip(cuts, [*cuts[1:], n], strict=True):
        stop = b - 1 if b in walk_ends else b  # the next observation of b - 1 is kept only inside a walk
        hit = np.flatnonzero(rewards[a:stop])
        terminated = len(hit) > 0
        if terminated:
            stop = a + int(hit[0]) + 1
        if stop > a:
            episodes.append(GoalEpisode(a, stop, rewards[a:stop].copy(), terminated))
    return episodes


def _torn_minari_export(folder: Path) -> bool:
    """Whether ``folder`` is what a killed export of an earlier version left: our dataset, with no episodes."""
    meta_file = folder / "data" / "metadata.json"
    try:
        meta = json.loads(meta_file.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return not any(folder.rglob("*.hdf5"))  # not even metadata: nothing of value
    if not isinstance(meta, dict):
        return False
    authors = meta.get("author")
    authors = [authors] if isinstance(authors, str) else authors if isinstance(authors, list) else []
    ours = not authors or any(str(a).startswith("steer-envs") for a in authors)
    return ours and not meta.get("total_episodes")


def _check_minari_id(dataset_id: Any) -> str:
    if not isinstance(dataset_id, str) or not dataset_id or dataset_id != dataset_id.strip("/"):
        raise ValueError(f"dataset_id must be a Minari id such as 'steer/maze2d-large-v0', got {dataset_id!r}")
    parts = dataset_id.split("/")
    if any(part in ("", ".", "..") for part in parts) or not re.fullmatch(r"[A-Za-z0-9_.\-/]+", dataset_id):
        raise ValueError(f"dataset_id must be a Minari id such as 'steer/maze2d-large-v0', got {dataset_id!r}")
    return dataset_id


def to_minari(
    dataset: RandomWalkDataset,
    dataset_id: str,
    *,
    env_id: str | None = None,
    root: str | os.PathLike[str] | None = None,
) -> Any:
    """Store ``dataset`` as a local Minari dataset, one episode per goal (:func:`goal_episodes`); returns it.

    Needs a Minari storage backend (``pip install "minari[hdf5]"``). The
    dataset goes to ``<root>/<dataset_id>``; ``root`` (a relative path is
    taken from the working directory) defaults to Minari's own data path
    (:func:`minari_root`: ``MINARI_DATASETS_PATH``, else
    ``~/.minari/datasets``), where ``minari.load_dataset(dataset_id)`` finds
    it; for another ``root``, load with ``MINARI_DATASETS_PATH=<root>``.

    Episodes follow the env's rules: rewards are the env's sparse reward
    (:func:`goal_rewards`), an episode terminates on the step that reaches its
    goal and is truncated when the walk's leg timed out. Observations are
    ``(x, y, vx, vy)`` (the env made with ``observe_velocity=True``), actions
    the next xy, step infos ``waypoint`` and ``goal``; ``env_id`` defaults to
    the maze's id.

    The dataset is built in a temp folder next to its final place and renamed
    there when complete (:func:`steer_envs.io.atomic_directory`), so a killed
    export leaves no dataset (and its leftovers are removed by the next
    export into the same folder); an existing complete dataset of that id is
    refused (``FileExistsError``), a torn one left by a killed export of an
    earlier version (no episodes) is replaced. ``MINARI_DATASETS_PATH`` is
    the same after the call as before.
    """
    if not isinstance(dataset, RandomWalkDataset):
        raise TypeError(f"dataset must be a RandomWalkDataset, got {type(dataset).__name__}")
    dataset_id = _check_minari_id(dataset_id)
    if env_id is not None and (not isinstance(env_id, str) or not env_id):
        raise ValueError(f"env_id must be a registered env id or None, got {env_id!r}")
    if root is not None and (not isinstance(root, (str, os.PathLike)) or not str(root).strip()):
        raise TypeError(f"root must be a folder path or None (Minari's data path), got {root!r}")
    episodes = goal_episodes(dataset)
    if not episodes:
        raise ValueError(f"dataset has no complete step to export ({len(dataset)} samples)")
    if importlib.util.find_spec("h5py") is None and importlib.util.find_spec("pyarrow") is None:
        raise ImportError('to_minari needs a Minari storage backend: pip install "minari[hdf5]"')
    import gymnasium as gym
    import minari
    from minari.data_collector import EpisodeBuffer
    from minari.dataset.minari_storage import MinariStorage
    from minari.namespace import create_namespace, list_local_namespaces

    if env_id is None:
        names = {"umaze": "Umaze", "medium": "Medium", "large": "Large"}
        env_id = f"steer_envs/Maze2D-{names[dataset.meta.get('maze', 'large')]}-v0"
    # absolute from here on: Minari joins its data path with the id itself, and a relative path taken
    # once from the working directory and once from the temp folder was the doubled path of #21
    base = minari_root() if root is None else Path(os.path.abspath(os.path.expanduser(os.fspath(root))))
    final = base.joinpath(*dataset_id.split("/"))
    overwrite = False
    if final.exists():
        if not (final.is_dir() and _torn_minari_export(final)):
            raise FileExistsError(
                f"a Minari dataset {dataset_id!r} already exists at {final}; use another id or version"
            )
        overwrite = True
    namespace = dataset_id.rsplit("/", 1)[0] if "/" in dataset_id else None
    buffers = []
    for k, ep in enumerate(episodes):
        sl = slice(ep.start, ep.stop)
        n = len(ep)
        buffers.append(
            EpisodeBuffer(
                id=k,
                observations=list(dataset.observations[ep.start : ep.stop + 1]),
                actions=list(dataset.actions[sl]),
                rewards=list(ep.rewards),
                terminations=list((np.arange(n) == n - 1) & ep.terminated),
                truncations=list((np.arange(n) == n - 1) & (not ep.terminated)),
                infos={"waypoint": dataset.waypoints[sl], "goal": dataset.goals[sl]},
            )
        )
    reached = sum(ep.terminated for ep in episodes)
    description = (
        f"steer-envs maze2d random walk cut into {len(episodes)} goal episodes ({reached} reach their goal; "
        f"reward: the env's sparse goal-cell reward): {json.dumps(dataset.meta)}"
    )
    env = gym.make(env_id, observe_velocity=True)
    previous = os.environ.get("MINARI_DATASETS_PATH")
    try:
        if namespace is not None:
            os.environ["MINARI_DATASETS_PATH"] = str(base)
            if namespace not in list_local_namespaces():
                create_namespace(namespace)
        with atomic_directory(final, overwrite=overwrite) as build:
            scratch = build.absolute() / "_minari"
            os.environ["MINARI_DATASETS_PATH"] = str(scratch)
            with warnings.catch_warnings():  # Minari recommends author/e-mail/permalink metadata; none applies here
                warnings.filterwarnings("ignore", category=UserWarning, module=r"minari\.")
                created = minari.create_dataset_from_buffers(
                    dataset_id=dataset_id,
                    buffer=buffers,
                    env=env,
                    algorithm_name="D4RL maze2d waypoint controller (random walk)",
                    author="steer-envs (steer_envs.data.maze_random_walk)",
                    description=description,
                )
                del created  # its storage points into the temp folder
            scratch.joinpath(*dataset_id.split("/"), "data").rename(build / "data")
            shutil.rmtree(scratch)
    finally:
        if previous is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = previous
        env.close()
    return minari.MinariDataset(MinariStorage.read(final / "data"))


def minari_load_command(dataset_id: str, root: str | os.PathLike[str] | None = None) -> str:
    """A shell line that loads the dataset ``dataset_id`` stored under ``root`` (default: Minari's data path).

    >>> print(minari_load_command("steer/walk-v0", "/data/minari"))
    MINARI_DATASETS_PATH=/data/minari python -c "import minari; print(minari.load_dataset('steer/walk-v0'))"
    """
    dataset_id = _check_minari_id(dataset_id)
    code = f"import minari; print(minari.load_dataset({dataset_id!r}))"
    line = f'python -c "{code}"'
    if root is None:
        return line
    return f"MINARI_DATASETS_PATH={shlex.quote(os.path.abspath(os.path.expanduser(os.fspath(root))))} {line}"


# ----------------------------------------------------------------------- CLI
_PROG = "python -m steer_envs.data.maze_random_walk"


def _fail(message: str) -> int:
    print(f"{_PROG}: error: {message}", file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    """``python -m steer_envs.data.maze_random_walk``: generate and save a random-walk dataset.

    Exit 0 done, 2 a usage error or an output that cannot be written (one line on stderr).
    """
    parser = argparse.ArgumentParser(
        prog=_PROG,
        description="Generate the D4RL maze2d random walk (ITPS training data) as an .npz dataset.",
    )
    parser.add_argument("--out", required=True, help="output .npz file, or a directory for the default name")
    parser.add_argument("--maze", default="large", choices=sorted(MAX_LEG_STEPS), help="maze map (default: large)")
    parser.add_argument("--steps", type=int, default=1_000_000, help="raw 100 Hz steps (default: 1000000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    parser.add_argument("--subsample", type=int, default=4, help="keep every k-th raw step (default: 4)")
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show (or hide) the progress bar (default: shown only when stderr is a terminal)",
    )
    parser.add_argument(
        "--minari-id",
        default=None,
        help="also store a Minari dataset with this id, one episode per goal with the env's reward (needs "
        "minari[hdf5]); it goes to Minari's data path (MINARI_DATASETS_PATH, default ~/.minari/datasets) unless "
        "--minari-root says otherwise",
    )
    parser.add_argument(
        "--minari-root",
        default=None,
        help="folder to store the Minari dataset in instead (load it with MINARI_DATASETS_PATH=<folder>; the "
        "line to do so is printed)",
    )
    args = parser.parse_args(argv)

    if not args.out.strip():
        parser.error("--out must not be empty")
    out = Path(args.out)
    if out.suffix != ".npz":
        out = out / f"maze2d-{args.maze}-randomwalk-seed{args.seed}.npz"
    if out.is_dir():
        parser.error(f"--out {args.out!r}: {out} is a folder")
    blocker = next((p for p in out.parents if p.exists() and not p.is_dir()), None)
    if blocker is not None:
        parser.error(f"--out {args.out!r}: {blocker} is not a folder")
    if args.minari_root is not None and not args.minari_id:
        parser.error("--minari-root needs --minari-id")
    if args.minari_id is not None:
        try:
            _check_minari_id(args.minari_id)
        except ValueError as err:
            parser.error(f"--minari-id: {err}")
    tic = time.perf_counter()
    try:
        ds = generate_random_walk(args.maze, args.steps, args.seed, subsample=args.subsample, progress=args.progress)
    except (TypeError, ValueError) as err:
        parser.error(str(err))
    elapsed = time.perf_counter() - tic
    try:
        save_random_walk(ds, out)
    except OSError as err:
        return _fail(f"cannot write {out}: {err}")
    grid = MazeGrid(maze_map(args.maze))
    in_wall = float(grid.is_wall(ds.actions).mean())
    raw = ds.meta["raw_steps"]
    print(f"wrote {out}: {len(ds)} samples ({raw} raw steps, x{args.subsample}), {len(ds.leg_starts)} goals")
    print(f"speed: {raw / elapsed:,.0f} raw steps/s ({elapsed:.1f} s)")
    print(f"waypoints in wall cells: {in_wall:.4%}; samples touching a wall: {float(ds.wall_contact.mean()):.4%}")
    if args.minari_id:
        root = None if args.minari_root is None else Path(os.path.abspath(args.minari_root))
        try:
            data = to_minari(ds, args.minari_id, root=root)
        except (ImportError, OSError, ValueError, TypeError) as err:
            return _fail(f"Minari dataset {args.minari_id!r}: {err}")
        where = root if root is not None else minari_root()
        reached = sum(ep.terminated for ep in goal_episodes(ds))
        print(
            f"wrote Minari dataset {args.minari_id!r} to {where.joinpath(*args.minari_id.split('/'))}: "
            f"{data.total_episodes} episodes ({reached} reach their goal), {data.total_steps} steps"
        )
        # name the folder whenever it is not where a plain minari.load_dataset looks
        default = root is None and "MINARI_DATASETS_PATH" not in os.environ
        print(f"load it with: {minari_load_command(args.minari_id, None if default else where)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
