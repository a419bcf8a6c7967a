"""GLiDE on the robosuite arms: the plan's choices, BC adapter, pseudo-attractor maths, mode mapping, evaluation."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from steer_envs.baselines import glide
from steer_envs.data import robosuite_replays as rr

TINY = glide.ArmBCSettings(hidden=(16,), steps=20)
BLOCK_REL = rr.feature_columns("lift", ["block_to_robot0_eef_pos"])
BLOCK = rr.feature_columns("lift", ["block_pos"])
EEF = rr.feature_columns("lift", ["robot0_eef_pos"])
PLAN = SimpleNamespace(goals={1: "block_to_robot0_eef_pos", 2: "block_to_robot0_eef_pos", 3: "robot0_eef_pos"})


def _features(eef: np.ndarray, block: np.ndarray) -> np.ndarray:
    """Lift feature rows ``(T, 23)`` with the given eef and block positions (the rest zero)."""
    f = np.zeros((len(eef), 23))
    f[:, EEF], f[:, BLOCK], f[:, BLOCK_REL] = eef, block, block - eef
    return f


def _demo(offset: float) -> tuple[np.ndarray, np.ndarray]:
    """The eef goes down onto a block at (offset, 0, 0), then up with it: modes 0 0 0 1 1 2."""
    eef = np.array([[0, 0, 0.3], [0, 0, 0.2], [0, 0, 0.1], [0, 0, 0.01], [0, 0, 0.05], [0, 0, 0.1]])
    eef[:, 0] += offset
    block = np.tile([offset, 0.0, 0.0], (6, 1))
    block[4:, 2] = eef[4:, 2] - 0.01  # lifted in the gripper
    return _features(eef, block), np.array([0, 0, 0, 1, 1, 2])


def test_attractors_from_transitions_relative_and_absolute() -> None:
    (f1, m1), (f2, m2) = _demo(0.0), _demo(0.2)
    reach, lift, final = glide.mode_attractors("lift", [f1, f2], [m1, m2], plan=PLAN, quantile=1.0)
    # mode 0 -> 1 happens at state 3: the block is 1 cm below the eef in both demos
    np.testing.assert_allclose(reach.value, [0.0, 0.0, -0.01])
    assert reach.relative and not final.relative
    np.testing.assert_allclose(lift.value, [0.0, 0.0, -0.01])  # mode 1 -> 2 at state 5 (block held)
    np.testing.assert_allclose(final.value, [0.1, 0.0, 0.1])  # the final mode: the mean last eef
    # the relative target follows the block: wherever the block is now, the eef goes 1 cm above it
    now = _features(np.array([[0.5, 0.5, 0.5]]), np.array([[0.3, -0.1, 0.0]]))[0]
    np.testing.assert_allclose(reach.target(now), [0.3, -0.1, 0.01])
    np.testing.assert_allclose(final.target(now), [0.1, 0.0, 0.1])
    # the threshold is the quantile of the mode's demo distances to its target (quantile 1: the largest)
    assert reach.threshold == pytest.approx(0.29)
    assert reach.distance(now) == pytest.approx(np.linalg.norm([0.2, 0.6, 0.49]))


def test_min_threshold_and_a_mode_never_left() -> None:
    f, m = _demo(0.0)
    m = np.array([0, 0, 0, 0, 0, 0])  # never leaves mode 0: every attractor falls back to the last state
    reach, lift, final = glide.mode_attractors("lift", [f], [m], plan=PLAN, min_threshold=0.5)
    np.testing.assert_allclose(reach.value, f[-1, BLOCK_REL])
    assert reach.threshold == 0.5 and lift.threshold == np.inf and final.threshold == np.inf


def test_the_attractor_is_mixed_in_only_far_from_its_target() -> None:
    demos = [_arm_trajectory(*_demo(0.0)), _arm_trajectory(*_demo(0.1))]
    policy = glide.GlideArmPolicy(
        "lift", demos, [d.modes for d in demos], plan=PLAN, attractor_weight=0.5, min_threshold=0.05, settings=TINY
    )
    action = np.array([0.2, 0.0, -0.2, 0.1, 0.0, 0.0, 1.0])
    threshold = policy.attractors[0].threshold
    near = _features(np.array([[0.0, 0.0, 0.01 + 0.5 * threshold]]), np.zeros((1, 3)))[0]
    np.testing.assert_array_equal(policy.attract(action, near, 0), action)
    far = _features(np.array([[0.0, 0.0, 0.01 + 2.0 * threshold]]), np.zeros((1, 3)))[0]
    out = policy.attract(action, far, 0)
    pull = np.clip(10.0 * (policy.attractors[0].target(far) - far[EEF]), -1, 1)
    np.testing.assert_allclose(out[:3], 0.5 * action[:3] + 0.5 * pull)
    np.testing.assert_array_equal(out[3:], action[3:])  # rotation and gripper are the policy's
    assert policy.act(np.zeros(19), far, 2).shape == (7,)  # the final mode, without pairs, borrows mode 1's BC
    assert policy.policy_of == [0, 1, 1]
    with pytest.raises(ValueError):
        policy.act(np.zeros(19), far, 3)


def _arm_trajectory(features: np.ndarray, modes: np.ndarray) -> rr.ArmTrajectory:
    t = len(features)
    rng = np.random.default_rng(t)
    return rr.ArmTrajectory(
        task="lift",
        seed=0,
        features=features.astype(np.float32),
        obs=rng.normal(size=(t, 19)).astype(np.float32),
        actions=np.clip(rng.normal(size=(t - 1, 7)), -1, 1).astype(np.float32),
        eef=features[:, EEF],
        modes=modes.astype(np.int16),
        success=True,
        violation_step=-1,
        perturbation=rr.ArmPerturbation("demo"),
    )


def test_arm_bc_clips_each_component_and_is_seeded() -> None:
    x = np.random.default_rng(0).normal(size=(64, 5))
    a = np.clip(np.c_[x, x[:, :2]], -1, 1)
    one, two = glide.ArmBC(x, a, seed=3, settings=TINY), glide.ArmBC(x, a, seed=3, settings=TINY)
    out = one.act(100 * x)
    assert out.shape == (64, 7) and np.all(np.abs(out) <= 1.0)
    np.testing.assert_array_equal(out, two.act(100 * x))
    assert one.act(x[0]).shape == (7,)


def test_plan_steps_map_cans_four_steps_to_three_modes() -> None:
    recorded_plan = glide.recorded_plan
    assert glide.plan_goal_features("can", recorded_plan("can")) == [
        "can_to_robot0_eef_pos",  # reach: step 1
        "robot0_eef_pos",  # transport (close + move): step 3, where the merged steps end
        "robot0_eef_pos",  # hover: step 4
    ]
    assert glide.plan_goal_features("square", recorded_plan("square"))[2] == "peg_to_robot0_eef_pos"
    with pytest.raises(ValueError, match="goal feature"):
        glide.plan_goal_features(
            "lift", SimpleNamespace(goals={1: "block_quat", 2: "robot0_eef_pos", 3: "robot0_eef_pos"})
        )


def test_demo_modes_checks_the_predictor() -> None:
    demos = [_arm_trajectory(*_demo(0.0))]

    class Wrong:
        def predict(self, states: np.ndarray) -> np.ndarray:
            return np.full(len(states), 5)

    with pytest.raises(ValueError, match=r"modes outside \[0, 3\)"):
        glide.demo_modes("lift", demos, Wrong())
    with pytest.raises(TypeError, match="predictor"):
        glide.demo_modes("lift", demos, object())
    assert glide.demo_modes("lift", demos, glide.GROUND_TRUTH)[0].tolist() == [0, 0, 0, 1, 1, 2]


# ------------------------------------------------------------------- with the simulator
@pytest.fixture(scope="module")
def lift_demos() -> list[rr.ArmTrajectory]:
    pytest.importorskip("robosuite")
    env = rr.make_arm_env("lift")
    try:
        return [rr.record_demo(env, seed) for seed in (0, 1)]
    finally:
        env.close()


def _evaluate(policy: Any, predictor: Any = glide.GROUND_TRUTH, perturbed: bool = False) -> dict[str, Any]:
    import gymnasium as gym

    from steer_envs.wrappers.arm_perturbation import ArmPerturbationWrapper

    env: Any = gym.make("steer_envs/Lift-v0", max_episode_steps=15)
    if perturbed:
        env = ArmPerturbationWrapper(env)
    try:
        return glide.evaluate_arm_policy(env, policy, predictor=predictor, n_episodes=1)
    finally:
        env.close()


def test_training_and_evaluation_smoke_on_lift(lift_demos: list[rr.ArmTrajectory]) -> None:
    assert all(d.success for d in lift_demos)
    bc = glide.train_arm_policy("lift", "bc", 0, demos=lift_demos, bc=TINY)
    assert isinstance(bc, glide.BCArmPolicy)
    for perturbed in (False, True):
        result = _evaluate(bc, perturbed=perturbed)
        assert 0.0 <= result["success_rate"] <= 1.0 and 0.0 <= result["violation_rate"] <= 1.0
        assert 1 <= result["mean_length"] <= 15 and result["episodes"]["seed"] == [10_000]
        assert result["task"] == "lift" and result["eval_seconds"] >= 0
        if not perturbed:
            assert result["mean_perturbations"] == 0
    glide_bc = glide.train_arm_policy("lift", "glide_bc", 0, demos=lift_demos, predictor=glide.GROUND_TRUTH, bc=TINY)
    again = glide.train_arm_policy("lift", "glide_bc", 0, demos=lift_demos, predictor=glide.GROUND_TRUTH, bc=TINY)
    assert isinstance(glide_bc, glide.GlideBC)  # the GLiDE+BC core PolygonNav's GlideBCPolicy shares
    assert _evaluate(glide_bc)["episodes"] == _evaluate(again)["episodes"]  # deterministic for a seed
    kmeans = glide.KMeansModes("lift", lift_demos)
    km = glide.train_arm_policy("lift", "glide_bc", 0, demos=lift_demos, predictor=kmeans, bc=TINY)
    assert _evaluate(km, kmeans, perturbed=True)["n_episodes"] == 1


def test_training_and_evaluation_refuse_bad_arguments(lift_demos: list[rr.ArmTrajectory]) -> None:
    with pytest.raises(ValueError, match="method"):
        glide.train_arm_policy("lift", "dp", 0, demos=lift_demos)
    with pytest.raises(ValueError, match="demos"):
        glide.train_arm_policy("can", "bc", 0, demos=lift_demos)
    with pytest.raises(TypeError, match="robosuite arm env"):
        glide.evaluate_arm_policy(
            object(), glide.BCArmPolicy(glide.ArmBC(np.zeros((2, 3)), np.zeros((2, 7)), settings=TINY)), n_episodes=1
        )
    with pytest.raises(TypeError, match="predictor"):
        _evaluate(glide.train_arm_policy("lift", "bc", 0, demos=lift_demos, bc=TINY), predictor=object())


def test_feasibility_and_plan_choices() -> None:
    f = glide.manipulation_feasibility(4)
    assert f[0, 3] == -2 and f[0, 1] == 0 and f[3, 2] == 0 and f[2, 0] == -1
    assert glide.recorded_plan("square").num_modes == 4 and glide.recorded_plan("can").num_modes == 4
    assert glide.selected_features("can", "full")[0] == "can_to_robot0_eef_pos"
    assert len(glide.selected_features("square", "no_feature_selection")) == 15
    names = glide.selected_features("square", "full")
    assert glide.dynamics_columns("square", names) == ((7, 8, 9), (0, 1, 2))  # peg-to-gripper moves with the robot
    for task in ("lift", "can", "square"):  # every variant's features carry psi's inputs and outputs
        glide.dynamics_columns(task, glide.selected_features(task, "no_feature_selection"))
    with pytest.raises(ValueError, match="needs the feature 'robot0_eef_pos'"):
        glide.dynamics_columns("lift", ["block_to_robot0_eef_pos"])
    assert glide.ArmGroundingSetup().stride_of("lift") == 1 and glide.ArmGroundingSetup(stride=3).stride_of("can") == 3
    with pytest.raises(ValueError, match="unknown variant"):
        glide.train_arm_predictor("lift", "oracle", [])


# ------------------------------------------------------- recipes, run cache, public-code attractor
def test_robomimic_recipe_trains_raw_inputs_with_a_tanh_output() -> None:
    r = glide.ArmBCSettings.recipe("robomimic")
    assert (r.hidden, r.lr, r.batch_size, r.standardize, r.output) == ((1024, 1024), 1e-4, 100, False, "tanh")
    assert r.steps == glide.ROBOMIMIC_CPU_STEPS < glide.ROBOMIMIC_STEPS
    assert glide.ArmBCSettings.recipe("thesis") == glide.ArmBCSettings()
    small = glide.ArmBCSettings.recipe("robomimic", hidden=(16,), steps=30)
    assert (small.hidden, small.steps, small.lr) == ((16,), 30, 1e-4)
    x = np.random.default_rng(1).normal(size=(50, 4)) * [1.0, 10.0, 100.0, 0.01]
    a = np.c_[np.clip(x[:, :2], -1, 1), np.zeros((50, 4)), np.where(x[:, :1] > 0, 1.0, -1.0)]  # gripper at +-1
    raw = glide.ArmBC(x, a, settings=small)
    np.testing.assert_array_equal(raw.mean, 0.0)
    np.testing.assert_array_equal(raw.scale, 1.0)  # raw observations: no standardisation
    assert raw.policy.config.output == "tanh" and np.all(np.abs(raw.act(x)) <= 1.0)
    thesis = glide.ArmBC(x, a, settings=glide.ArmBCSettings(hidden=(16,), steps=30))
    assert np.allclose(thesis.mean, x.mean(0)) and not np.allclose(thesis.act(x), raw.act(x))
    with pytest.raises(ValueError, match="recipe"):
        glide.ArmBCSettings.recipe("diffusion")
    with pytest.raises(ValueError, match="output"):
        glide.ArmBCSettings(output="relu")
    with pytest.raises(TypeError, match="standardize"):
        glide.ArmBCSettings(standardize=1)  # type: ignore[arg-type]


def test_arm_bc_runs_are_cached_and_keep_learning_curve_steps(tmp_path: Any) -> None:
    x = np.random.default_rng(0).normal(size=(64, 5))
    a = np.clip(np.c_[x, x[:, :2]], -1, 1)
    settings = glide.ArmBCSettings(hidden=(16,), steps=40)
    first = glide.ArmBC(x, a, seed=2, settings=settings, cache_dir=tmp_path, keep_steps=(10, 20))
    assert first.trained_steps == 40 and first.run_folder is not None and first.run_folder.parent == tmp_path
    again = glide.ArmBC(x, a, seed=2, settings=settings, cache_dir=tmp_path, keep_steps=(10, 20))
    assert again.trained_steps == 0  # read from the cache
    np.testing.assert_array_equal(again.act(x), first.act(x))
    np.testing.assert_array_equal(glide.ArmBC(x, a, seed=2, settings=settings).act(x), first.act(x))  # as in memory
    at_10 = first.at_step(10)
    assert at_10.steps == 10 and first.steps == 40
    short = glide.ArmBC(x, a, seed=2, settings=glide.ArmBCSettings(hidden=(16,), steps=10))
    np.testing.assert_array_equal(at_10.act(x), short.act(x))  # the kept weights are a 10-step run's
    with pytest.raises(ValueError, match="no weights kept at step 15"):
        first.at_step(15)
    with pytest.raises(ValueError, match="keep"):
        glide.ArmBC(x, a, settings=settings, keep_steps=(41,))
    with pytest.raises(TypeError, match="cache_dir"):
        glide.ArmBC(x, a, settings=settings, cache_dir=3)  # type: ignore[arg-type]


def _potential(rel: np.ndarray, offset: np.ndarray, eef: np.ndarray) -> float:
    """The fork's potential exp(|(object - eef) - g|) at eef, the object fixed (rel = object - eef at eef = 0)."""
    return float(np.exp(np.linalg.norm(rel - eef - offset)))


