"""Demos and GLiDE counterfactual replays on the robosuite arms: features, replays, perturbations, files."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from robosuite_helpers import ROBOSUITE_MARKS, module_env

from steer_envs.data import robosuite_replays as rr
from steer_envs.io import DatasetError

pytestmark = ROBOSUITE_MARKS


lift = module_env("steer_envs.data.robosuite_replays:make_arm_env", "lift")


@pytest.fixture(scope="module")
def demo(lift: rr.RobosuiteEnv) -> rr.ArmTrajectory:
    return rr.record_demo(lift, 3)


def test_features_layout_and_values(lift: rr.RobosuiteEnv, demo: rr.ArmTrajectory) -> None:
    dim = sum(size for _, size in rr.FEATURES["lift"])
    assert demo.features.shape == (len(demo), dim)
    obs = lift.robosuite_obs
    f = rr.feature_vector(lift)
    np.testing.assert_allclose(f[rr.feature_columns("lift", ["block_pos"])], obs["cube_pos"], atol=1e-6)
    eef = f[rr.feature_columns("lift", ["robot0_eef_pos"])]
    rel = f[rr.feature_columns("lift", ["block_to_robot0_eef_pos"])]
    np.testing.assert_allclose(rel, obs["cube_pos"] - eef, atol=1e-6)
    for name in ("block_quat", "block_to_robot0_eef_quat", "robot0_eef_quat"):
        q = f[rr.feature_columns("lift", [name])]
        assert abs(np.linalg.norm(q) - 1) < 1e-5 and q[3] >= 0  # unit, canonical sign
    assert rr.feature_names("square")[-1] == "gripper_state" and "peg_to_robot0_eef_pos" in rr.feature_names("square")


def test_demo_is_a_successful_expert_episode(demo: rr.ArmTrajectory) -> None:
    assert demo.success and demo.violation_step == -1 and demo.source == -1
    assert demo.actions.shape == (len(demo) - 1, 7) and demo.obs.shape == (len(demo), 19)
    assert demo.modes[0] == 0 and demo.modes[-1] == 2  # reach ... reach_height
    assert np.all(np.diff(demo.modes) >= 0)


def test_recording_goes_on_while_success_holds(lift: rr.RobosuiteEnv, demo: rr.ArmTrajectory) -> None:
    # robosuite's demo collection: recorded until success has held for 10 more steps
    assert demo.success_from == len(demo) - 1 - rr.SUCCESS_HOLD_STEPS
    assert np.all(demo.modes[demo.success_from :] == 2) and demo.modes[demo.success_from - 1] != 2
    short = rr.record_demo(lift, 3, success_hold=0)
    assert short.success and short.success_from == len(short) - 1 == demo.success_from
    np.testing.assert_allclose(short.eef, demo.eef[: len(short)], atol=1e-9)
    with pytest.raises(ValueError, match="success_hold"):
        rr.record_demo(lift, 3, success_hold=-1)


def test_unperturbed_replay_retraces_the_demo(lift: rr.RobosuiteEnv, demo: rr.ArmTrajectory) -> None:
    r = rr.replay(lift, demo, rr.ArmPerturbation("demo"), source=0)
    assert r.success and len(r) == len(demo) and r.source == 0
    np.testing.assert_allclose(r.eef, demo.eef, atol=1e-6)
    assert np.array_equal(r.modes, demo.modes)


def test_gripper_forced_open_while_grasping_fails(lift: rr.RobosuiteEnv, demo: rr.ArmTrajectory) -> None:
    closing = int(np.flatnonzero(demo.modes == 1)[0]) - 10  # the fingers are closing on the cube
    r = rr.replay(lift, demo, rr.ArmPerturbation("gripper", (closing, closing + 15)))
    assert not r.success and r.modes[-1] != 2


def test_sample_perturbation_respects_the_windows(demo: rr.ArmTrajectory) -> None:
    rng = np.random.default_rng(0)
    n = len(demo.actions)
    kinds = []
    for _ in range(300):
        p = rr.sample_perturbation(demo, rng, min_window=10, keep_last=14)
        s, e = p.window
        kinds.append(p.kind)
        assert 0 <= s <= e < n - 14
        if p.kind == "kernel":
            assert e - s + 1 >= 10 and np.all(np.abs(p.target - demo.eef[(s + e) // 2 + 1]) <= 0.1 + 1e-12)
        else:
            assert 5 <= e - s + 1 <= 20 and np.all(np.isnan(p.target))
    assert 0.55 < kinds.count("kernel") / len(kinds) < 0.78  # 2 of 3
    with pytest.raises(ValueError, match="window"):
        rr.sample_perturbation(demo, rng, kernel_fraction=1.0, min_window=n)
    with pytest.raises(ValueError, match="kernel_fraction"):
        rr.sample_perturbation(demo, rng, kernel_fraction=1.5)


def test_early_terminated_copy_is_a_shorter_failure(demo: rr.ArmTrajectory) -> None:
    cut = rr.early_terminated(demo, np.random.default_rng(1))
    assert not cut.success and cut.perturbation.kind == "truncated"
    assert 2 <= len(cut) < len(demo) and len(cut.actions) == len(cut) - 1
    np.testing.assert_array_equal(cut.features, demo.features[: len(cut)])
    lengths = {len(rr.early_terminated(demo, np.random.default_rng(s))) for s in range(200)}
    assert max(lengths) == demo.success_from  # never a state where the task had succeeded
    assert min(lengths) >= int(0.3 * demo.success_from)


def test_files_round_trip_and_refuse_bad_input(tmp_path, demo: rr.ArmTrajectory) -> None:
    cut = rr.early_terminated(demo, np.random.default_rng(1))
    path = rr.save_trajectories(tmp_path / "t.npz", [demo, cut], meta={"note": "x"})
    back, meta = rr.load_trajectories(path)
    assert meta["note"] == "x" and meta["task"] == "lift" and len(back) == 2
    for a, b in zip(back, [demo, cut], strict=True):
        for name in ("features", "obs", "actions", "eef", "modes"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert (a.success, a.perturbation.kind, a.seed, a.success_from) == (
            b.success,
            b.perturbation.kind,
            b.seed,
            b.success_from,
        )
    with pytest.raises(ValueError, match=r"\.npz"):
        rr.save_trajectories(tmp_path / "t.txt", [demo])
    with pytest.raises(ValueError, match="one task"):
        rr.save_trajectories(tmp_path / "u.npz", [demo, replace(demo, task="can")])
    bad = replace(demo, features=demo.features.copy())
    bad.features[0, 0] = np.nan
    rr.save_trajectories(tmp_path / "nan.npz", [bad])
    with pytest.raises(DatasetError, match="NaN"):
        rr.load_trajectories(tmp_path / "nan.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(DatasetError, match=r"junk\.npz"):
        rr.load_trajectories(tmp_path / "junk.npz")


def test_bad_names_and_envs() -> None:
    with pytest.raises(ValueError, match="task"):
        rr.feature_names("stack")
    with pytest.raises(ValueError, match="unknown features"):
        rr.feature_columns("can", ["block_pos"])
    with pytest.raises(ValueError, match="non-empty"):
        rr.feature_columns("can", "can_pos")
    with pytest.raises(TypeError, match="RobosuiteEnv"):
        rr.feature_vector(object())  # type: ignore[arg-type]
