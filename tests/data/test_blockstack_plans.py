"""BlockStack skill plans: the waypoint layout, padding, dropped skills, one training window per skill, the CLI."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from steer_envs.data.blockstack_plans import PLAN_HORIZON, PLAN_STRIDE, skill_plan, to_plan_dataset
from steer_envs.data.blockstack_skills import OBS_DIM, ONTO_NONE, SkillRecord
from steer_envs.data.trajectories import PlanWindows, load_trajectories


def record(steps: int, *, success: bool = True, seed: int = 0, close_at: int | None = None) -> SkillRecord:
    """A synthetic pick: the eef moves down in z by 1 mm a step, the gripper closes at ``close_at``."""
    eef = np.stack([np.zeros(steps + 1), np.zeros(steps + 1), 0.2 - 1e-3 * np.arange(steps + 1)], axis=1)
    grip = np.where(np.arange(steps + 1) >= (close_at if close_at is not None else steps), 1.0, -1.0)
    obs = np.zeros((steps + 1, OBS_DIM), np.float32)
    obs[:, :3] = eef
    obs[:, 5] = np.arange(steps + 1)  # a marker of the step
    return SkillRecord(
        name="pick_1",
        cube=1,
        onto=ONTO_NONE,
        target=np.zeros(3),
        success=success,
        violation=False,
        seed=seed,
        index=0,
        obs=obs,
        actions=np.zeros((steps, 7), np.float32),
        eef=eef,
        gripper=grip.astype(np.float32),
        modes=np.zeros(steps + 1, np.int16),
    )


def test_waypoints_are_the_eef_every_stride_steps_padded_with_the_last() -> None:
    r = record(50, close_at=20)
    made = skill_plan(r)
    assert made is not None
    obs, plan = made
    assert plan.shape == (PLAN_HORIZON, 4) and obs.shape == (PLAN_HORIZON, OBS_DIM)
    k = np.arange(PLAN_HORIZON)
    ends = np.minimum(PLAN_STRIDE * (k + 1), 50)
    assert np.allclose(plan[:, 2], 0.2 - 1e-3 * ends)
    assert np.array_equal(plan[:, 3], np.where(ends >= 20, 1.0, -1.0))
    assert obs[0, 5] == 0 and obs[1, 5] == PLAN_STRIDE  # the first observation is the skill's start
    assert np.all(plan[ends == 50] == plan[-1])  # padding repeats the last waypoint


def test_too_long_or_empty_skills_make_no_plan() -> None:
    assert skill_plan(record(PLAN_STRIDE * PLAN_HORIZON)) is not None
    assert skill_plan(record(PLAN_STRIDE * PLAN_HORIZON + 1)) is None
    assert skill_plan(record(0)) is None


def test_dataset_has_one_window_per_kept_skill() -> None:
    recs = [record(40, seed=1), record(60, success=False, seed=2), record(200, seed=3), record(70, seed=4)]
    data = to_plan_dataset(recs)
    assert data.meta["episode_seeds"] == [1, 4] and data.meta["dropped_too_long"] == 1
    assert data.meta["plan_stride"] == PLAN_STRIDE and data.meta["plan_horizon"] == PLAN_HORIZON
    windows = PlanWindows(data, n_obs=1, horizon=PLAN_HORIZON, action_start=0)
    assert len(windows) == 2
    obs, plan = windows[1]
    assert obs[0, 5] == 0 and np.allclose(plan, skill_plan(recs[3])[1])  # type: ignore[index]
    assert len(to_plan_dataset(recs, successful_only=False).meta["skills"]) == 3


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"records": "x"}, TypeError, "records"),
        ({"records": [1]}, TypeError, r"records\[0\]"),
        ({"records": []}, ValueError, "no skill"),
        ({"records": [record(10)], "stride": 0}, ValueError, "stride"),
        ({"records": [record(10)], "successful_only": "yes"}, TypeError, "successful_only"),
    ],
)
def test_bad_input_is_refused(kwargs: dict[str, Any], error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        to_plan_dataset(**kwargs)


def test_cli_writes_a_trajectory_file_from_the_shards(tmp_path: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    import steer_envs.bench.suites.itps_blockstack.data as shards
    from steer_envs.bench.suites.itps_blockstack.data import main

    merged = tmp_path / "merged.npz"
    monkeypatch.setattr(shards, "skills_dataset", lambda cache, n, k, b: ([record(40), record(50)], merged))
    out = tmp_path / "plans.npz"
    assert main(["--cache-dir", str(tmp_path), "--episodes", "2", "--permutations", "1", "--out", str(out)]) == 0
    data = load_trajectories(out)
    assert len(data) == 2 * 2 * PLAN_HORIZON and data.meta["episodes"] == 2
    with pytest.raises(SystemExit) as exc:
        main(["--cache-dir", str(tmp_path), "--out", str(tmp_path / "plans.txt")])
    assert exc.value.code == 2


def test_cube_permutations_copy_each_plan_with_the_cube_slots_reordered() -> None:
    r = record(40)
    r.obs[:, 5:] = np.repeat(np.arange(4), 7)[None, :] + 10  # cube i's pose entries all read 10 + i
    data = to_plan_dataset([r], permutations=3, seed=1)
    assert len(data) == 4 * PLAN_HORIZON and data.meta["cube_permutations"] == 3
    starts = data.observations[::PLAN_HORIZON]
    assert np.array_equal(starts[0], r.obs[0])  # the first copy is the original
    for row in starts:
        assert np.array_equal(row[:5], r.obs[0, :5])
        slots = row[5:].reshape(4, 7)
        assert np.all(slots == slots[:, :1]) and sorted(slots[:, 0]) == [10, 11, 12, 13]
    assert np.all(data.actions.reshape(4, PLAN_HORIZON, 4) == data.actions[:PLAN_HORIZON])
    with pytest.raises(ValueError, match="permutations"):
        to_plan_dataset([r], permutations=-1)
