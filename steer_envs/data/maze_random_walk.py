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
import json
import os
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.control.waypoint import WaypointController
from steer_envs.core.progress import check_progress, progress_bar
from steer_envs.core.validation import integer, one_of
from steer_envs.data.minari_export import (
    check_minari_id,
    minari_load_command,
    minari_root,
    require_minari,
    store_minari_dataset,
)
from steer_envs.data.trajectories import TrajectoryDataset
from steer_envs.envs.maze_grid import MazeGrid, maze_map
from steer_envs.envs.maze_physics import TIMESTEP, MazePhysics
from steer_envs.io import DatasetError, atomic_write_npz, npz_json, read_npz, require_arrays

FORMAT = "steer_envs.maze2d_random_walk/1"
#: the most raw steps one walk may have (the ITPS data uses 1M; D4RL's largest maze2d set 4M)
MAX_STEPS = 10**8
#: D4RL maze2d timeouts (raw steps per goal) by maze.
MAX_LEG_STEPS = {"umaze": 300, "medium": 600, "large": 800}


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
    obs, wps, goals, contact, leg_starts = _walk(
        physics, controller, random_goal, goal, n, subsample, leg_limit, progress
    )
    meta = _walk_meta(maze, seed, n * subsample, subsample, leg_limit)
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


def _walk_meta(maze: str, seed: int, raw_steps: int, subsample: int, leg_limit: int) -> dict[str, Any]:
    """The meta dict of a walk: the format, its settings and the controller's constants."""
    return {
        "format": FORMAT,
        "maze": maze,
        "seed": int(seed),
        "raw_steps": int(raw_steps),
        "subsample": int(subsample),
        "raw_dt": TIMESTEP,
        "dt": TIMESTEP * int(subsample),
        "max_leg_steps": leg_limit,
        "controller": {"q_iterations": 50, "gamma": 0.99, "jitter": 0.2, "solve_thresh": 0.1, "pd": [10.0, 1.0]},
        "coordinates": "cell units, x = row, y = column",
    }


def _walk(
    physics: MazePhysics,
    controller: WaypointController,
    random_goal: Callable[[], np.ndarray],
    goal: np.ndarray,
    n: int,
    subsample: int,
    leg_limit: int,
    progress: bool | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[int]]:
    """Step the walk ``n * subsample`` raw steps from the physics' state toward ``goal`` (planned already).

    Returns the kept states ``(n + 1, 4)`` (the last one after the final step),
    waypoints and goals ``(n, 2)``, wall contacts ``(n,)`` and the samples where a new leg starts.
    """
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
    return obs, wps, goals, contact, leg_starts


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


def to_minari(
    dataset: RandomWalkDataset,
    dataset_id: str,
    *,
    env_id: str | None = None,
    root: str | os.PathLike[str] | None = None,
) -> Any:
    """Store ``dataset`` as a local Minari dataset, one episode per goal (:func:`goal_episodes`); returns it.

    Needs the ``minari`` extra (``pip install "steer-envs[minari]"``: Minari and its hdf5 backend). The
    dataset goes to ``<root>/<dataset_id>`` (``root`` defaults to Minari's data path,
    :func:`~steer_envs.data.minari_export.minari_root`), written atomically by
    :func:`~steer_envs.data.minari_export.store_minari_dataset` (which says where it
    is found, and what happens to an existing dataset of that id).

    Episodes follow the env's rules: rewards are the env's sparse reward
    (:func:`goal_rewards`), an episode terminates on the step that reaches its
    goal and is truncated when the walk's leg timed out. Observations are
    ``(x, y, vx, vy)`` (the env made with ``observe_velocity=True``), actions
    the next xy, step infos ``waypoint`` and ``goal``; ``env_id`` defaults to
    the maze's id.
    """
    if not isinstance(dataset, RandomWalkDataset):
        raise TypeError(f"dataset must be a RandomWalkDataset, got {type(dataset).__name__}")
    dataset_id = check_minari_id(dataset_id)
    if env_id is not None and (not isinstance(env_id, str) or not env_id):
        raise ValueError(f"env_id must be a registered env id or None, got {env_id!r}")
    if root is not None and (not isinstance(root, (str, os.PathLike)) or not str(root).strip()):
        raise TypeError(f"root must be a folder path or None (Minari's data path), got {root!r}")
    episodes = goal_episodes(dataset)
    if not episodes:
        raise ValueError(f"dataset has no complete step to export ({len(dataset)} samples)")
    require_minari("to_minari")
    if env_id is None:
        names = {"umaze": "Umaze", "medium": "Medium", "large": "Large"}
        env_id = f"steer_envs/Maze2D-{names[dataset.meta.get('maze', 'large')]}-v0"
    reached = sum(ep.terminated for ep in episodes)
    return store_minari_dataset(
        dataset_id,
        [_minari_episode(dataset, ep) for ep in episodes],
        env_id=env_id,
        env_kwargs={"observe_velocity": True},
        root=root,
        algorithm_name="D4RL maze2d waypoint controller (random walk)",
        author="steer-envs (steer_envs.data.maze_random_walk)",
        description=f"steer-envs maze2d random walk cut into {len(episodes)} goal episodes ({reached} reach their "
        f"goal; reward: the env's sparse goal-cell reward): {json.dumps(dataset.meta)}",
    )


