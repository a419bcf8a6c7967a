"""Observation/action trajectories for training chunked policies: the dataset, its statistics, its windows.

A :class:`TrajectoryDataset` is what every trajectory policy trains on,
whatever the domain: per step an observation ``(obs_dim,)`` (the policy's
input) and an action ``(action_dim,)``, split into episodes. Two optional
declarations say how the data relates to the env:

* ``obs_indices``: the observations are these entries of the env's
  observation (a policy trained on them selects the same entries at run time);
* ``action_obs_indices``: the actions are position targets, action dimension
  ``j`` being the next value of observation entry ``action_obs_indices[j]``.
  Their statistics are then pooled, so both are normalized alike (what plans
  relative to the current state need).

:class:`PlanWindows` cuts ``(observation history, plan)`` training pairs.
Files are ``.npz`` (no pickle), written atomically; :func:`load_trajectories`
also reads the datasets of :mod:`steer_envs.data.maze_random_walk`.

>>> import numpy as np
>>> obs = np.arange(20, dtype=np.float32).reshape(10, 2)
>>> ds = TrajectoryDataset(obs, obs + 1, episode_starts=[0, 5])
>>> len(ds), ds.obs_dim, ds.action_dim, len(PlanWindows(ds, n_obs=2, horizon=3))
(10, 2, 2, 4)
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.io import atomic_open

__all__ = ["FORMAT", "PlanWindows", "TrajectoryDataset", "load_trajectories", "save_trajectories"]

FORMAT = "steer_envs.trajectories/1"


def _indices(value: Any, name: str, bound: int | None) -> tuple[int, ...] | None:
    if value is None:
        return None
    try:
        out = tuple(int(v) for v in value)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a sequence of ints or None, got {value!r}") from None
    if not out or len(set(out)) != len(out) or min(out) < 0 or (bound is not None and max(out) >= bound):
        limit = f" below {bound}" if bound is not None else ""
        raise ValueError(f"{name} must be distinct ints >= 0{limit}, got {list(out)}")
    return out


@dataclass
class TrajectoryDataset:
    """Steps of observation and action, split into episodes (see the module docstring).

    Attributes:
        observations: ``(N, obs_dim)`` float32, the policy's input at each step.
        actions: ``(N, action_dim)`` float32, the action taken at each step.
        episode_starts: increasing first-step indices of the episodes, starting at 0.
        obs_indices: entries of the env observation the observations are (or ``None``).
        action_obs_indices: observation entry set by each action dimension (or ``None``).
        meta: provenance (JSON-serializable), e.g. the generator's seed.
    """

    observations: np.ndarray
    actions: np.ndarray
    episode_starts: Any = (0,)
    obs_indices: tuple[int, ...] | None = None
    action_obs_indices: tuple[int, ...] | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.observations = np.asarray(self.observations, dtype=np.float32)
        self.actions = np.asarray(self.actions, dtype=np.float32)
        if self.observations.ndim != 2 or self.observations.shape[1] < 1:
            raise ValueError(f"observations must have shape (N, obs_dim), got {self.observations.shape}")
        n = len(self.observations)
        if self.actions.ndim != 2 or len(self.actions) != n or self.actions.shape[1] < 1:
            raise ValueError(f"actions must have shape ({n}, action_dim), got {self.actions.shape}")
        if not (np.all(np.isfinite(self.observations)) and np.all(np.isfinite(self.actions))):
            raise ValueError("observations and actions must be finite")
        starts = np.asarray(self.episode_starts, dtype=np.int64)
        if starts.ndim != 1 or (n and (len(starts) == 0 or starts[0] != 0 or np.any(np.diff(starts) <= 0))):
            raise ValueError(f"episode_starts must be increasing indices starting at 0, got {starts.tolist()}")
        if len(starts) and starts[-1] >= max(n, 1):
            raise ValueError(f"episode_starts must be < {n}, got {starts.tolist()}")
        self.episode_starts = starts
        self.obs_indices = _indices(self.obs_indices, "obs_indices", None)
        if self.obs_indices is not None and len(self.obs_indices) != self.obs_dim:
            raise ValueError(f"obs_indices must have obs_dim={self.obs_dim} entries, got {list(self.obs_indices)}")
        self.action_obs_indices = _indices(self.action_obs_indices, "action_obs_indices", self.obs_dim)
        if self.action_obs_indices is not None and len(self.action_obs_indices) != self.action_dim:
            got = list(self.action_obs_indices)
            raise ValueError(f"action_obs_indices must have action_dim={self.action_dim} entries, got {got}")
        if not isinstance(self.meta, dict):
            raise TypeError(f"meta must be a dict, got {type(self.meta).__name__}")

    def __len__(self) -> int:
        return len(self.observations)

    @property
    def obs_dim(self) -> int:
        """Entries of one observation."""
        return int(self.observations.shape[1])

    @property
    def action_dim(self) -> int:
        """Entries of one action."""
        return int(self.actions.shape[1])

    def episode_slices(self) -> list[slice]:
        """One slice per episode."""
        ends = [*self.episode_starts[1:].tolist(), len(self)]
        return [slice(int(a), int(b)) for a, b in zip(self.episode_starts.tolist(), ends, strict=True)]

    def stats(self) -> dict[str, dict[str, np.ndarray]]:
        """Normalization statistics ``{"observation": {"min", "max", "mean", "std"}, "action": {...}}`` (float64).

        With ``action_obs_indices`` the actions and the observation entries they
        set share statistics computed over both.
        """
        out = {"observation": _moments(self.observations), "action": _moments(self.actions)}
        if self.action_obs_indices is not None:
            idx = list(self.action_obs_indices)
            pooled = _moments(np.concatenate([self.observations[:, idx], self.actions]))
            for key, value in pooled.items():
                out["action"][key] = value.copy()
                out["observation"][key][idx] = value
        return out

    def provenance(self) -> dict[str, Any]:
        """The scalar entries of :attr:`meta` (what a training record keeps to recognise the data)."""
        return {k: v for k, v in self.meta.items() if isinstance(v, (str, int, float, bool)) or v is None}


def _moments(data: np.ndarray) -> dict[str, np.ndarray]:
    arr = np.asarray(data).astype(np.float64)
    if len(arr) == 0:
        raise ValueError("statistics of an empty dataset are undefined")
    return {"min": arr.min(axis=0), "max": arr.max(axis=0), "mean": arr.mean(axis=0), "std": arr.std(axis=0)}


# ----------------------------------------------------------------- windowing
class PlanWindows:
    """Training pairs ``(observation history, plan)`` for chunked policies (DP, ACT).

    Sample ``i`` at step ``t``: ``obs = observations[t - n_obs + 1 .. t]``
    ``(n_obs, obs_dim)`` and ``plan = actions[t + action_start .. t +
    action_start + horizon - 1]`` ``(horizon, action_dim)``. ``action_start = 0``
    gives the next ``horizon`` actions (ACT); LeRobot's Diffusion Policy takes
    ``action_start = 1 - n_obs`` (the plan starts at the oldest observed step).
    Windows never cross an episode boundary. Indexable (a torch-style dataset).

    >>> import numpy as np
    >>> ds = TrajectoryDataset(np.arange(6.0)[:, None], np.arange(1.0, 7.0)[:, None])
    >>> obs, plan = PlanWindows(ds, n_obs=2, horizon=2)[0]
    >>> obs.ravel().tolist(), plan.ravel().tolist()
    ([0.0, 1.0], [2.0, 3.0])
    """

    def __init__(self, dataset: TrajectoryDataset, n_obs: int = 2, horizon: int = 64, action_start: int = 0) -> None:
        if not isinstance(dataset, TrajectoryDataset):
            raise TypeError(f"dataset must be a TrajectoryDataset, got {type(dataset).__name__}")
        if not isinstance(n_obs, (int, np.integer)) or n_obs < 1:
            raise ValueError(f"n_obs must be a positive int, got {n_obs!r}")
        if not isinstance(horizon, (int, np.integer)) or horizon < 1:
            raise ValueError(f"horizon must be a positive int, got {horizon!r}")
        if not isinstance(action_start, (int, np.integer)) or action_start < 1 - n_obs:
            raise ValueError(f"action_start must be an int >= 1 - n_obs = {1 - n_obs}, got {action_start!r}")
        self.observations = np.ascontiguousarray(dataset.observations, dtype=np.float32)
        self.actions = np.ascontiguousarray(dataset.actions, dtype=np.float32)
        self.n_obs, self.horizon, self.action_start = int(n_obs), int(horizon), int(action_start)
        steps = []
        for sl in dataset.episode_slices():
            first = sl.start + self.n_obs - 1
            last = sl.stop - self.action_start - self.horizon  # last t with a full plan inside the episode
            if last >= first:
                steps.append(np.arange(first, last + 1))
        self.steps = np.concatenate(steps) if steps else np.zeros(0, dtype=np.int64)
        self._obs_offsets = np.arange(1 - self.n_obs, 1)
        self._plan_offsets = self.action_start + np.arange(self.horizon)

    def __len__(self) -> int:
        return len(self.steps)

    def __getitem__(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        if not -len(self) <= int(i) < len(self):
            raise IndexError(f"window index {i} out of range for {len(self)} windows")
        obs, plan = self.gather(np.array([int(i)]))
        return obs[0], plan[0]

    def gather(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Batched windows: ``obs (B, n_obs, obs_dim)`` and ``plans (B, horizon, action_dim)`` float32."""
        t = self.steps[np.asarray(indices, dtype=np.int64)]
        return self.observations[t[:, None] + self._obs_offsets], self.actions[t[:, None] + self._plan_offsets]

    def batches(
        self, batch_size: int, rng: np.random.Generator | None = None
    ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """One epoch of batches (shuffled when ``rng`` is given)."""
        if not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
            raise ValueError(f"batch_size must be a positive int, got {batch_size!r}")
        order = rng.permutation(len(self)) if rng is not None else np.arange(len(self))
        for a in range(0, len(order), int(batch_size)):
            yield self.gather(order[a : a + int(batch_size)])


# ------------------------------------------------------------------ file I/O
def save_trajectories(dataset: TrajectoryDataset, path: str | os.PathLike[str]) -> Path:
    """Write ``dataset`` to ``path`` (``.npz``, atomically). Returns the path.

    >>> import tempfile, numpy as np
    >>> ds = TrajectoryDataset(np.zeros((4, 3)), np.ones((4, 2)), meta={"seed": 1})
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     load_trajectories(save_trajectories(ds, f"{tmp}/d.npz")).meta
    {'seed': 1}
    """
    if not isinstance(dataset, TrajectoryDataset):
        raise TypeError(f"dataset must be a TrajectoryDataset, got {type(dataset).__name__}")
    out = Path(path)
    if out.suffix != ".npz":
        raise ValueError(f"path must end with .npz, got {str(out)!r}")
    header = {
        "format": FORMAT,
        "obs_indices": None if dataset.obs_indices is None else list(dataset.obs_indices),
        "action_obs_indices": None if dataset.action_obs_indices is None else list(dataset.action_obs_indices),
        "meta": dataset.meta,
    }
    with atomic_open(out, "wb") as fh:
        np.savez_compressed(
            fh,
            header=np.array(json.dumps(header)),
            observations=dataset.observations,
            actions=dataset.actions,
            episode_starts=dataset.episode_starts,
        )
    return out


def load_trajectories(path: str | os.PathLike[str]) -> TrajectoryDataset:
    """Read a file of :func:`save_trajectories`, or a Maze2D random walk (converted with its declarations).

    ``ValueError`` naming the file when it is missing or of another format.
    """
    src = Path(path)
    if not src.is_file():
        raise ValueError(f"no dataset file at {str(src)!r}")
    try:
        npz = np.load(src, allow_pickle=False)
    except (OSError, EOFError, ValueError) as err:
        raise ValueError(f"{src} is not a readable .npz dataset ({err})") from None
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise ValueError(f"{src} is not an .npz archive of arrays")
    with npz:
        if "header" in npz.files:
            header = json.loads(str(npz["header"]))
            if not isinstance(header, Mapping) or header.get("format") != FORMAT:
                found = header.get("format") if isinstance(header, Mapping) else None
                raise ValueError(f"{src} has format {found!r}, expected {FORMAT!r}")
            return TrajectoryDataset(
                npz["observations"],
                npz["actions"],
                npz["episode_starts"],
                obs_indices=header.get("obs_indices"),
                action_obs_indices=header.get("action_obs_indices"),
                meta=dict(header.get("meta") or {}),
            )
        is_walk = "meta" in npz.files
    if is_walk:
        from steer_envs.data.maze_random_walk import load_random_walk

        return load_random_walk(src).to_trajectories()
    raise ValueError(f"{src} is not a trajectory dataset (no header; expected {FORMAT!r} or a maze2d random walk)")
