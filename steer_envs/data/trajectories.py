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
also reads the datasets of :mod:`steer_envs.data.maze_random_walk`, and
checks every array's header before loading it: a file that is missing,
foreign, malformed or holds non-finite data is a
:class:`~steer_envs.io.DatasetError` naming it.

>>> import numpy as np
>>> obs = np.arange(20, dtype=np.float32).reshape(10, 2)
>>> ds = TrajectoryDataset(obs, obs + 1, episode_starts=[0, 5])
>>> len(ds), ds.obs_dim, ds.action_dim, len(PlanWindows(ds, n_obs=2, horizon=3))
(10, 2, 2, 4)
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.core.validation import describe, integer
from steer_envs.io import DatasetError, atomic_write_npz, npz_json, read_npz, require_arrays

__all__ = [
    "FORMAT",
    "DatasetError",
    "PlanWindows",
    "TrajectoryDataset",
    "load_trajectories",
    "save_trajectories",
    "trajectories_from_arrays",
]

FORMAT = "steer_envs.trajectories/1"


def _raw_array(value: Any, name: str, kind: str, shape: str) -> np.ndarray:
    """``value`` as a numpy array of the dtype numpy gives it (a torch tensor moved to the CPU first).

    ``TypeError`` (``name`` must be ``kind``) for None, strings, bytes, dicts and
    sets; ``ValueError`` (``name`` must be ``shape``) where numpy cannot make an
    array of it (ragged input).
    """
    if hasattr(value, "detach") and callable(value.detach) and hasattr(value, "cpu"):  # a torch tensor
        value = value.detach().cpu().numpy()
    if value is None or isinstance(value, (str, bytes, dict, set)):
        raise TypeError(f"{name} must be {kind}, got {describe(value)}")
    try:
        return np.asarray(value)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name} must be {shape} ({err})") from None


def real_matrix(value: Any, name: str, dtype: type = np.float32) -> np.ndarray:
    """``value`` (a 2-D array, nested sequence or tensor of real numbers) as a ``dtype`` array, not coerced.

    ``TypeError`` for strings, bools, complex numbers and objects (numpy would
    parse ``"1.5"`` and drop imaginary parts); ``ValueError`` for ragged input.
    Shapes and finiteness are the caller's checks.
    """
    raw = _raw_array(value, name, "an array of real numbers", "a rectangular array of real numbers")
    if raw.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold real numbers, got dtype {raw.dtype}")
    return np.asarray(raw, dtype=dtype)


def index_array(value: Any, name: str) -> np.ndarray:
    """``value`` as a 1-D int64 array of integers (floats, bools and strings are a ``TypeError``)."""
    raw = _raw_array(value, name, "a sequence of ints", "a 1-D sequence of ints")
    if raw.size == 0:
        raw = raw.astype(np.int64)
    if raw.dtype.kind not in "iu":
        raise TypeError(f"{name} must hold ints, got dtype {raw.dtype}")
    if raw.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {raw.shape}")
    return raw.astype(np.int64)


