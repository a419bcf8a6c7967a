"""Kitchen skill plans: one door or bowl skill as one fixed-length plan of waypoints (ITPS §2.3).

The kitchen Diffusion Policy plans a *whole skill* at a time from the scene at
the skill's start, as the block-stacking one does
(:mod:`steer_envs.data.blockstack_plans`). A plan is ``(PLAN_HORIZON, 5)``:
waypoint ``k`` is the state after ``PLAN_STRIDE * (k + 1)`` control steps:
the end-effector position (world frame, m), the wrist yaw (rad) and the
gripper command in force then (-1 open, +1 closed). A skill shorter than
``PLAN_STRIDE * PLAN_HORIZON`` steps is padded with its last waypoint (the arm
waits there); a longer one is not made into a plan (:func:`skill_plan` returns ``None``).

Yaw convention (:func:`plan_yaw`): the expert's wrist yaw
(:func:`~steer_envs.control.kitchen.eef_yaw`: the
fingers' opening axis about the vertical, 0 along world y), unwrapped along
the skill so it is continuous (a half turn of the wrist shows as one), then
shifted by the multiple of pi that puts the yaw at the skill's first gripper
switch (the grasp or the release, where the yaw matters) into [-pi/2, pi/2).
The fingers are symmetric, so the shift changes no grip; it makes plans of the
same skill alike whichever of the two equivalent wrist yaws the arm started
at. The tracker (:func:`~steer_envs.control.kitchen.execute_kitchen_plan`)
undoes the shift against the wrist's yaw at the start.

:func:`to_plan_dataset` turns skill records into a
:class:`~steer_envs.data.trajectories.TrajectoryDataset` with one
``PLAN_HORIZON``-step episode per skill, so ``PlanWindows`` with ``n_obs=1``
and ``horizon=PLAN_HORIZON`` yields exactly one window per skill: the env's
17-D observation at the skill's start and its plan. The bench's shard module
builds that file from the ``itps-kitchen-data`` shards::

    python -m steer_envs.data.kitchen_shards --cache-dir DIR --episodes 120 --out plans.npz
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import partial
from typing import Any

import numpy as np

from steer_envs.control.kitchen import PLAN_DIM, PLAN_STRIDE  # the tracker's layout
from steer_envs.core.validation import boolean, real_array
from steer_envs.data.kitchen_skills import SkillRecord
from steer_envs.data.skill_plans import Plan, plan_dataset, plannable_skills, sample_plan
from steer_envs.data.trajectories import TrajectoryDataset

__all__ = ["PLAN_DIM", "PLAN_HORIZON", "PLAN_STRIDE", "YAW_CONVENTION", "plan_yaw", "skill_plan", "to_plan_dataset"]

#: waypoints per plan: ``PLAN_STRIDE * PLAN_HORIZON`` control steps hold the expert's longest skill with margin.
PLAN_HORIZON = 32
#: the yaw convention, as stored in a plan data set's meta.
YAW_CONVENTION = "eef_yaw unwrapped, shifted by k*pi into [-pi/2, pi/2) at the first gripper switch"


def plan_yaw(yaw: Any, gripper: Any) -> np.ndarray:
    """The plan yaw of a skill's per-step wrist yaws and gripper commands (see the module docstring).

    ``yaw``: ``(T,)`` rad (any branch); ``gripper``: ``(T,)`` commands. Without a
    gripper switch the last step anchors the shift.
    """
    owner = "plan_yaw"
    y = real_array(yaw, "yaw", ndim=1, owner=owner)
    g = real_array(gripper, "gripper", shape=(len(y),), owner=owner)
    if len(y) == 0:
        raise ValueError(f"{owner}: `yaw` must not be empty")
    y = np.unwrap(y)
    closed = g > 0
    switches = np.flatnonzero(closed != closed[0])
    anchor = int(switches[0]) if switches.size else len(y) - 1
    return y - np.pi * np.floor((y[anchor] + np.pi / 2) / np.pi)


def skill_plan(record: SkillRecord, *, stride: int = PLAN_STRIDE, horizon: int = PLAN_HORIZON) -> Plan | None:
    """``(obs, plan)`` of one skill: observations ``(horizon, 17)``, waypoints ``[x, y, z, yaw, gripper]``.

    See :func:`~steer_envs.data.skill_plans.sample_plan` and, for the yaw,
    :func:`plan_yaw`; ``None`` when the skill is empty or too long.
    """

    def waypoints(ends: np.ndarray) -> np.ndarray:
        yaw = plan_yaw(record.yaw, record.gripper)
        return np.concatenate([record.eef[ends], yaw[ends, None], record.gripper[ends, None]], axis=1)

    return sample_plan(record, SkillRecord, stride, horizon, waypoints)


def to_plan_dataset(
    records: Sequence[SkillRecord],
    *,
    stride: int = PLAN_STRIDE,
    horizon: int = PLAN_HORIZON,
    successful_only: bool = True,
    meta: Mapping[str, Any] | None = None,
) -> TrajectoryDataset:
    """One ``horizon``-step episode per skill (see the module docstring); failed skills dropped by default.

    ``successful_only`` drops skills that failed or reported a violation. The
    dataset's meta records the plan layout (``plan_stride``, ``plan_horizon``,
    ``yaw_convention``), per plan its skill name (``skills``), task (``skill_tasks``) and episode seed, and how
    many skills were dropped as too long.
    """
    owner = "to_plan_dataset"
    successful_only = boolean(successful_only, "successful_only", owner=owner)
    plan = partial(skill_plan, stride=stride, horizon=horizon)
    kept, too_long = plannable_skills(records, SkillRecord, plan, successful_only=successful_only, owner=owner)
    info = {
        **dict(meta or {}),
        "source": "kitchen_plans",
        "action": "eef_pos+yaw+gripper",
        "plan_stride": int(stride),
        "plan_horizon": int(horizon),
        "yaw_convention": YAW_CONVENTION,
        "skills": [r.name for r, _ in kept],
        "skill_tasks": [r.task for r, _ in kept],
        "episode_seeds": [r.seed for r, _ in kept],
        "dropped_too_long": int(too_long),
    }
    return plan_dataset([obs for _, (obs, _) in kept], [plan for _, (_, plan) in kept], horizon, info)
