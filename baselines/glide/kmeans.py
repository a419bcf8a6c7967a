"""Trajectory-segmentation baseline for GLiDE: k-means++ on demonstration states.

Thesis §4.3 (Fig. 4.4e, Table 4.2 "Traj. Seg. Baseline"): cluster the states
seen in the demonstrations into ``K`` groups with k-means++ and label any state
by its nearest cluster centre. Clusters carry no mode index of their own, so
they are ordered by *when* the demonstrations visit them (mean normalised
time of their member states): the earliest cluster is mode 0, the latest mode
``K - 1``. The baseline uses only statistical similarity, no success labels.

* :class:`KMeansSegmentation` clusters raw states (PolygonNav's positions);
* :class:`KMeansModes` is the robosuite arms' version (thesis Table 4.2
  "kmeans"): the LLM's selected features of the demos, standardised (the
  features mix metres and quaternion components), then clustered.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from sklearn.cluster import KMeans

from steer_envs.baselines.glide.arm_plan import num_modes, selected_columns
from steer_envs.core.validation import integer, real_array
from steer_envs.data.robosuite_replays import ArmTrajectory


class KMeansSegmentation:
    """k-means++ clusters of demonstration states, numbered in temporal order.

    Args:
        num_modes: number of clusters ``K`` (the plan's number of modes).
        seed: seeds k-means++.
        n_init: k-means restarts (best inertia kept).

    >>> import numpy as np
    >>> demo = np.stack([np.linspace(0, 9, 30), np.zeros(30)], axis=1)  # moves right over time
    >>> km = KMeansSegmentation(3, n_init=1).fit([demo])
    >>> km.predict(np.array([[0.0, 0.0], [4.5, 0.0], [9.0, 0.0]])).tolist()
    [0, 1, 2]
    """

    def __init__(self, num_modes: int, *, seed: int = 0, n_init: int = 10) -> None:
        owner = "KMeansSegmentation"
        self.num_modes = integer(num_modes, "num_modes", low=2, owner=owner)
        self.seed = integer(seed, "seed", low=0, high=2**32 - 1, owner=owner)
        self.n_init = integer(n_init, "n_init", low=1, high=10_000, owner=owner)
        self.centers: np.ndarray | None = None  # (K, d), row m is mode m's centre

    def fit(self, demonstrations: Sequence[np.ndarray]) -> KMeansSegmentation:
        """Cluster the states of ``demonstrations`` (each ``(T_i, d)``) and order the clusters in time."""
        if len(demonstrations) == 0:
            raise ValueError("demonstrations must not be empty")
        states, phase = [], []
        for i, demo in enumerate(demonstrations):
            arr = real_array(demo, f"demonstrations[{i}]", owner="KMeansSegmentation")
            if arr.ndim != 2 or len(arr) < 1:
                raise ValueError(f"demonstrations[{i}] must have shape (T >= 1, d), got {arr.shape}")
            states.append(arr)
            phase.append(np.linspace(0.0, 1.0, len(arr)))
        x = np.concatenate(states)
        if len(x) < self.num_modes:
            raise ValueError(f"need at least num_modes={self.num_modes} states, got {len(x)}")
        t = np.concatenate(phase)
        km = KMeans(n_clusters=self.num_modes, init="k-means++", n_init=self.n_init, random_state=self.seed)
        labels = km.fit_predict(x)
        mean_phase = np.array([t[labels == c].mean() if np.any(labels == c) else np.inf for c in range(self.num_modes)])
        self.centers = km.cluster_centers_[np.argsort(mean_phase)]
        return self

    def predict(self, states: np.ndarray) -> np.ndarray:
        """Mode of each state ``(N, d) -> (N,)``: the temporal rank of its nearest centre."""
        if self.centers is None:
            raise RuntimeError("KMeansSegmentation.predict called before fit")
        x = real_array(states, "states", owner="KMeansSegmentation")
        if x.ndim != 2 or x.shape[1] != self.centers.shape[1]:
            raise ValueError(f"states must have shape (N, {self.centers.shape[1]}), got {x.shape}")
        d2 = ((x[:, None, :] - self.centers[None, :, :]) ** 2).sum(-1)
        return d2.argmin(axis=1).astype(np.int64)


class KMeansModes:
    """The k-means baseline on an arm task: standardised selected features, clusters in temporal order.

    A mode predictor (``predict(features[:, selected_columns(task)])``) for the
    robosuite tasks: the columns are the LLM's selected features
    (:func:`~steer_envs.baselines.glide.arm_plan.selected_columns`), each
    standardised with the demos' mean and std, and clustered into the task's
    ground-truth number of modes by :class:`KMeansSegmentation`.

    Args:
        task: ``"lift"``, ``"can"`` or ``"square"``.
        demos: the successful demonstrations
            (:class:`~steer_envs.data.robosuite_replays.ArmTrajectory`).
        seed: seeds k-means++.
    """

    def __init__(self, task: str, demos: Sequence[ArmTrajectory], *, seed: int = 0) -> None:
        k = num_modes(task)
        self.task = task
        cols = selected_columns(task, "kmeans")
        x = [np.asarray(d.features[:, cols], dtype=np.float64) for d in demos]
        if not x:
            raise ValueError("KMeansModes: demos must not be empty")
        stacked = np.concatenate(x)
        self.mean, self.std = stacked.mean(0), stacked.std(0) + 1e-6
        self.kmeans = KMeansSegmentation(k, seed=seed).fit([(s - self.mean) / self.std for s in x])

    def predict(self, states: np.ndarray) -> np.ndarray:
        """Mode of each row of selected features ``(N, d) -> (N,)``."""
        return self.kmeans.predict((np.asarray(states, dtype=np.float64) - self.mean) / self.std)


__all__ = ["KMeansModes", "KMeansSegmentation"]
