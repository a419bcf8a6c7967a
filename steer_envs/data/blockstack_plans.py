"""BlockStack skill plans: one pick-or-place skill as one fixed-length plan of waypoints (ITPS §2.3).

The block-stacking Diffusion Policy plans a *whole skill* at a time from the
scene at the skill's start (the thesis's "one pick-or-place skill per plan").
A plan is ``(PLAN_HORIZON, 4)``: waypoint ``k`` is the end-effector position
(world frame, m) after ``PLAN_STRIDE * (k + 1)`` control steps and the gripper
command in force then (-1 open, +1 closed). A skill shorter than
``PLAN_STRIDE * PLAN_HORIZON`` steps is padded with its last waypoint (the arm
waits there); a longer one is not made into a plan (:func:`skill_plan` returns
``None``; 0.3 % of the random planner's skills).

:func:`to_plan_dataset` turns skill records into a
:class:`~steer_envs.data.trajectories.TrajectoryDataset` with one
``PLAN_HORIZON``-step episode per skill, so ``PlanWindows`` with ``n_obs=1``
and ``horizon=PLAN_HORIZON`` yields exactly one window per skill: the
observation at the skill's start and its plan. The bench's shard module builds
that file from the ``itps-blockstack-data`` shards::

    python -m steer_envs.data.blockstack_shards --cache-dir DIR --episodes 200 --out plans.npz
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import partial
from typing import Any

import numpy as np

from steer_envs.control.blockstack import PLAN_DIM, PLAN_STRIDE  # the tracker's layout, one layer down
from steer_envs.core.validation import boolean, integer, real_scalar
from steer_envs.data.blockstack_skills import SkillRecord
from steer_envs.data.skill_plans import Plan, plan_dataset, plannable_skills, sample_plan
from steer_envs.data.trajectories import TrajectoryDataset
from steer_envs.envs.robosuite.blockstack import NUM_CUBES

__all__ = ["PLAN_DIM", "PLAN_HORIZON", "PLAN_STRIDE", "TABLE_CENTRE", "move_scene", "skill_plan", "to_plan_dataset"]

#: waypoints per plan: ``PLAN_STRIDE * PLAN_HORIZON = 96`` control steps hold 99.7 % of the skills.
PLAN_HORIZON = 32
#: the first observation column of the cube poses (after eef 3 and finger positions 2).
CUBE_START = 5
#: the xy (m, world frame) the rigid augmentation rotates about: BlockStack-v0's table centre.
TABLE_CENTRE = (0.0, 0.0)


def skill_plan(record: SkillRecord, *, stride: int = PLAN_STRIDE, horizon: int = PLAN_HORIZON) -> Plan | None:
    """``(obs, plan)`` of one skill: observations ``(horizon, 33)``, waypoints ``[x, y, z, gripper]``.

    See :func:`~steer_envs.data.skill_plans.sample_plan`; ``None`` when the skill is empty or too long.
    """

    def waypoints(ends: np.ndarray) -> np.ndarray:
        return np.concatenate([record.eef[ends], record.gripper[ends, None]], axis=1)

    return sample_plan(record, SkillRecord, stride, horizon, waypoints)


def _cube_columns(order: np.ndarray) -> np.ndarray:
    """Observation columns listing the cubes in ``order`` (eef and fingers first, then 7 entries a cube)."""
    cubes = [np.arange(CUBE_START + 7 * int(i), CUBE_START + 7 * int(i) + 7) for i in order]
    return np.concatenate([np.arange(CUBE_START), *cubes])


def move_scene(obs: np.ndarray, plan: np.ndarray, angle: float, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``obs`` (rows of 33) and ``plan`` (rows of ``[x, y, z, gripper]``) turned by ``angle`` (rad) about the
    vertical axis through :data:`TABLE_CENTRE`, then shifted by ``offset`` (xy, m).

    Positions (end effector, cubes, waypoints) move; cube orientations turn with
    them; heights, fingers and gripper commands stay. The skill's physics is
    invariant under such a motion of the whole scene (within the arm's reach).
    """
    from scipy.spatial.transform import Rotation

    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[c, -s], [s, c]])
    centre = np.asarray(TABLE_CENTRE)
    shift = np.asarray(offset, dtype=np.float64).reshape(2)

    def move_xy(xy: np.ndarray) -> np.ndarray:
        return (xy - centre) @ turn.T + centre + shift

    obs, plan = obs.astype(np.float64), plan.astype(np.float64)
    obs[:, 0:2] = move_xy(obs[:, 0:2])
    plan[:, 0:2] = move_xy(plan[:, 0:2])
    yaw = Rotation.from_euler("z", angle)
    for i in range(NUM_CUBES):
        pos, quat = CUBE_START + 7 * i, CUBE_START + 7 * i + 3
        obs[:, pos : pos + 2] = move_xy(obs[:, pos : pos + 2])
        obs[:, quat : quat + 4] = (yaw * Rotation.from_quat(obs[:, quat : quat + 4])).as_quat()  # xyzw
    return obs.astype(np.float32), plan.astype(np.float32)