def _minari_episode(dataset: RandomWalkDataset, ep: GoalEpisode) -> dict[str, Any]:
    """The Minari episode (``EpisodeBuffer`` fields) of one goal episode of ``dataset``."""
    sl = slice(ep.start, ep.stop)
    last = np.arange(len(ep)) == len(ep) - 1
    return {
        "observations": list(dataset.observations[ep.start : ep.stop + 1]),
        "actions": list(dataset.actions[sl]),
        "rewards": list(ep.rewards),
        "terminations": list(last & ep.terminated),
        "truncations": list(last & (not ep.terminated)),
        "infos": {"waypoint": dataset.waypoints[sl], "goal": dataset.goals[sl]},
    }


# ----------------------------------------------------------------------- CLI
_PROG = "python -m steer_envs.data.maze_random_walk"


def _fail(message: str) -> int:
    print(f"{_PROG}: error: {message}", file=sys.stderr)
    return 2


def _parser() -> argparse.ArgumentParser:
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
    return parser


def _output_file(parser: argparse.ArgumentParser, args: argparse.Namespace) -> Path:
    """The ``.npz`` the CLI writes (``--out``, or the default name in that folder); exit 2 on a usage error."""
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
            check_minari_id(args.minari_id)
        except ValueError as err:
            parser.error(f"--minari-id: {err}")
    return out


def _export_minari(ds: RandomWalkDataset, dataset_id: str, minari_root_arg: str | None) -> int:
    """The CLI's ``--minari-id``: store ``ds`` with :func:`to_minari` and print where it went and how to load it."""
    root = None if minari_root_arg is None else Path(os.path.abspath(minari_root_arg))
    try:
        data = to_minari(ds, dataset_id, root=root)
    except (ImportError, OSError, ValueError, TypeError) as err:
        return _fail(f"Minari dataset {dataset_id!r}: {err}")
    where = root if root is not None else minari_root()
    reached = sum(ep.terminated for ep in goal_episodes(ds))
    print(
        f"wrote Minari dataset {dataset_id!r} to {where.joinpath(*dataset_id.split('/'))}: "
        f"{data.total_episodes} episodes ({reached} reach their goal), {data.total_steps} steps"
    )
    # name the folder whenever it is not where a plain minari.load_dataset looks
    default = root is None and "MINARI_DATASETS_PATH" not in os.environ
    print(f"load it with: {minari_load_command(dataset_id, None if default else where)}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m steer_envs.data.maze_random_walk``: generate and save a random-walk dataset.

    Exit 0 done, 2 a usage error or an output that cannot be written (one line on stderr).
    """
    parser = _parser()
    args = parser.parse_args(argv)
    out = _output_file(parser, args)
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
        return _export_minari(ds, args.minari_id, args.minari_root)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
