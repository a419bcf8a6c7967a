"""RL-facing options of the 2D envs: dense rewards, observable sensors, normalised actions, goal-conditioned Maze2D."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from kinematic_helpers import step_singles_like_vector

import steer_envs
from steer_envs.data.experts import RLConventionExpert, make_expert
from steer_envs.envs.kinematic import DENSE_REWARD_SCALE
from steer_envs.envs.maze2d import Maze2DEnv, Maze2DGoalEnv
from steer_envs.envs.registry import BASE_ENTRIES, VARIANT_ENTRIES, entry

KINEMATIC_BASE = steer_envs.env_ids(kinematic_only=True)
MAZES = ("Umaze", "Medium", "Large")


def test_variant_ids_are_registered_beside_the_base_ids() -> None:
    ids = set(steer_envs.env_ids(variants=True))
    assert set(steer_envs.env_ids()) == {e.id for e in BASE_ENTRIES}  # the default list is unchanged
    for base in KINEMATIC_BASE:
        stem, version = base.rsplit("-", 1)
        assert f"{stem}Dense-{version}" in ids
        assert entry(f"{stem}Dense-{version}").kwargs["reward_type"] == "dense"
    for maze in MAZES:
        for suffix in ("Dense", "Goal", "GoalDense"):
            assert f"steer_envs/Maze2D-{maze}{suffix}-v0" in ids
    assert all(e.variant_of is not None and e.id in gym.registry for e in VARIANT_ENTRIES)
    with pytest.raises(TypeError, match="variants"):
        steer_envs.env_ids(variants="yes")  # type: ignore[arg-type]


def test_dense_ids_carry_the_rl_options_as_registered_and_the_base_ids_do_not() -> None:
    for base in KINEMATIC_BASE:
        stem, version = base.rsplit("-", 1)
        plain, dense = gym.make(base), gym.make(f"{stem}Dense-{version}")
        sensors = len(plain.unwrapped.task.sensors)
        assert (plain.unwrapped.reward_type, plain.unwrapped.observe_sensors, plain.unwrapped.normalize_actions) == (
            "sparse",
            False,
            False,
        )
        assert plain.observation_space.shape == (2,)
        assert plain.action_space.high[0] == pytest.approx(plain.unwrapped.max_speed)  # float32
        assert (dense.unwrapped.reward_type, dense.unwrapped.observe_sensors, dense.unwrapped.normalize_actions) == (
            "dense",
            True,
            True,
        )
        assert dense.observation_space.shape == (2 + sensors,)
        assert dense.action_space.low.tolist() == [-1.0, -1.0] and dense.action_space.high.tolist() == [1.0, 1.0]
        # an explicit option still overrides the registered one
        assert gym.make(f"{stem}Dense-{version}", observe_sensors=False).observation_space.shape == (2,)
    for maze in MAZES:
        for suffix, normalised in (("", False), ("Goal", False), ("Dense", True), ("GoalDense", True)):
            env = gym.make(f"steer_envs/Maze2D-{maze}{suffix}-v0")
            assert env.unwrapped.normalize_actions is normalised, (maze, suffix)
            assert (env.action_space.low.tolist() == [-1.0, -1.0]) is normalised, (maze, suffix)
            assert env.unwrapped.relative_actions is False


@pytest.mark.parametrize("env_id", [*KINEMATIC_BASE, "steer_envs/Maze2D-Umaze-v0"])
def test_bad_options_name_the_argument(env_id: str) -> None:
    with pytest.raises(ValueError, match=r"reward_type.*'dense'.*'shaped'"):
        gym.make(env_id, reward_type="shaped")
    with pytest.raises(TypeError, match="reward_type"):
        gym.make(env_id, reward_type=1)
    for name in ("observe_sensors", "normalize_actions"):
        with pytest.raises(TypeError, match=name):
            gym.make(env_id, **{name: "yes"})


@pytest.mark.parametrize("env_id", KINEMATIC_BASE)
def test_sparse_default_is_unchanged_and_dense_rewards_the_expert(env_id: str) -> None:
    stem, version = env_id.rsplit("-", 1)
    # the dense id's raw velocity actions (it registers [-1, 1] ones), so both envs step exactly alike
    sparse, dense = gym.make(env_id), gym.make(f"{stem}Dense-{version}", normalize_actions=False)
    expert = make_expert(sparse)
    obs, info = sparse.reset(seed=0)
    dense.reset(seed=0)
    expert.reset(obs, info)
    sparse_rewards, dense_rewards = [], []
    terminated = truncated = False
    while not (terminated or truncated):
        action = expert.act(obs, info)
        obs, r, terminated, truncated, info = sparse.step(action)
        dobs, d, dterm, _, dinfo = dense.step(action)
        np.testing.assert_array_equal(obs, dobs[:2])  # then the sensor bits
        assert dterm == terminated and dinfo["mode"] == info["mode"]
        sparse_rewards.append(r)
        dense_rewards.append(d)
    assert info["success"]
    assert sparse_rewards == [0.0] * (len(sparse_rewards) - 1) + [1.0]  # +1 on success, else 0
    num_stages = sparse.unwrapped.model.num_stages
    # the shaping telescopes: every mode advanced earns DENSE_REWARD_SCALE, the distance term at most as much
    total = sum(dense_rewards)
    assert num_stages * DENSE_REWARD_SCALE <= total <= (num_stages + 1) * DENSE_REWARD_SCALE + 1.0
    assert max(dense_rewards) >= DENSE_REWARD_SCALE * 0.9  # a mode advanced in one step


def test_soup_scoop_dense_penalises_a_spill() -> None:
    env = gym.make("steer_envs/SoupScoopDense-v0").unwrapped
    env.reset(seed=0, options={"state": [-3.0, -6.0]})  # in the soup
    _, reward, *_, info = env.step(np.array([10.0, 0.0], dtype=np.float32))  # not yet in pink
    while info["mode_name"] != "c":
        _, reward, *_, info = env.step(np.array([10.0, 0.0], dtype=np.float32))
    # scooped: a mode advanced (+DENSE_REWARD_SCALE, less the jump to the next, farther sub-goal)
    assert reward > 0.25 * DENSE_REWARD_SCALE
    env.perturb(to=[2.05, 0.0])  # at pink's left edge, the soup still on
    _, reward, _, _, info = env.step(np.array([-10.0, 0.0], dtype=np.float32))
    assert info["constraint_violation"] and info["mode_name"] == "a"
    assert reward < -2 * DENSE_REWARD_SCALE  # two modes lost (and the sparse -1), no extra penalty
    assert reward > -3 * DENSE_REWARD_SCALE


@pytest.mark.parametrize("env_id", KINEMATIC_BASE)
def test_dense_reward_is_the_shaping_between_the_states_also_after_a_push_or_a_reset(env_id: str) -> None:
    # a step reuses the previous step's potential: a push or a reset in between must not be missed
    stem, version = env_id.rsplit("-", 1)
    env = gym.make(f"{stem}Dense-{version}").unwrapped
    model, rng = env.model, np.random.default_rng(0)
    env.reset(seed=0)
    for i in range(60):
        if i % 20 == 7:
            env.perturb(delta=rng.normal(size=2))
        if i % 20 == 14:
            env.reset(seed=i, options={"state": rng.uniform(model.low, model.high)})
        pos, memory = env.state[None, :], env._memory.copy()
        _, reward, terminated, _, info = env.step(env.action_space.sample())
        violation = np.array([info["constraint_violation"]])
        expected = env.rewards(
            np.array([info["success"]]),
            violation,
            model.potential(memory, pos),
            model.potential(env._memory, env.state[None, :]),
        )[0]
        assert reward == pytest.approx(expected, abs=1e-9), i
        if terminated:
            env.reset(seed=100 + i)


@pytest.mark.parametrize("env_id", KINEMATIC_BASE)
def test_vector_dense_reward_is_the_shaping_between_the_states_also_after_a_push(env_id: str) -> None:
    # the vector env reuses the previous step's potential too: a push (or an autoreset) must not be missed
    stem, version = env_id.rsplit("-", 1)
    venv = gym.make_vec(f"{stem}Dense-{version}", num_envs=4, vectorization_mode="vector_entry_point")
    inner, rng = venv.unwrapped, np.random.default_rng(0)
    model = inner.model
    venv.reset(seed=0)
    for i in range(60):
        if i % 20 == 7:
            inner.perturb(rng.uniform(model.low, model.high, size=(4, 2)), np.array([True, False, True, False]))
        pos, memory = inner._pos.copy(), inner._memory.copy()
        _, rewards, _, _, infos = venv.step(rng.uniform(-1, 1, size=(4, 2)).astype(np.float32) * inner.env.max_speed)
        expected = inner.env.rewards(
            infos["success"],
            infos["constraint_violation"],
            model.potential(memory, pos),
            model.potential(inner._memory, inner._pos),
        )
        moved = inner._elapsed > 0  # an agent autoreset in this step is not moved (its reward is 0)
        np.testing.assert_allclose(rewards[moved], expected[moved], atol=1e-9, err_msg=str(i))


HEADINGS = np.array([[np.cos(a), np.sin(a)] for a in np.linspace(0, 2 * np.pi, 16, endpoint=False)])
CANDIDATES = np.concatenate([HEADINGS * scale for scale in (1.0, 0.3, 0.1)])


@pytest.mark.parametrize("env_id", KINEMATIC_BASE)
def test_one_step_greedy_on_the_dense_potential_reaches_the_goal(env_id: str) -> None:
    # the shaping must lead somewhere: a controller that takes, each step, the action whose next state has
    # the highest potential (a violation counted as a lost mode) succeeds without a violation. Two traps it
    # found: SoupScoop's scoop sub-goal at the zone's edge (spills on the way up), Cooking aiming a
    # reloaded, already delivered food at the pot (a local optimum at the pot's edge) and PolygonNav's
    # straight-line distance to polygon 1 through a later polygon (PolygonNav-5Mode, seed 1).
    stem, version = env_id.rsplit("-", 1)
    env = gym.make(f"{stem}Dense-{version}", normalize_actions=True).unwrapped
    model, n = env.model, len(CANDIDATES)
    for seed in (0, 1):
        env.reset(seed=seed)
        total, violations, info = 0.0, 0, {"success": False}
        for _ in range(2000):
            pos = np.repeat(np.reshape(env.state, (1, 2)), n, axis=0)
            moved = np.clip(pos + env.dt * np.stack([env.velocity_of(a) for a in CANDIDATES]), model.low, model.high)
            memory, violation = model.advance(np.repeat(env._memory, n, axis=0), pos, moved)
            action = CANDIDATES[int(np.argmax(model.potential(memory, moved) - violation))]
            _, reward, terminated, truncated, info = env.step(action.astype(np.float32))
            total, violations = total + reward, violations + int(info["constraint_violation"])
            if terminated or truncated:
                break
        assert violations == 0, (seed, info["mode_name"], env.state)
        assert info["success"], (seed, info["mode_name"], env.state)
        assert total > model.num_stages * DENSE_REWARD_SCALE


@pytest.mark.parametrize("env_id", KINEMATIC_BASE)
def test_observed_sensors_are_the_info_sensors(env_id: str) -> None:
    env = gym.make(env_id, observe_sensors=True)
    task = env.unwrapped.task
    assert env.observation_space.shape == (2 + len(task.sensors),)
    obs, info = env.reset(seed=1)
    for _ in range(30):
        assert obs in env.observation_space
        np.testing.assert_array_equal(obs[2:], [float(info["sensors"][ap]) for ap in task.sensors])
        np.testing.assert_allclose(obs[:2], env.unwrapped.state, atol=1e-5)
        obs, _, terminated, truncated, info = env.step(env.action_space.sample())
        if terminated or truncated:
            break


def test_soup_on_the_spoon_is_observable() -> None:
    env = gym.make("steer_envs/SoupScoop-v0", observe_sensors=True)
    env.reset(seed=0, options={"state": [1.9, -6.0]})
    obs, *_ = env.step(np.array([10.0, 0.0], dtype=np.float32))  # yellow -> pink: scooped
    s = env.unwrapped.task.sensors.index("s")
    assert obs[2 + s] == 1.0
    plain = gym.make("steer_envs/SoupScoop-v0")
    plain.reset(seed=0, options={"state": [1.9, -6.0]})
    assert plain.step(np.array([10.0, 0.0], dtype=np.float32))[0].shape == (2,)


@pytest.mark.parametrize("env_id", KINEMATIC_BASE)
def test_normalised_actions_scale_by_max_speed(env_id: str) -> None:
    raw, norm = gym.make(env_id), gym.make(env_id, normalize_actions=True)
    max_speed = raw.unwrapped.max_speed
    assert norm.action_space.low.tolist() == [-1.0, -1.0] and norm.action_space.high.tolist() == [1.0, 1.0]
    raw.reset(seed=2)
    norm.reset(seed=2)
    rng = np.random.default_rng(0)
    for _ in range(10):
        a = rng.uniform(-1, 1, size=2).astype(np.float32)
        o1, r1, t1, _, _ = raw.step(a * np.float32(max_speed))
        o2, r2, t2, _, _ = norm.step(a)
        np.testing.assert_allclose(o1, o2, atol=1e-5)
        assert (r1, t1) == (r2, t2)
        if t1:
            break


@pytest.mark.parametrize("env_id", KINEMATIC_BASE)
def test_vector_env_matches_single_envs_with_every_option(env_id: str) -> None:
    kwargs = {"reward_type": "dense", "observe_sensors": True, "normalize_actions": True}
    num = 3
    venv = gym.make_vec(env_id, num_envs=num, vectorization_mode="vector_entry_point", **kwargs)
    vobs, _ = venv.reset(seed=4)
    assert vobs.shape == (num, venv.single_observation_space.shape[0])
    singles = [gym.make(env_id, **kwargs) for _ in range(num)]
    for k, env in enumerate(singles):
        sobs, _ = env.reset(options={"state": venv.unwrapped._pos[k]})
        np.testing.assert_allclose(vobs[k], sobs, atol=1e-6)
    rng = np.random.default_rng(1)
    done = np.zeros(num, dtype=bool)
    for _ in range(25):
        actions = rng.uniform(-1, 1, size=(num, 2)).astype(np.float32)
        for k, terminated, _, _ in step_singles_like_vector(venv, singles, actions, done):
            done[k] = terminated
    venv.close()


# ------------------------------------------------------------------ Maze2D
def test_maze2d_goal_is_in_info_either_way() -> None:
    env = gym.make("steer_envs/Maze2D-Umaze-v0")
    obs, info = env.reset(seed=0)
    assert obs.shape == (2,)
    np.testing.assert_array_equal(info["goal"], env.unwrapped.goal_xy)
    *_, info = env.step(env.action_space.sample())
    np.testing.assert_array_equal(info["goal"], env.unwrapped.goal_xy)
    free = gym.make("steer_envs/Maze2D-Umaze-v0", sample_goal=False)
    assert free.reset(seed=0)[1]["goal"] is None


def test_maze2d_goal_conditioned_observation_and_reward() -> None:
    env = gym.make("steer_envs/Maze2D-UmazeGoal-v0")
    base = env.unwrapped
    assert isinstance(base, Maze2DGoalEnv)
    assert set(env.observation_space.spaces) == {"observation", "achieved_goal", "desired_goal"}
    obs, info = env.reset(seed=3)
    np.testing.assert_allclose(obs["desired_goal"], info["goal"])
    np.testing.assert_allclose(obs["achieved_goal"], base.state, atol=1e-6)
    for _ in range(20):
        obs, reward, terminated, _, info = env.step(env.action_space.sample())
        assert reward == base.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)
        if terminated:
            break
    # vectorised over any leading axes
    achieved = np.array([[[1.0, 1.0], [3.0, 3.0]]], dtype=np.float32)
    desired = np.array([[[1.3, 0.8], [1.0, 1.0]]], dtype=np.float32)
    np.testing.assert_array_equal(base.compute_reward(achieved, desired, None), [[1.0, 0.0]])
    with pytest.raises(ValueError, match="same shape"):
        base.compute_reward(achieved[0], desired[0, :1], None)
    # the option makes the same class; a goal is compulsory
    assert isinstance(Maze2DEnv("umaze", goal_conditioned=True), Maze2DGoalEnv)
    assert not isinstance(Maze2DEnv("umaze"), Maze2DGoalEnv)
    assert not hasattr(Maze2DEnv("umaze"), "compute_reward")  # stable-baselines3 takes it for a goal env
    with pytest.raises(ValueError, match="sample_goal"):
        Maze2DEnv("umaze", goal_conditioned=True, sample_goal=False)
    with pytest.raises(ValueError, match="goal_cell"):
        env.reset(options={"goal_cell": None})


def test_maze2d_dense_reward_is_minus_the_path_distance() -> None:
    env = gym.make("steer_envs/Maze2D-UmazeGoalDense-v0").unwrapped
    grid = env.grid
    # U maze: (1, 1) to (3, 1) goes around the wall row through (1, 3) and (3, 3): 6 cell steps, not 2
    d = grid.path_distance(np.array([[1.0, 1.0], [3.0, 1.0], [1.0, 1.2]]), np.array([[3.0, 1.0]] * 3))
    assert d[0] == pytest.approx(6.0) and d[1] == 0.0 and d[2] < d[0]
    r = env.compute_reward(np.array([[1.0, 1.0], [3.0, 1.0]]), np.array([[3.0, 1.0], [3.0, 1.0]]), None)
    np.testing.assert_allclose(r, [-6.0 / env.extent, 0.0])
    plain = gym.make("steer_envs/Maze2D-UmazeDense-v0")
    plain.reset(seed=0, options={"state": [1.0, 1.0], "goal_cell": (3, 1)})
    _, reward, *_ = plain.step(np.array([1.0, 2.0], dtype=np.float32))
    assert -6.0 / env.extent <= reward < 0.0


def test_maze2d_dense_ids_observe_velocity_and_the_goal_their_reward_measures() -> None:
    env = gym.make("steer_envs/Maze2D-UmazeDense-v0")
    assert env.observation_space.shape == (6,)  # xy, velocity (as PointMaze), goal xy
    for seed in (0, 1, 2):
        obs, info = env.reset(seed=seed)
        np.testing.assert_allclose(obs[4:], info["goal"])
        assert env.observation_space.contains(obs)
    obs, *_, info = env.step(env.action_space.sample())
    np.testing.assert_allclose(obs[4:], info["goal"])
    np.testing.assert_allclose(obs[2:4], env.unwrapped.velocity, atol=1e-5)
    for goal_id in ("steer_envs/Maze2D-UmazeGoal-v0", "steer_envs/Maze2D-UmazeGoalDense-v0"):
        assert gym.make(goal_id).observation_space["observation"].shape == (4,)
    assert gym.make("steer_envs/Maze2D-Umaze-v0").observation_space.shape == (2,)  # the ITPS id is unchanged
    both = gym.make("steer_envs/Maze2D-Umaze-v0", observe_sensors=True, observe_goal=True, observe_velocity=True)
    obs, info = both.reset(seed=0)
    assert obs.shape == (8,) and both.observation_space.contains(obs)
    np.testing.assert_allclose(obs[6:], info["goal"])
    free = Maze2DEnv("umaze", sample_goal=False, observe_goal=True)
    obs, _ = free.reset(seed=0)
    np.testing.assert_allclose(obs[2:], obs[:2])  # no goal: the agent's own xy
    with pytest.raises(ValueError, match="observe_goal"):
        Maze2DEnv("umaze", goal_conditioned=True, observe_goal=True)
    with pytest.raises(TypeError, match="observe_goal"):
        Maze2DEnv("umaze", observe_goal="yes")


def test_maze2d_dense_ids_act_at_half_the_itps_rate_in_the_same_time() -> None:
    from steer_envs.envs.registry import MAZE_DENSE_FRAME_SKIP

    for maze in MAZES:
        base = gym.make(f"steer_envs/Maze2D-{maze}-v0")
        assert base.unwrapped.frame_skip == 4  # the ITPS data rate
        seconds = base.spec.max_episode_steps * base.unwrapped.dt
        for suffix, skip in (("Dense", MAZE_DENSE_FRAME_SKIP), ("GoalDense", MAZE_DENSE_FRAME_SKIP), ("Goal", 4)):
            env = gym.make(f"steer_envs/Maze2D-{maze}{suffix}-v0")
            assert env.unwrapped.frame_skip == skip
            assert env.spec.max_episode_steps * env.unwrapped.dt == pytest.approx(seconds)


def test_maze2d_normalised_actions_map_onto_the_grid() -> None:
    env = gym.make("steer_envs/Maze2D-Umaze-v0", normalize_actions=True, observe_sensors=True)
    assert env.action_space.low.tolist() == [-1.0, -1.0]
    assert env.observation_space.shape == (4,)
    ref = gym.make("steer_envs/Maze2D-Umaze-v0")
    obs, _ = env.reset(seed=0, options={"state": [1.0, 1.0], "goal_cell": (3, 1)})
    ref.reset(seed=0, options={"state": [1.0, 1.0], "goal_cell": (3, 1)})
    high = ref.unwrapped.grid.high
    for target in ([1.0, 3.0], [1.0, 1.0]):
        a = (2.0 * np.array(target) / high - 1.0).astype(np.float32)
        obs, *_ = env.step(a)
        ref_obs, *_ = ref.step(np.array(target, dtype=np.float32))
        np.testing.assert_allclose(obs[:2], ref_obs, atol=1e-5)


def test_maze2d_relative_actions_are_offsets_from_the_agent() -> None:
    env = gym.make("steer_envs/Maze2D-UmazeDense-v0", relative_actions=True)
    assert env.action_space.low.tolist() == [-1.0, -1.0] and env.action_space.high.tolist() == [1.0, 1.0]
    ref = gym.make("steer_envs/Maze2D-UmazeDense-v0", normalize_actions=False)  # absolute waypoints
    options = {"state": [1.0, 1.0], "goal_cell": (3, 1)}
    obs, _ = env.reset(seed=0, options=options)
    ref_obs, _ = ref.reset(seed=0, options=options)
    for offset in ([0.0, 0.7], [0.3, -1.0], [5.0, 0.0]):  # the last is clipped to one cell
        waypoint = obs[:2] + np.clip(offset, -1.0, 1.0)
        obs, reward, *_ = env.step(np.array(offset, dtype=np.float32))
        ref_obs, ref_reward, *_ = ref.step(waypoint.astype(np.float32))
        np.testing.assert_allclose(obs, ref_obs, atol=1e-5)
        assert reward == pytest.approx(ref_reward, abs=1e-6)
    with pytest.raises(TypeError, match="relative_actions"):
        Maze2DEnv("umaze", relative_actions=1)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_sb3_her_sac_learns_a_few_hundred_steps_on_goal_conditioned_maze() -> None:
    from stable_baselines3 import SAC, HerReplayBuffer

    env = gym.make("steer_envs/Maze2D-UmazeGoal-v0", normalize_actions=True)
    model = SAC(
        "MultiInputPolicy",
        env,
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
        learning_starts=100,
        batch_size=32,
        policy_kwargs={"net_arch": [32, 32]},
        seed=0,
        device="cpu",
    )
    model.learn(total_timesteps=300)
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert action in env.action_space


@pytest.mark.parametrize(
    ("env_id", "options"),
    [
        ("steer_envs/PolygonNav-3ModeDense-v0", {}),
        ("steer_envs/SoupScoop-v0", {"normalize_actions": True}),
        ("steer_envs/Maze2D-UmazeDense-v0", {}),
        ("steer_envs/Maze2D-UmazeDense-v0", {"relative_actions": True}),
    ],
)
def test_the_expert_acts_in_the_ids_action_convention(env_id: str, options: dict[str, bool]) -> None:
    env = gym.make(env_id, **options)
    expert = make_expert(env)
    assert isinstance(expert, RLConventionExpert)
    expert.gain = 3.0  # a setting reaches the wrapped expert (read back through it)
    assert expert.inner.gain == 3.0 and expert.gain == 3.0
    obs, info = env.reset(seed=1)
    expert.reset(obs, info)
    terminated = truncated = False
    while not (terminated or truncated):
        action = expert.act(obs, info)
        assert action.dtype == np.float32 and np.abs(action).max() <= 1.0
        obs, _, terminated, truncated, info = env.step(action)
    assert info["success"] and terminated
    assert not isinstance(make_expert(gym.make("steer_envs/SoupScoop-v0")), RLConventionExpert)  # the thesis's ids
