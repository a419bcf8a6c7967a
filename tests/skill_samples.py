"""Synthetic BlockStack and Kitchen skill records (no simulator) for the skill-plan and skill-file tests.

Both records descend (:func:`blockstack_record`, :func:`kitchen_record`);
:func:`check_descent_plan` checks the plan a domain's ``skill_plan`` makes of one.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.data import blockstack_skills, kitchen_skills


def _descent(steps: int, obs_dim: int, marker: int, close_at: int) -> dict[str, Any]:
    """The fields both records share: the eef moves down in z by 1 mm a step, the gripper closes at ``close_at``.

    Observation column ``marker`` holds the step's index.
    """
    t = np.arange(steps + 1)
    eef = np.stack([np.zeros(steps + 1), np.zeros(steps + 1), 0.2 - 1e-3 * t], axis=1)
    obs = np.zeros((steps + 1, obs_dim), np.float32)
    obs[:, :3] = eef
    obs[:, marker] = t
    return {
        "violation": False,
        "index": 0,
        "obs": obs,
        "actions": np.zeros((steps, 7), np.float32),
        "eef": eef,
        "gripper": np.where(t >= close_at, 1.0, -1.0).astype(np.float32),
    }


def blockstack_record(
    steps: int, *, success: bool = True, seed: int = 0, close_at: int | None = None
) -> blockstack_skills.SkillRecord:
    """A synthetic pick of cube 1 (the step index in observation column 5); closes at the last step by default."""
    return blockstack_skills.SkillRecord(
        name="pick_1",
        cube=1,
        onto=blockstack_skills.ONTO_NONE,
        target=np.zeros(3),
        success=success,
        seed=seed,
        modes=np.zeros(steps + 1, np.int16),
        **_descent(steps, blockstack_skills.OBS_DIM, 5, steps if close_at is None else close_at),
    )


def kitchen_record(
    steps: int,
    *,
    success: bool = True,
    seed: int = 0,
    close_at: int | None = None,
    yaw0: float = 0.0,
    turn: float = 0.0,
    name: str = "pick_bowl",
    task: str = "sink",
) -> kitchen_skills.SkillRecord:
    """A synthetic skill whose wrist turns by ``turn`` from ``yaw0`` (the step index in observation column 7);
    never closes by default."""
    t = np.arange(steps + 1)
    return kitchen_skills.SkillRecord(
        name=name,
        task=task,
        success=success,
        seed=seed,
        yaw=(yaw0 + turn * t / max(steps, 1) + np.pi) % (2 * np.pi) - np.pi,  # wrapped, as eef_yaw reads it
        modes=np.full(steps + 1, kitchen_skills.MODES.index("closed_table"), np.int16),
        handle=np.array([-0.1, 0.18, 1.03]),
        hinge=np.array([-0.02, 0.54, 1.03]),
        **_descent(steps, kitchen_skills.OBS_DIM, 7, steps + 1 if close_at is None else close_at),
    )


def check_descent_plan(
    made: tuple[np.ndarray, np.ndarray] | None,
    steps: int,
    close_at: int,
    *,
    horizon: int,
    stride: int,
    width: int,
    obs_dim: int,
    marker: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Check ``skill_plan``'s ``(obs, plan)`` of a descending record of ``steps`` steps; return them.

    Waypoint ``k`` is the state at step ``stride * (k + 1)`` (the eef's z, the
    gripper in the plan's last of ``width`` columns), the plan is padded with
    its last waypoint, and observation ``k`` is the state at step ``stride * k``
    (its column ``marker`` holds the step).
    """
    assert made is not None
    obs, plan = made
    assert plan.shape == (horizon, width) and obs.shape == (horizon, obs_dim)
    ends = np.minimum(stride * (np.arange(horizon) + 1), steps)
    assert np.allclose(plan[:, 2], 0.2 - 1e-3 * ends)
    assert np.array_equal(plan[:, -1], np.where(ends >= close_at, 1.0, -1.0))
    assert obs[0, marker] == 0 and obs[1, marker] == stride  # the first observation is the skill's start
    assert np.all(plan[ends == steps] == plan[-1])  # padding repeats the last waypoint
    return obs, plan
