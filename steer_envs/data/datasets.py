"""Read any trajectory file a policy trains on, whatever wrote it.

:func:`load_dataset` takes a file of
:func:`~steer_envs.data.trajectories.save_trajectories` or a Maze2D random
walk of :func:`~steer_envs.data.maze_random_walk.save_random_walk` (converted
with its declarations); the training entry point reads its ``--dataset``
through it. It sits above both formats so that neither module needs the other.

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

from steer_envs.data.maze_random_walk import random_walk_from_arrays
from steer_envs.data.trajectories import FORMAT, TrajectoryDataset, trajectories_from_arrays
from steer_envs.io import DatasetError, read_npz

__all__ = ["load_dataset"]


def load_dataset(path: str | os.PathLike[str]) -> TrajectoryDataset:
    """The trajectories in ``path``: a :func:`save_trajectories` file or a Maze2D random walk.

    :class:`~steer_envs.io.DatasetError` (a ``ValueError``) naming the file
    when it is missing, not an ``.npz`` of plain arrays, of neither format,
    or holds arrays of the wrong dtype, shape or with non-finite values.
    """
    src = Path(path)
    if not src.is_file():
        raise DatasetError(f"no dataset file at {str(src)!r}")
    arrays = read_npz(src)
    if "header" in arrays:
        return trajectories_from_arrays(src, arrays)
    if "meta" in arrays:
        return random_walk_from_arrays(src, arrays).to_trajectories()
    raise DatasetError(f"{src} is not a trajectory dataset (no header; expected {FORMAT!r} or a maze2d random walk)")
