"""steer-envs trajectories <-> a robomimic HDF5 dataset (the layout robomimic's ``SequenceDataset`` reads).

The file follows robomimic's documented dataset structure
(https://robomimic.github.io/docs/datasets/overview.html), written with ``h5py``::

    data                 attrs: total (frames), env_args (JSON)
    data/demo_<i>        attrs: num_samples; one demo per steer-envs episode
        obs/<obs_key>    (N, obs_dim) observations
        next_obs/<obs_key>  (N, obs_dim) the next observation (the last one repeated at the end)
        actions          (N, action_dim)
        rewards, dones   (N,) zeros; dones[-1] = 1

:func:`to_robomimic` writes it atomically (a killed write leaves no file);
:func:`from_robomimic` reads any robomimic file of low-dimensional
observations back (``obs_keys`` concatenated, demos in index order). The
declarations robomimic has no field for (``obs_indices``,
``action_obs_indices``, ``meta``) ride in ``env_args["steer_envs"]``. Needs
h5py (``pip install "steer-envs[robomimic]"``).

>>> import tempfile, numpy as np
>>> from steer_envs.data.trajectories import TrajectoryDataset
>>> ds = TrajectoryDataset(np.arange(12.0).reshape(6, 2), np.ones((6, 2)), [0, 4])
>>> with tempfile.TemporaryDirectory() as tmp:
...     back = from_robomimic(to_robomimic(ds, f"{tmp}/demo.hdf5"))
>>> back.episode_starts.tolist(), bool(np.array_equal(back.observations, ds.observations))
([0, 4], True)
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.core.extras import require
from steer_envs.data.trajectories import TrajectoryDataset
from steer_envs.io import DatasetError, atomic_open

__all__ = ["from_robomimic", "to_robomimic"]

_DEMO = re.compile(r"demo_(\d+)")


def to_robomimic(
    dataset: TrajectoryDataset,
    path: str | os.PathLike[str],
    *,
    obs_key: str = "state",
    env_name: str = "steer_envs",
) -> Path:
    """Write ``dataset`` as the robomimic HDF5 file ``path`` (one demo per episode); returns ``path``.

    ``obs_key`` names the observation under ``obs/``; ``env_name`` goes to
    ``env_args`` (robomimic's record of the env the data came from).
    """
    if not isinstance(dataset, TrajectoryDataset):
        raise TypeError(f"to_robomimic: `dataset` must be a TrajectoryDataset, got {type(dataset).__name__}")
    if not isinstance(obs_key, str) or not obs_key or "/" in obs_key:
        raise ValueError(f"to_robomimic: `obs_key` must be a name without '/', got {obs_key!r}")
    h5py = require("h5py", "robomimic", "to_robomimic")
    env_args = {
        "env_name": env_name,
        "type": 4,  # robomimic's EnvType.GYM_TYPE: a Gym(nasium) env
        "env_kwargs": {},
        "steer_envs": dataset.declarations(),
    }
    target = Path(path)
    with atomic_open(target, "wb") as fh, h5py.File(fh, "w") as f:
        data = f.create_group("data")
        data.attrs["total"] = len(dataset)
        data.attrs["env_args"] = json.dumps(env_args)
        for i, episode in enumerate(dataset.episode_slices()):
            obs = dataset.observations[episode]
            demo = data.create_group(f"demo_{i}")
            demo.attrs["num_samples"] = len(obs)
            demo.create_dataset(f"obs/{obs_key}", data=obs)
            demo.create_dataset(f"next_obs/{obs_key}", data=np.concatenate([obs[1:], obs[-1:]]))
            demo.create_dataset("actions", data=dataset.actions[episode])
            demo.create_dataset("rewards", data=np.zeros(len(obs)))
            dones = np.zeros(len(obs), dtype=np.int64)
            dones[-1] = 1
            demo.create_dataset("dones", data=dones)
    return target


def _demo_names(data: Any, src: Path) -> list[str]:
    names = [name for name in data if _DEMO.fullmatch(name)]
    if not names:
        raise DatasetError(f"{src}: no data/demo_<i> groups (not a robomimic dataset)")
    return sorted(names, key=lambda name: int(name[5:]))


def _read_demo(demo: Any, keys: Sequence[str], src: Path) -> tuple[np.ndarray, np.ndarray]:
    missing = [k for k in keys if f"obs/{k}" not in demo] + (["actions"] if "actions" not in demo else [])
    if missing:
        raise DatasetError(f"{src}: {demo.name} has no {missing}")
    steps = len(demo["actions"])
    obs = np.concatenate([np.asarray(demo[f"obs/{k}"], dtype=np.float32).reshape(steps, -1) for k in keys], axis=1)
    return obs, np.asarray(demo["actions"], dtype=np.float32)


def from_robomimic(path: str | os.PathLike[str], *, obs_keys: Sequence[str] | None = None) -> TrajectoryDataset:
    """The trajectories of the robomimic HDF5 file ``path``.

    ``obs_keys`` (default: every key under the first demo's ``obs/``, sorted)
    are concatenated into the observation. A missing file, a file that is not
    HDF5 or not robomimic's layout is a :class:`~steer_envs.io.DatasetError` naming it.
    """
    src = Path(path)
    if not src.is_file():
        raise DatasetError(f"no robomimic dataset file at {str(src)!r}")
    h5py = require("h5py", "robomimic", "from_robomimic")
    try:
        f = h5py.File(src, "r")
    except OSError as exc:
        raise DatasetError(f"{src} is not an HDF5 file ({exc})") from None
    with f:
        if "data" not in f:
            raise DatasetError(f"{src}: no 'data' group (not a robomimic dataset)")
        names = _demo_names(f["data"], src)
        keys = list(obs_keys) if obs_keys is not None else sorted(f["data"][names[0]]["obs"])
        pieces = [_read_demo(f["data"][name], keys, src) for name in names]
        env_args = json.loads(f["data"].attrs.get("env_args", "{}"))
    observations, actions = zip(*pieces, strict=True)
    return TrajectoryDataset.from_episodes(observations, actions, env_args.get("steer_envs"))
