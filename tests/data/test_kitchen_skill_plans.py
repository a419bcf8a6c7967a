"""Kitchen skill plans and skill files: waypoint layout, yaw convention, padding, one window per skill, files, CLI.

Synthetic records only (no simulator): the recorded skills are tested in
``tests/control/test_kitchen_control.py`` and ``tests/bench/test_itps_kitchen_data.py``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from skill_samples import check_descent_plan
from skill_samples import kitchen_record as record

from steer_envs.data.kitchen_plans import PLAN_DIM, PLAN_HORIZON, PLAN_STRIDE, plan_yaw, skill_plan, to_plan_dataset
from steer_envs.data.kitchen_skills import OBS_DIM, SkillRecord, load_skills, save_skills
from steer_envs.data.trajectories import PlanWindows, load_trajectories
from steer_envs.io import DatasetError


def test_waypoints_are_the_state_every_stride_steps_padded_with_the_last() -> None:
    assert PLAN_DIM == 5
    made = skill_plan(record(100, close_at=40))
    obs, plan = check_descent_plan(
        made, 100, 40, horizon=PLAN_HORIZON, stride=PLAN_STRIDE, width=PLAN_DIM, obs_dim=OBS_DIM, marker=7
    )
    again = skill_plan(record(100, close_at=40))
    assert again is not None and np.array_equal(again[1], plan) and np.array_equal(again[0], obs)  # deterministic


def test_too_long_or_empty_skills_make_no_plan() -> None:
    assert skill_plan(record(PLAN_STRIDE * PLAN_HORIZON)) is not None
    assert skill_plan(record(PLAN_STRIDE * PLAN_HORIZON + 1)) is None
    assert skill_plan(record(0)) is None
    assert skill_plan(record(20), stride=1, horizon=10) is None


def test_plan_yaw_is_continuous_and_anchored_at_the_first_switch() -> None:
    # a half turn of the wrist through the (-pi, pi] seam stays one continuous turn
    r = record(90, close_at=60, yaw0=0.0, turn=np.pi)
    yaw = plan_yaw(r.yaw, r.gripper)
    assert np.all(np.abs(np.diff(yaw)) < 0.1) and np.isclose(yaw[-1] - yaw[0], np.pi)
    assert -np.pi / 2 <= yaw[60] < np.pi / 2  # the grasp's yaw is in the window ...
    assert np.isclose((yaw[0] - r.yaw[0]) % np.pi, 0.0) or np.isclose((yaw[0] - r.yaw[0]) % np.pi, np.pi)  # ... k*pi
    # the two equivalent wrist yaws give the same plan yaw
    a = plan_yaw(record(50, close_at=20, yaw0=0.3).yaw, record(50, close_at=20).gripper)
    b = plan_yaw(record(50, close_at=20, yaw0=0.3 - np.pi).yaw, record(50, close_at=20).gripper)
    assert np.allclose(a, b) and np.allclose(a, 0.3)
    # no switch: the last step anchors
    assert -np.pi / 2 <= plan_yaw([3.0, 3.1], [-1.0, -1.0])[-1] < np.pi / 2
    made = skill_plan(r)
    assert made is not None and np.allclose(made[1][:, 3], yaw[np.minimum(PLAN_STRIDE * np.arange(1, 33), 90)])
    with pytest.raises(ValueError, match="gripper"):
        plan_yaw([0.0, 1.0], [1.0])
    with pytest.raises(ValueError, match="yaw"):
        plan_yaw([], [])


def test_dataset_has_one_window_per_kept_skill() -> None:
    recs = [record(40, seed=1), record(60, success=False, seed=2), record(400, seed=3), record(70, seed=4)]
    data = to_plan_dataset(recs, meta={"note": 1})
    assert data.meta["episode_seeds"] == [1, 4] and data.meta["dropped_too_long"] == 1 and data.meta["note"] == 1
    assert data.meta["plan_stride"] == PLAN_STRIDE and data.meta["plan_horizon"] == PLAN_HORIZON
    assert data.meta["skills"] == ["pick_bowl"] * 2 and data.meta["skill_tasks"] == ["sink"] * 2
    assert data.obs_dim == OBS_DIM and data.action_dim == PLAN_DIM and len(data) == 2 * PLAN_HORIZON
    windows = PlanWindows(data, n_obs=1, horizon=PLAN_HORIZON, action_start=0)
    assert len(windows) == 2
    obs, plan = windows[1]
    made = skill_plan(recs[3])
    assert made is not None and obs[0, 7] == 0 and np.allclose(plan, made[1])
    assert len(to_plan_dataset(recs, successful_only=False).meta["skills"]) == 3


def test_skill_plan_refuses_a_non_record() -> None:
    with pytest.raises(TypeError, match="record"):
        skill_plan("pick")  # type: ignore[arg-type]


def test_skill_files_round_trip_and_refuse_bad_files(tmp_path: Path) -> None:
    recs = [record(30, seed=5, close_at=10), record(12, seed=5, name="place_in_sink")]
    path = save_skills(tmp_path / "s.npz", recs, meta={"who": "test"})
    back, meta = load_skills(path)
    assert meta["who"] == "test" and [r.name for r in back] == ["pick_bowl", "place_in_sink"]
    for a, b in zip(recs, back, strict=True):
        for field in ("obs", "actions", "eef", "yaw", "gripper", "modes", "handle", "hinge"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), field
        assert (a.task, a.seed, a.success, a.mode_before, a.mode_after) == (
            b.task,
            b.seed,
            b.success,
            "closed_table",
            "closed_table",
        )
    scene = back[0].scene
    assert not scene.held and np.array_equal(scene.eef, recs[0].eef[0]) and np.array_equal(scene.handle, recs[0].handle)
    with pytest.raises(ValueError, match="path"):
        save_skills(tmp_path / "s.txt", recs)
    with pytest.raises(ValueError, match="records"):
        save_skills(tmp_path / "e.npz", [])
    with pytest.raises(TypeError, match=r"records\[0\]"):
        save_skills(tmp_path / "e.npz", ["x"])  # type: ignore[list-item]
    with pytest.raises(TypeError, match="meta"):
        save_skills(tmp_path / "e.npz", recs, meta={"x": object()})
    arrays = dict(np.load(path))
    arrays["modes"] = arrays["modes"] + 100
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(DatasetError, match="modes"):
        load_skills(tmp_path / "bad.npz")
    with pytest.raises(DatasetError, match="no such file"):
        load_skills(tmp_path / "missing.npz")


def test_cli_writes_a_trajectory_file_from_the_shards(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import steer_envs.data.kitchen_shards as shards
    from steer_envs.data.kitchen_shards import main

    merged = tmp_path / "merged.npz"
    seen: list[Any] = []

    def fake(
        cache: Any, n: int, tasks: Any, max_skills: int, every_task: bool, perturbed_starts: bool
    ) -> tuple[list[SkillRecord], Path]:
        seen.append((n, list(tasks), max_skills, every_task, perturbed_starts))
        return [record(40), record(50, name="place_in_sink")], merged

    monkeypatch.setattr(shards, "skills_dataset", fake)
    out = tmp_path / "plans.npz"
    assert main(["--cache-dir", str(tmp_path), "--episodes", "2", "--tasks", "sink", "--out", str(out)]) == 0
    assert seen == [(2, ["sink"], 8, False, False)]
    data = load_trajectories(out)
    assert len(data) == 2 * PLAN_HORIZON and data.meta["episodes"] == 2 and data.meta["tasks"] == ["sink"]
    assert "perturbed_starts" not in data.meta
    assert main(["--cache-dir", str(tmp_path), "--episodes", "2", "--every-task", "--out", str(out)]) == 0
    assert seen[-1] == (2, ["microwave", "sink"], 8, True, False) and load_trajectories(out).meta["every_task"] is True
    assert main(["--cache-dir", str(tmp_path), "--episodes", "2", "--perturbed-starts", "--out", str(out)]) == 0
    assert seen[-1] == (2, ["microwave", "sink"], 8, False, True)
    assert load_trajectories(out).meta["perturbed_starts"] is True
    with pytest.raises(SystemExit) as exc:
        main(["--cache-dir", str(tmp_path), "--out", str(tmp_path / "plans.txt")])
    assert exc.value.code == 2