def to_plan_dataset(
    records: Sequence[SkillRecord],
    *,
    stride: int = PLAN_STRIDE,
    horizon: int = PLAN_HORIZON,
    successful_only: bool = True,
    permutations: int = 0,
    shift: float = 0.0,
    yaw: float = 0.0,
    seed: int = 0,
    meta: Mapping[str, Any] | None = None,
) -> TrajectoryDataset:
    """One ``horizon``-step episode per skill (see the module docstring); failed skills dropped by default.

    ``permutations``: extra copies of every skill whose observations list the
    four cubes in another (seeded random) order; the plan is unchanged. The
    cubes are interchangeable, so this teaches the policy that a skill goes
    to *a* cube, not to an observation slot: without it a few thousand skills
    are memorized scene by scene (one plan per scene, no multimodality).
    ``shift`` (m) and ``yaw`` (rad) > 0 also move each copy's whole scene
    rigidly (:func:`move_scene`): a turn drawn uniformly in ``[-yaw, yaw]``
    and an xy shift in ``[-shift, shift]``, so the policy sees cube layouts
    beyond the recorded ones and learns to aim at where a cube *is*.
    The dataset's meta records the plan layout (``plan_stride``, ``plan_horizon``),
    the augmentation, the skill names and how many skills were dropped as too long.
    """
    owner = "to_plan_dataset"
    successful_only = boolean(successful_only, "successful_only", owner=owner)
    permutations = integer(permutations, "permutations", low=0, high=1000, owner=owner)
    shift = real_scalar(shift, "shift", low=0.0, high=0.5, owner=owner)
    yaw = real_scalar(yaw, "yaw", low=0.0, high=float(np.pi), owner=owner)
    rng = np.random.default_rng(integer(seed, "seed", low=0, owner=owner))
    plan = partial(skill_plan, stride=stride, horizon=horizon)
    kept, too_long = plannable_skills(records, SkillRecord, plan, successful_only=successful_only, owner=owner)
    obs, plans, names, seeds = [], [], [], []
    for r, made in kept:
        for copy in range(permutations + 1):
            moved = made if copy == 0 else _augmented(made, rng, shift, yaw)
            obs.append(moved[0])
            plans.append(moved[1])
            names.append(r.name)
            seeds.append(r.seed)
    info = {
        **dict(meta or {}),
        "source": "blockstack_plans",
        "action": "eef_pos+gripper",
        "plan_stride": int(stride),
        "plan_horizon": int(horizon),
        "cube_permutations": int(permutations),
        "augment_shift": float(shift),
        "augment_yaw": float(yaw),
        "augment_seed": int(seed),
        "skills": names,
        "episode_seeds": seeds,
        "dropped_too_long": int(too_long),
    }
    return plan_dataset(obs, plans, horizon, info)


def _augmented(made: Plan, rng: np.random.Generator, shift: float, yaw: float) -> Plan:
    """A copy of a plan whose scene moved rigidly (when ``shift`` or ``yaw``) and lists the cubes in a random order."""
    if shift or yaw:
        made = move_scene(*made, rng.uniform(-yaw, yaw), rng.uniform(-shift, shift, size=2))
    return made[0][:, _cube_columns(rng.permutation(NUM_CUBES))], made[1]
