"""steer-envs trajectories <-> `Minari <https://minari.farama.org>`_ datasets, through Minari itself.

:func:`trajectories_to_minari` stores a
:class:`~steer_envs.data.trajectories.TrajectoryDataset` as a local Minari
dataset (one Minari episode per steer-envs episode, written atomically by
:func:`~steer_envs.data.minari_export.store_minari_dataset`); :func:`from_minari`
reads any Minari dataset with vector observations and actions back, from its
id (``minari.load_dataset``) or a loaded ``MinariDataset``. A Minari episode
holds one observation more than actions (the state after the last step):
:func:`trajectories_to_minari` stores the last observation again there and
:func:`from_minari` drops it. The declarations Minari has no field for
(``obs_indices``, ``action_obs_indices``, ``meta``) ride in the dataset's
description as JSON after ``steer_envs:``. Needs the ``minari`` extra.

>>> from_minari  # doctest: +ELLIPSIS
<function from_minari at ...>
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from steer_envs.data.minari_export import check_minari_id, require_minari, store_minari_dataset
from steer_envs.data.trajectories import TrajectoryDataset
from steer_envs.io import DatasetError

__all__ = ["from_minari", "trajectories_to_minari"]

_MARK = "steer_envs:"


def trajectories_to_minari(
    dataset: TrajectoryDataset,
    dataset_id: str,
    *,
    env_id: str,
    env_kwargs: Mapping[str, Any] | None = None,
    root: str | os.PathLike[str] | None = None,
    description: str = "steer-envs trajectories",
) -> Any:
    """Store ``dataset`` as the local Minari dataset ``dataset_id``; returns it (a ``MinariDataset``).

    ``gymnasium.make(env_id, **env_kwargs)`` is the env Minari records (its
    spaces must hold the observations and actions). Rewards are 0; an
    episode's last step is truncated, not terminated (the data says nothing
    of success). ``root`` as in :func:`~steer_envs.data.minari_export.store_minari_dataset`.
    """
    if not isinstance(dataset, TrajectoryDataset):
        raise TypeError(f"trajectories_to_minari: `dataset` must be a TrajectoryDataset, got {type(dataset).__name__}")
    dataset_id = check_minari_id(dataset_id)
    episodes = []
    for episode in dataset.episode_slices():
        obs = dataset.observations[episode]
        last = np.arange(len(obs)) == len(obs) - 1
        episodes.append(
            {
                "observations": list(np.concatenate([obs, obs[-1:]])),
                "actions": list(dataset.actions[episode]),
                "rewards": [0.0] * len(obs),
                "terminations": [False] * len(obs),
                "truncations": list(last),
                "infos": {},
            }
        )
    side = dataset.declarations()
    return store_minari_dataset(
        dataset_id,
        episodes,
        env_id=env_id,
        env_kwargs=dict(env_kwargs or {}),
        root=root,
        algorithm_name="steer-envs TrajectoryDataset export",
        author="steer-envs (steer_envs.data.minari_trajectories)",
        description=f"{description}\n{_MARK}{json.dumps(side)}",
    )


def _side(description: Any) -> dict[str, Any]:
    text = str(description or "")
    at = text.rfind(_MARK)
    if at < 0:
        return {}
    try:
        value = json.loads(text[at + len(_MARK) :])
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def from_minari(dataset: Any, *, root: str | os.PathLike[str] | None = None) -> TrajectoryDataset:
    """The trajectories of a Minari dataset: its id (loaded from ``root``, default Minari's path) or the dataset.

    Observations and actions must be vector (Box) arrays; each episode's final
    observation (the state after its last action) is dropped.
    """
    minari = require_minari("from_minari")
    if isinstance(dataset, str):
        dataset_id = check_minari_id(dataset)
        if root is None:
            dataset = minari.load_dataset(dataset_id)
        else:
            from minari.dataset.minari_storage import MinariStorage

            folder = os.path.join(os.fspath(root), *dataset_id.split("/"), "data")
            if not os.path.isdir(folder):
                raise DatasetError(f"no Minari dataset {dataset_id!r} under {os.fspath(root)!r}")
            dataset = minari.MinariDataset(MinariStorage.read(folder))
    observations, actions = [], []
    for episode in dataset.iterate_episodes():
        obs, act = np.asarray(episode.observations), np.asarray(episode.actions)
        if obs.dtype == object or obs.ndim != 2 or act.ndim != 2:
            raise DatasetError(f"from_minari: episode {episode.id} is not vector observations and actions")
        observations.append(obs[: len(act)])
        actions.append(act)
    if not actions:
        raise DatasetError("from_minari: the dataset has no episodes")
    side = _side(getattr(dataset.storage, "metadata", {}).get("description"))
    return TrajectoryDataset.from_episodes(observations, actions, side)
