"""steer-envs trajectories <-> a `LeRobotDataset <https://huggingface.co/docs/lerobot>`_, through LeRobot itself.

:func:`to_lerobot` writes a :class:`~steer_envs.data.trajectories.TrajectoryDataset`
with ``LeRobotDataset.create`` / ``add_frame`` / ``save_episode`` /
``finalize`` (one LeRobot episode per steer-envs episode; observations as
``observation.state``, actions as ``action``), so LeRobot's own tools and
policies read it; :func:`from_lerobot` reads any LeRobotDataset of vector
features back with ``LeRobotDataset``. The export is atomic (built next to
its final folder and renamed, :func:`steer_envs.io.atomic_directory`).

LeRobot's Diffusion Policy needs an image or an ``observation.environment_state``
besides the state; a steer-envs dataset has neither, so by default the export
repeats the observation as ``observation.environment_state`` (a
LeRobotDataset exported from steer-envs then trains LeRobot's DP as it is).
The declarations LeRobot has no field for (``obs_indices``,
``action_obs_indices``, ``meta``) go to ``meta/steer_envs.json`` inside the
dataset, so a round trip keeps them. Needs LeRobot (``pip install
"steer-envs[lerobot]"``, in an environment of its own: LeRobot's pins clash
with the ``all`` extra's; ``scripts/test_interop.sh`` builds one).

>>> to_lerobot  # doctest: +ELLIPSIS
<function to_lerobot at ...>
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.core.extras import require
from steer_envs.data.trajectories import TrajectoryDataset
from steer_envs.io import DatasetError, atomic_directory, atomic_write_text

__all__ = ["ENV_STATE", "STATE", "from_lerobot", "to_lerobot"]

#: LeRobot's feature names for the agent's state and the environment's state
STATE = "observation.state"
ENV_STATE = "observation.environment_state"
_SIDE_FILE = "meta/steer_envs.json"


def _fps(dataset: TrajectoryDataset, fps: int | None) -> int:
    if fps is None:
        meta = dataset.meta
        if "fps" in meta:
            fps = int(meta["fps"])
        elif "dt" in meta:  # the time between two samples
            fps = round(1.0 / float(meta["dt"]))
        else:
            raise ValueError("to_lerobot: `fps` is needed (the dataset's meta has neither 'fps' nor 'dt')")
    if isinstance(fps, bool) or not isinstance(fps, (int, np.integer)) or fps < 1:
        raise ValueError(f"to_lerobot: `fps` must be a positive int (frames per second), got {fps!r}")
    return int(fps)


def _features(dataset: TrajectoryDataset, environment_state: bool) -> dict[str, dict[str, Any]]:
    def vector(width: int, prefix: str) -> dict[str, Any]:
        return {"dtype": "float32", "shape": (width,), "names": [f"{prefix}{i}" for i in range(width)]}

    features = {STATE: vector(dataset.obs_dim, "s"), "action": vector(dataset.action_dim, "a")}
    if environment_state:
        features[ENV_STATE] = vector(dataset.obs_dim, "s")
    return features


def to_lerobot(
    dataset: TrajectoryDataset,
    root: str | os.PathLike[str],
    *,
    repo_id: str = "steer_envs/trajectories",
    fps: int | None = None,
    task: str = "steer-envs trajectories",
    environment_state: bool = True,
    overwrite: bool = False,
) -> Path:
    """Write ``dataset`` as a LeRobotDataset in the folder ``root``; returns ``root``.

    ``fps`` defaults to the dataset's ``meta`` (``fps``, or ``1 / dt``, ``dt``
    being the time between two samples); ``task`` is every frame's task string; ``environment_state``
    repeats the observation as ``observation.environment_state`` (what
    LeRobot's DP needs without images). An existing ``root`` is a
    ``FileExistsError`` unless ``overwrite``.
    """
    if not isinstance(dataset, TrajectoryDataset):
        raise TypeError(f"to_lerobot: `dataset` must be a TrajectoryDataset, got {type(dataset).__name__}")
    if not isinstance(task, str) or not task:
        raise ValueError(f"to_lerobot: `task` must be a non-empty string, got {task!r}")
    rate = _fps(dataset, fps)
    lerobot_dataset = require("lerobot.datasets.lerobot_dataset", "lerobot", "to_lerobot")
    target = Path(root)
    with atomic_directory(target, overwrite=overwrite) as tmp:
        folder = tmp / "dataset"  # LeRobotDataset.create makes its own root
        out = lerobot_dataset.LeRobotDataset.create(
            repo_id=repo_id, fps=rate, features=_features(dataset, environment_state), root=folder, use_videos=False
        )
        for episode in dataset.episode_slices():
            for obs, action in zip(dataset.observations[episode], dataset.actions[episode], strict=True):
                frame = {STATE: obs, "action": action, "task": task}
                if environment_state:
                    frame[ENV_STATE] = obs
                out.add_frame(frame)
            out.save_episode()
        out.finalize()
        side = {"repo_id": repo_id, **dataset.declarations()}
        atomic_write_text(folder / _SIDE_FILE, json.dumps(side, indent=1))
        for item in folder.iterdir():
            item.rename(tmp / item.name)
        folder.rmdir()
    return target


def _column(hf_dataset: Any, key: str, root: Path) -> np.ndarray:
    if key not in hf_dataset.column_names:
        raise DatasetError(f"{root}: the LeRobotDataset has no {key!r} feature (features: {hf_dataset.column_names})")
    return np.asarray(hf_dataset.with_format("numpy")[key], dtype=np.float32)


def from_lerobot(
    root: str | os.PathLike[str], *, repo_id: str | None = None, observation: str = STATE
) -> TrajectoryDataset:
    """The trajectories of the LeRobotDataset in ``root`` (read by ``LeRobotDataset``, never from a hub).

    ``observation`` names the feature that becomes the observation (default
    ``observation.state``); ``action`` is the action. Episodes follow
    ``episode_index``. Declarations written by :func:`to_lerobot` come back.
    A folder that is not a LeRobotDataset is a :class:`~steer_envs.io.DatasetError`.
    """
    folder = Path(root)
    if not (folder / "meta" / "info.json").is_file():
        raise DatasetError(f"no LeRobotDataset at {str(folder)!r} (no meta/info.json)")
    side: Mapping[str, Any] = {}
    if (folder / _SIDE_FILE).is_file():
        side = json.loads((folder / _SIDE_FILE).read_text())
    lerobot_dataset = require("lerobot.datasets.lerobot_dataset", "lerobot", "from_lerobot")
    name = repo_id or str(side.get("repo_id") or f"local/{folder.name}")
    data = lerobot_dataset.LeRobotDataset(name, root=folder).hf_dataset
    episodes = np.asarray(data.with_format("numpy")["episode_index"]).reshape(-1)
    order = np.argsort(episodes, kind="stable")
    if np.any(order != np.arange(len(order))):
        raise DatasetError(f"{folder}: frames are not grouped by episode")
    starts = np.flatnonzero(np.r_[True, episodes[1:] != episodes[:-1]]) if len(episodes) else np.zeros(0, int)

    observations, actions = _column(data, observation, folder), _column(data, "action", folder)
    return TrajectoryDataset.with_declarations(observations, actions, starts.astype(np.int64), side)
