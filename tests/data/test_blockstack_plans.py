"""BlockStack skill plans: the waypoint layout, padding, dropped skills, one training window per skill, the CLI."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from skill_samples import blockstack_record as record
from skill_samples import check_descent_plan

from steer_envs.data.blockstack_plans import PLAN_HORIZON, PLAN_STRIDE, skill_plan, to_plan_dataset
from steer_envs.data.blockstack_skills import OBS_DIM
from steer_envs.data.trajectories import PlanWindows, load_trajectories


def test_waypoints_are_the_eef_every_stride_steps_padded_with_the_last() -> None:
    made = skill_plan(record(50, close_at=20))
    check_descent_plan(made, 50, 20, horizon=PLAN_HORIZON, stride=PLAN_STRIDE, width=4, obs_dim=OBS_DIM, marker=5)


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


def test_cli_writes_a_trajectory_file_from_the_shards(tmp_path: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    import steer_envs.data.blockstack_shards as shards
    from steer_envs.data.blockstack_shards import main

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


def _scene(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random 33-D observation row (unit cube quaternions) and a random plan."""
    from scipy.spatial.transform import Rotation

    obs = rng.uniform(-0.2, 0.2, size=(3, OBS_DIM)).astype(np.float32)
    for i in range(4):
        obs[:, 8 + 7 * i : 12 + 7 * i] = Rotation.random(3, random_state=i).as_quat()
    return obs, rng.uniform(-0.2, 0.2, size=(PLAN_HORIZON, 4)).astype(np.float32)


def test_move_scene_is_a_rigid_motion_of_positions_and_cube_yaws() -> None:
    from steer_envs.control.blockstack import yaw_of
    from steer_envs.data.blockstack_plans import move_scene

    obs, plan = _scene(np.random.default_rng(0))
    same = move_scene(obs, plan, 0.0, np.zeros(2))
    assert np.allclose(same[0], obs, atol=1e-6) and np.allclose(same[1], plan, atol=1e-6)
    moved_obs, moved_plan = move_scene(obs, plan, 0.7, np.array([0.03, -0.02]))
    points = [obs[:, 0:3], *(obs[:, 5 + 7 * i : 8 + 7 * i] for i in range(4))]
    moved = [moved_obs[:, 0:3], *(moved_obs[:, 5 + 7 * i : 8 + 7 * i] for i in range(4))]
    for a, b in zip(points, moved, strict=True):  # distances among eef, cubes and waypoints are kept
        assert np.allclose(
            np.linalg.norm(a[0] - plan[:, :3], axis=1), np.linalg.norm(b[0] - moved_plan[:, :3], axis=1), atol=1e-5
        )
        assert np.allclose(a[:, 2], b[:, 2])  # heights stay
    assert np.array_equal(moved_obs[:, 3:5], obs[:, 3:5]) and np.array_equal(moved_plan[:, 2:], plan[:, 2:])
    for i in range(4):  # each cube turns by the angle about the vertical (its tilt is kept)
        q0, q1 = obs[0, 8 + 7 * i : 12 + 7 * i], moved_obs[0, 8 + 7 * i : 12 + 7 * i]
        from scipy.spatial.transform import Rotation

        rel = Rotation.from_quat(q1) * Rotation.from_quat(q0).inv()
        assert np.allclose(rel.as_rotvec(), [0.0, 0.0, 0.7], atol=1e-5)
        assert np.isfinite(yaw_of(q1))


def test_rigid_augmentation_moves_every_copy_but_the_first() -> None:
    r = record(40)
    obs, _ = _scene(np.random.default_rng(1))
    r.obs[:] = obs[0]
    data = to_plan_dataset([r], permutations=3, shift=0.04, yaw=np.pi, seed=2)
    assert data.meta["augment_shift"] == 0.04 and data.meta["augment_yaw"] == float(np.pi)
    starts = data.observations[::PLAN_HORIZON]
    plans = data.actions.reshape(4, PLAN_HORIZON, 4)
    assert np.array_equal(starts[0], r.obs[0]) and np.allclose(plans[0], skill_plan(r)[1])  # type: ignore[index]
    for k in range(1, 4):
        assert not np.allclose(plans[k, :, :2], plans[0, :, :2])  # moved in xy ...
        assert np.allclose(plans[k, :, 2:], plans[0, :, 2:])  # ... not in height or gripper
        # the moved end effector keeps its distance to the waypoints
        assert np.allclose(
            np.linalg.norm(starts[k, :3] - plans[k, :, :3], axis=1),
            np.linalg.norm(starts[0, :3] - plans[0, :, :3], axis=1),
            atol=1e-5,
        )
    with pytest.raises(ValueError, match="shift"):
        to_plan_dataset([r], permutations=1, shift=-0.1)
    with pytest.raises(ValueError, match="yaw"):
        to_plan_dataset([r], permutations=1, yaw=4.0)


def test_the_rotation_centre_is_the_table_centre() -> None:
    from steer_envs.data.blockstack_plans import TABLE_CENTRE
    from steer_envs.envs.robosuite.blockstack import PLACE_RANGE, BlockStackEnv

    env = BlockStackEnv()
    try:
        env.reset(seed=0)
        assert np.allclose(env.rs_env.table_offset[:2], TABLE_CENTRE)
        assert np.all(np.abs(env.cube_pos[:, :2] - np.asarray(TABLE_CENTRE)) <= PLACE_RANGE + 1e-6)
    finally:
        env.close()
