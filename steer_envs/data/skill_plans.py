"""What BlockStack and Kitchen skill plans share: which steps a fixed-length plan samples, which skills become plans.

A skill plan is a whole skill as ``horizon`` waypoints, waypoint ``k`` the
state after ``stride * (k + 1)`` control steps (a shorter skill padded with
its last state). :func:`sample_plan` samples those states of a record (and the observations
at the waypoints' start steps);
:func:`plannable_skills` picks the records a plan data set keeps and
:func:`plan_dataset` stacks their plans into one ``horizon``-step episode each.
The domains (:mod:`~steer_envs.data.blockstack_plans`,
:mod:`~steer_envs.data.kitchen_plans`) choose what a waypoint holds.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from steer_envs.core.validation import integer
from steer_envs.data.trajectories import TrajectoryDataset

__all__ = ["Plan", "plan_dataset", "plannable_skills", "sample_plan"]

#: a plan made of one record: the observations at the waypoints' start steps and the waypoints
Plan = tuple[np.ndarray, np.ndarray]


def sample_plan(
    record: Any, kind: type[Any], stride: int, horizon: int, waypoints: Callable[[np.ndarray], np.ndarray]
) -> Plan | None:
    """``(obs, plan)`` of one skill: its observations ``(horizon, obs_dim)`` at the waypoints' start steps and
    its plan ``waypoints(ends)`` (float32 both), ``ends`` the state rows of the ``horizon`` waypoints.

    ``obs[0]`` is the skill's first observation (what a plan is conditioned on).
    ``record``: a ``kind`` skill record (``TypeError`` otherwise, naming ``skill_plan``).
    ``None`` when the skill is empty or longer than ``stride * horizon`` steps.

    >>> class Record:  # a 5-step skill whose observation at each state is the state's index
    ...     obs = np.arange(6.0)[:, None]
    ...     def __len__(self) -> int:
    ...         return 5
    >>> obs, plan = sample_plan(Record(), Record, stride=2, horizon=4, waypoints=lambda ends: ends[:, None])
    >>> obs[:, 0].tolist(), plan[:, 0].tolist()
    ([0.0, 2.0, 4.0, 5.0], [2.0, 4.0, 5.0, 5.0])
    """
    if not isinstance(record, kind):
        raise TypeError(f"skill_plan: `record` must be a SkillRecord, got {type(record).__name__}")
    stride = integer(stride, "stride", low=1, high=1000, owner="skill_plan")
    horizon = integer(horizon, "horizon", low=1, high=10_000, owner="skill_plan")
    steps = len(record)
    if steps == 0 or steps > stride * horizon:
        return None
    ends = np.minimum(stride * np.arange(1, horizon + 1), steps)
    obs = record.obs[np.minimum(stride * np.arange(horizon), steps)]
    return obs.astype(np.float32), waypoints(ends).astype(np.float32)


def plannable_skills(
    records: Sequence[Any], kind: type[Any], make: Callable[[Any], Plan | None], *, successful_only: bool, owner: str
) -> tuple[list[tuple[Any, Plan]], int]:
    """The records of ``kind`` that become plans (``make(record)``), with their plans; and how many were too long.

    ``successful_only`` drops skills that failed or reported a violation; a
    skill ``make`` turns down (``None``) is dropped and counted unless empty.
    ``TypeError`` / ``ValueError`` naming ``owner`` for records that are not
    ``kind`` or when no skill is kept.
    """
    if isinstance(records, (str, bytes)) or not isinstance(records, Sequence):
        raise TypeError(f"{owner}: `records` must be a sequence of SkillRecord, got {type(records).__name__}")
    kept: list[tuple[Any, Plan]] = []
    too_long = 0
    for i, r in enumerate(records):
        if not isinstance(r, kind):
            raise TypeError(f"{owner}: `records[{i}]` must be a SkillRecord, got {type(r).__name__}")
        if successful_only and not (r.success and not r.violation):
            continue
        made = make(r)
        if made is None:
            too_long += len(r) > 0
            continue
        kept.append((r, made))
    if not kept:
        raise ValueError(f"{owner}: `records` holds no skill to keep (of {len(records)})")
    return kept, too_long


def plan_dataset(
    obs: Sequence[np.ndarray], plans: Sequence[np.ndarray], horizon: int, meta: Mapping[str, Any]
) -> TrajectoryDataset:
    """One ``horizon``-step episode per plan: its observations and waypoints, with ``meta``."""
    starts = np.arange(len(plans), dtype=np.int64) * int(horizon)
    return TrajectoryDataset(np.concatenate(obs), np.concatenate(plans), starts, meta=dict(meta))
