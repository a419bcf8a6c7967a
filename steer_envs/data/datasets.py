"""Read any trajectory dataset a policy trains on, whatever wrote it.

:func:`load_dataset` takes a file of
:func:`~steer_envs.data.trajectories.save_trajectories`, a Maze2D random
walk of :func:`~steer_envs.data.maze_random_walk.save_random_walk` (converted
with its declarations), or the datasets other libraries write, named with a
prefix: ``lerobot:DIR`` (a LeRobotDataset folder,
:mod:`~steer_envs.data.lerobot_dataset`), ``robomimic:FILE`` (a robomimic
HDF5 file, :mod:`~steer_envs.data.robomimic_hdf5`) or ``minari:ID`` (a local
Minari dataset, :mod:`~steer_envs.data.minari_trajectories`). The training
entry point reads its ``--dataset`` through it. It sits above every format so
that none of their modules needs another.

>>> import tempfile, numpy as np
>>> from steer_envs.data.trajectories import TrajectoryDataset, save_trajectories
>>> ds = TrajectoryDataset(np.zeros((4, 2)), np.zeros((4, 2)), np.array([0]))
>>> with tempfile.TemporaryDirectory() as tmp:
...     load_dataset(save_trajectories(ds, f"{tmp}/d.npz")).observations.shape
(4, 2)
"""

from __future__ import annotations

import os
from pathlib import Path

from steer_envs.data.lerobot_dataset import from_lerobot
from steer_envs.data.maze_random_walk import random_walk_from_arrays
from steer_envs.data.minari_trajectories import from_minari
from steer_envs.data.robomimic_hdf5 import from_robomimic
from steer_envs.data.trajectories import FORMAT, TrajectoryDataset, trajectories_from_arrays
from steer_envs.io import DatasetError, read_npz

__all__ = ["DATASET_KINDS", "canonical_dataset", "load_dataset"]

#: the prefixes of datasets other libraries write: ``KIND:WHERE``
DATASET_KINDS = ("lerobot", "robomimic", "minari")


def _split(spec: str | os.PathLike[str]) -> tuple[str | None, str]:
    text = os.fspath(spec)
    kind, sep, rest = text.partition(":")
    if sep and kind in DATASET_KINDS and not Path(text).exists():
        if not rest:
            raise DatasetError(f"dataset {text!r}: say where after '{kind}:' ({kind}:DIR, FILE or ID)")
        return kind, rest
    return None, text


def canonical_dataset(spec: str | os.PathLike[str]) -> str:
    """``spec`` with its path made absolute (a Minari id stays as it is), as a run records it.

    >>> canonical_dataset("minari:steer/maze-v0")
    'minari:steer/maze-v0'
    """
    kind, where = _split(spec)
    if kind == "minari":
        return f"minari:{where}"
    resolved = str(Path(where).expanduser().resolve())
    return resolved if kind is None else f"{kind}:{resolved}"


def load_dataset(path: str | os.PathLike[str]) -> TrajectoryDataset:
    """The trajectories in ``path``: a :func:`save_trajectories` file, a Maze2D random walk, or ``KIND:WHERE``.

    :class:`~steer_envs.io.DatasetError` (a ``ValueError``) naming the file
    when it is missing, not an ``.npz`` of plain arrays, of neither format,
    or holds arrays of the wrong dtype, shape or with non-finite values.
    ``lerobot:``, ``robomimic:`` and ``minari:`` need their library
    (a :class:`~steer_envs.core.extras.MissingExtraError` names the extra).
    """
    kind, where = _split(path)
    if kind == "lerobot":
        return from_lerobot(where)
    if kind == "robomimic":
        return from_robomimic(where)
    if kind == "minari":
        return from_minari(where)
    src = Path(where)
    if not src.is_file():
        raise DatasetError(f"no dataset file at {str(src)!r}")
    arrays = read_npz(src)
    if "header" in arrays:
        return trajectories_from_arrays(src, arrays)
    if "meta" in arrays:
        return random_walk_from_arrays(src, arrays).to_trajectories()
    raise DatasetError(f"{src} is not a trajectory dataset (no header; expected {FORMAT!r} or a maze2d random walk)")