def _indices(value: Any, name: str, bound: int | None) -> tuple[int, ...] | None:
    if value is None:
        return None
    if not isinstance(value, (list, tuple, range, np.ndarray)) or (isinstance(value, np.ndarray) and value.ndim != 1):
        raise TypeError(f"{name} must be a 1-D sequence of ints or None, got {describe(value)}")
    out = tuple(integer(v, f"{name} entry") for v in value)
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
        self.observations = real_matrix(self.observations, "observations")
        self.actions = real_matrix(self.actions, "actions")
        if self.observations.ndim != 2 or self.observations.shape[1] < 1:
            raise ValueError(f"observations must have shape (N, obs_dim), got {self.observations.shape}")
        n = len(self.observations)
        if self.actions.ndim != 2 or len(self.actions) != n or self.actions.shape[1] < 1:
            raise ValueError(f"actions must have shape ({n}, action_dim), got {self.actions.shape}")
        if not (np.all(np.isfinite(self.observations)) and np.all(np.isfinite(self.actions))):
            raise ValueError("observations and actions must be finite")
        starts = index_array(self.episode_starts, "episode_starts")
        if n and (len(starts) == 0 or starts[0] != 0 or np.any(np.diff(starts) <= 0)):
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
        if not all(isinstance(k, str) for k in self.meta):
            raise TypeError(f"meta keys must be strings, got {sorted(map(repr, self.meta))[:5]}")

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

    def declarations(self) -> dict[str, Any]:
        """``obs_indices``, ``action_obs_indices`` (lists or ``None``) and ``meta`` as JSON-ready values.

        What a file keeps beside the arrays (this module's header; the
        LeRobotDataset, robomimic and Minari bridges, whose formats have no field
        for them); :meth:`from_episodes` takes them back.
        """
        return {
            "obs_indices": None if self.obs_indices is None else list(self.obs_indices),
            "action_obs_indices": None if self.action_obs_indices is None else list(self.action_obs_indices),
            "meta": self.meta,
        }

    @classmethod
    def with_declarations(
        cls, observations: Any, actions: Any, episode_starts: Any, declarations: Mapping[str, Any] | None
    ) -> TrajectoryDataset:
        """A dataset of these arrays and the :meth:`declarations` a file kept beside them (``None``: none)."""
        side = declarations or {}
        return cls(
            observations,
            actions,
            episode_starts,
            obs_indices=side.get("obs_indices"),
            action_obs_indices=side.get("action_obs_indices"),
            meta=dict(side.get("meta") or {}),
        )

    @classmethod
    def from_episodes(
        cls, observations: Sequence[Any], actions: Sequence[Any], declarations: Mapping[str, Any] | None = None
    ) -> TrajectoryDataset:
        """The episodes ``observations[i]``, ``actions[i]`` one after another, with :meth:`declarations`.

        >>> import numpy as np
        >>> episodes = [np.zeros((3, 2)), np.ones((2, 2))]
        >>> TrajectoryDataset.from_episodes(episodes, [np.zeros((3, 1)), np.zeros((2, 1))]).episode_starts.tolist()
        [0, 3]
        """
        lengths = [len(obs) for obs in observations]
        starts = np.cumsum([0, *lengths[:-1]]).astype(np.int64)
        return cls.with_declarations(
            np.concatenate(list(observations)), np.concatenate(list(actions)), starts, declarations
        )

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
        n_obs = integer(n_obs, "n_obs", low=1, owner="PlanWindows")
        horizon = integer(horizon, "horizon", low=1, owner="PlanWindows")
        action_start = integer(action_start, "action_start", low=1 - n_obs, owner="PlanWindows")
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
        integer(batch_size, "batch_size", low=1, owner="PlanWindows.batches")
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
    header = {"format": FORMAT, **dataset.declarations()}
    try:
        text = json.dumps(header)
    except (TypeError, ValueError) as err:
        raise TypeError(f"dataset.meta must be JSON-serializable ({err})") from None
    arrays = {
        "header": np.array(text),
        "observations": dataset.observations,
        "actions": dataset.actions,
        "episode_starts": dataset.episode_starts,
    }
    return atomic_write_npz(out, arrays)


def load_trajectories(path: str | os.PathLike[str]) -> TrajectoryDataset:
    """Read a file of :func:`save_trajectories` (:func:`steer_envs.data.datasets.load_dataset` also reads random walks).

    :class:`~steer_envs.io.DatasetError` (a ``ValueError``) naming the file
    when it is missing, not an ``.npz`` of plain arrays, of another format, or
    holds arrays of the wrong dtype, shape or with non-finite values.
    """
    src = Path(path)
    if not src.is_file():
        raise DatasetError(f"no dataset file at {str(src)!r}")
    return trajectories_from_arrays(src, read_npz(src))


def trajectories_from_arrays(src: Path, arrays: Mapping[str, np.ndarray]) -> TrajectoryDataset:
    """A :class:`TrajectoryDataset` from the arrays of the file ``src`` (checked; ``DatasetError`` naming it)."""
    if "header" not in arrays:
        raise DatasetError(f"{src} is not a trajectory dataset (no header; expected {FORMAT!r})")
    header = npz_json(src, arrays, "header")
    if header.get("format") != FORMAT:
        raise DatasetError(f"{src} has format {header.get('format')!r}, expected {FORMAT!r}")
    require_arrays(src, arrays, {"observations": ("iuf", 2), "actions": ("iuf", 2), "episode_starts": ("iu", 1)})
    meta = header.get("meta") or {}
    if not isinstance(meta, dict):
        raise DatasetError(f"{src}: the header's meta must be a JSON object, got {type(meta).__name__}")
    try:
        return TrajectoryDataset.with_declarations(
            arrays["observations"], arrays["actions"], arrays["episode_starts"], header
        )
    except (TypeError, ValueError) as err:
        raise DatasetError(f"{src}: {err}") from None