def test_public_code_attractor_is_the_forks_gradient_pull() -> None:
    (f1, m1), (f2, m2) = _demo(0.0), _demo(0.2)
    pull = glide.PublicCodeAttractor.from_demos("lift", [f1, f2], [m1, m2])
    np.testing.assert_allclose(pull.offset, [0.0, 0.0, -0.015])  # the grasp offset -0.01, its height x 1.5
    now = _features(np.array([[0.3, 0.1, 0.4]]), np.array([[0.0, 0.0, 0.0]]))[0]
    rel = now[BLOCK_REL]
    step = 1e-6  # the pull is -0.1 x the potential's gradient in the eef position (central differences)
    grad = [(_potential(rel, pull.offset, e) - _potential(rel, pull.offset, -e)) / (2 * step) for e in np.eye(3) * step]
    np.testing.assert_allclose(pull.pull(now), -0.1 * np.asarray(grad), rtol=1e-5)
    action = np.array([0.1, -0.1, 0.0, 0.3, 0.2, 0.1, 0.7])
    out = pull.apply(action, now)
    np.testing.assert_allclose(out[:3], np.clip(action[:3] - 0.1 * np.asarray(grad), -1, 1), rtol=1e-5)
    np.testing.assert_array_equal(out[3:6], 0.0)  # rotation zeroed while it acts
    assert out[6] == 0.7  # the gripper is the policy's
    close = _features(np.array([[0.0, 0.0, 0.09]]), np.zeros((1, 3)))[0]  # 9 cm from the block: no pull
    assert pull.pull(close) is None
    np.testing.assert_array_equal(pull.apply(action, close), action)


def test_glide_bc_with_the_public_code_attractor_acts_in_the_first_mode_only() -> None:
    demos = [_arm_trajectory(*_demo(0.0)), _arm_trajectory(*_demo(0.1))]
    predicted = [np.array([0, 0, 1, 1, 1, 2]), np.array([0, 0, 1, 1, 1, 2])]  # the predictor's: one step early
    thesis = glide.GlideArmPolicy("lift", demos, predicted, plan=PLAN, settings=TINY)
    public = glide.GlideArmPolicy("lift", demos, predicted, plan=PLAN, settings=TINY, attractor="public_code")
    assert thesis.public is None and public.public is not None
    far = _features(np.array([[0.3, 0.1, 0.4]]), np.zeros((1, 3)))[0]
    obs = np.zeros(19)
    policy_action = public.policies[0].act(obs)  # the BCs are the same: same data, seeds and settings
    np.testing.assert_array_equal(policy_action, thesis.policies[0].act(obs))
    np.testing.assert_array_equal(public.act(obs, far, 0), public.public.apply(policy_action, far))
    assert not np.allclose(public.act(obs, far, 0), thesis.act(obs, far, 0))  # another attractor
    np.testing.assert_array_equal(public.act(obs, far, 1), public.policies[1].act(obs))  # no pull after mode 0
    # the fork reads the true mode: the pull follows it, not the mode the policy runs on
    fork = glide.GlideArmPolicy(
        "lift", demos, predicted, plan=PLAN, settings=TINY, attractor="public_code", attractor_mode="ground_truth"
    )
    np.testing.assert_array_equal(fork.act(obs, far, 1, true_mode=0), fork.public.apply(fork.policies[1].act(obs), far))
    np.testing.assert_array_equal(fork.act(obs, far, 0, true_mode=1), fork.policies[0].act(obs))
    # its grasp point comes from the demos' recorded modes (exit at state 3), the classifier's from state 2
    assert fork.public.offset[2] == pytest.approx(-0.015) and public.public.offset[2] != fork.public.offset[2]
    with pytest.raises(ValueError, match="true_mode"):
        fork.act(obs, far, 0)
    with pytest.raises(ValueError, match="attractor"):
        glide.GlideArmPolicy("lift", demos, predicted, plan=PLAN, settings=TINY, attractor="fork")
    with pytest.raises(ValueError, match="attractor_mode"):
        glide.GlideArmPolicy("lift", demos, predicted, plan=PLAN, settings=TINY, attractor_mode="oracle")
    kept = glide.GlideArmPolicy("lift", demos, predicted, plan=PLAN, settings=TINY, keep_steps=(5,))
    assert [p.steps for p in kept.at_step(5).policies if p is not None] == [5, 5]
    assert kept.trained_steps == 40 and [p.steps for p in kept.policies if p is not None] == [20, 20]


def test_classifier_data_padding() -> None:
    from steer_envs.baselines.glide.arm_grounding import pad_states

    np.testing.assert_array_equal(pad_states(np.arange(6.0).reshape(3, 2), 5)[3:], [[4.0, 5.0], [4.0, 5.0]])
    assert pad_states(np.zeros((7, 2)), 5).shape == (7, 2)  # longer ones stay
    assert glide.ArmGroundingSetup().pad_to == 0
    with pytest.raises(ValueError, match="pad_to"):
        glide.ArmGroundingSetup(pad_to=-1)
