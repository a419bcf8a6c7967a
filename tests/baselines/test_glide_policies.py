"""GLiDE mode-based policies on PolygonNav, their evaluation, and the grounding scores."""

from __future__ import annotations

import itertools

import gymnasium as gym
import numpy as np
import pytest

import steer_envs  # noqa: F401
from steer_envs.baselines.glide import (
    GlideBC,
    GlideBCConfig,
    GlideBCPolicy,
    GlidePlanningPolicy,
    GlideSetup,
    LearnedModeMap,
    PerturbationSchedule,
    PlannerConfig,
    evaluate_polygon_policy,
    grounding_scores,
    label_demonstrations,
    learn_grounding,
    mode_entry_points,
    polygon_demonstrations,
    potential_field,
    rrt,
    train_bc,
)

ENV_ID = "steer_envs/PolygonNav-4Mode-v0"


class _Oracle:
    """The ground-truth modes as a 'classifier' (isolates the policies from learning)."""

    def __init__(self, model: object) -> None:
        self.model = model

    def predict(self, states: np.ndarray) -> np.ndarray:
        return self.model.mode_of(np.asarray(states, dtype=np.float64))  # type: ignore[attr-defined]


@pytest.fixture(scope="module")
def setting() -> tuple[object, list]:
    env = gym.make(ENV_ID, layout_seed=0)
    model = env.unwrapped.model
    env.close()
    return model, polygon_demonstrations(ENV_ID, 0, 5, 0)


def test_bc_fits_a_velocity_field() -> None:
    rng = np.random.default_rng(0)
    states = rng.uniform(-1, 1, (400, 2))
    actions = -0.1 * states / np.maximum(np.linalg.norm(states, axis=1, keepdims=True), 1.0)
    policy = train_bc(states, actions, max_speed=0.1, seed=0, config=GlideBCConfig(steps=600))
    assert policy.config.output_scale == 0.1 and policy.config.output == "clip"
    pred = policy.act(states)
    assert np.mean(np.linalg.norm(pred - actions, axis=1)) < 0.02
    assert np.all(np.linalg.norm(policy.act(rng.uniform(-9, 9, (50, 2))), axis=1) <= 0.1 + 1e-9)
    with pytest.raises(ValueError, match="states and actions"):
        train_bc(states, actions[:-1], max_speed=0.1)
    with pytest.raises(ValueError, match="max_speed"):
        train_bc(states, actions, max_speed=0.0)


def test_segmentation_and_entry_points(setting: tuple) -> None:
    model, demos = setting
    modes = label_demonstrations(_Oracle(model), [d.states for d in demos], 4)
    agree = np.mean(np.concatenate([m == d.modes for d, m in zip(demos, modes, strict=True)]))
    assert agree > 0.99  # float32 observations vs float64 env state at the boundaries
    entries = mode_entry_points([d.states for d in demos], modes, 4)
    assert np.all(np.isnan(entries[0]))  # the demos start in free space: never *entered*
    np.testing.assert_array_equal(model.mode_of(entries[1:]), [1, 2, 3])
    with pytest.raises(ValueError, match="outside"):
        label_demonstrations(_Oracle(model), [d.states for d in demos], 2)


def test_potential_field_pulls_to_the_goal_and_pushes_off_forbidden_modes(setting: tuple) -> None:
    model, _ = setting
    grid_map = LearnedModeMap(_Oracle(model), model.low, model.high, 0.1)
    x = np.array([0.0, 0.0])
    far = potential_field(grid_map, x, np.array([1.0, 0.0]), frozenset({0, 1, 2, 3}), k_att=2.0, k_rep=10.0, d0=0.8)
    np.testing.assert_allclose(far, [2.0, 0.0])  # nothing forbidden: attraction only


def test_rrt_goes_around_an_obstacle() -> None:
    def free(p: np.ndarray) -> bool:
        return not (abs(p[0]) < 1 and p[1] > -3)  # a wall at x in (-1, 1) open below y = -3

    def seg(a: np.ndarray, b: np.ndarray) -> bool:
        return all(free(a + t * (b - a)) for t in np.linspace(0, 1, 60))

    path = rrt(
        np.array([-3.0, 2.0]), np.array([3.0, 2.0]), free, seg, np.full(2, -5.0), np.full(2, 5.0),
        np.random.default_rng(0), iterations=3000, step=0.5,
    )  # fmt: skip
    assert path is not None
    np.testing.assert_array_equal(path[-1], [3.0, 2.0])
    assert all(seg(a, b) for a, b in itertools.pairwise(path))
    assert min(p[1] for p in path) < -3  # it went under the wall


def test_learned_mode_map_reads_the_classifier_on_a_grid(setting: tuple) -> None:
    model, _ = setting
    grid_map = LearnedModeMap(_Oracle(model), model.low, model.high, 0.1)
    pts = np.random.default_rng(0).uniform(-8, 8, (500, 2))
    agree = np.mean(grid_map.mode(pts) == model.mode_of(pts))
    assert agree > 0.97  # up to the grid resolution at the boundaries
    dist, _, _ = grid_map.distance_field(frozenset({0}))
    assert dist.shape == grid_map.shape and dist.max() > 1.0


def test_waypoints_lie_in_their_learned_modes(setting: tuple) -> None:
    """A waypoint outside its mode would leave the agent standing in the previous mode."""
    model, demos = setting
    grid_map = LearnedModeMap(_Oracle(model), model.low, model.high, 0.05)
    centre = np.asarray(model.polygons[1].centroid.coords[0])
    far = centre + np.array([20.0, 0.0])  # outside the workspace, in no polygon
    moved = grid_map.nearest_in(far, 2)
    assert grid_map.mode(moved[None])[0] == 2
    np.testing.assert_array_equal(grid_map.nearest_in(centre, 2), centre)  # already inside: unchanged
    shifted = _LateFinalMode(model, 1.5)  # entries into the final mode spread along a bent learned boundary
    policy = GlidePlanningPolicy(
        shifted, [d.states for d in demos], 4, low=model.low, high=model.high, max_speed=0.1, seed=0
    )
    assert [int(policy.map.mode(policy.waypoints[k][None])[0]) for k in (1, 2, 3)] == [1, 2, 3]


def test_planning_on_the_true_modes_solves_the_task_and_resists_pushes(setting: tuple) -> None:
    model, demos = setting
    policy = GlidePlanningPolicy(
        _Oracle(model), [d.states for d in demos], 4, low=model.low, high=model.high, max_speed=0.1, seed=0
    )
    clean = evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=40, perturbed=False, seed=1)
    assert clean["success_rate"] >= 0.95 and clean["violation_rate"] == 0.0
    pushed = evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=40, perturbed=True, seed=1)
    assert pushed["perturbed_episodes"] > 10
    assert pushed["perturbations"] <= 3 * 40
    assert pushed["violation_rate"] == 0.0  # pushes are not the agent's transitions; the planner makes none
    assert pushed["success_rate"] >= 0.8
    assert policy.stats["costmap"] > 0  # the default free-space planner


def test_the_thesis_rrt_planner_is_still_available(setting: tuple) -> None:
    model, demos = setting
    config = PlannerConfig(free_space_planner="rrt")
    policy = GlidePlanningPolicy(
        _Oracle(model), [d.states for d in demos], 4, low=model.low, high=model.high, max_speed=0.1, config=config
    )
    clean = evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=20, perturbed=False, seed=1)
    assert clean["success_rate"] >= 0.9
    assert policy.stats["costmap"] == 0 and policy.stats["rrt"] > 0


class _LateFinalMode(_Oracle):
    """True modes, except the final mode also claims the previous polygon up to ``reach`` from its edge."""

    def __init__(self, model: object, reach: float) -> None:
        super().__init__(model)
        self.reach = reach

    def predict(self, states: np.ndarray) -> np.ndarray:
        import shapely

        x = np.asarray(states, dtype=np.float64)
        modes = super().predict(x)
        last = self.model.num_modes - 1  # type: ignore[attr-defined]
        near = shapely.distance(shapely.points(x), self.model.polygons[-1]) <= self.reach  # type: ignore[attr-defined]
        return np.where((modes == last - 1) & near, last, modes)


def test_planning_walks_into_the_final_mode_past_a_learned_boundary_that_is_short(setting: tuple) -> None:
    """A classifier whose final mode starts 0.5 early: the agent must not stop on the learned boundary."""
    model, demos = setting
    clf = _LateFinalMode(model, 0.5)
    policy = GlidePlanningPolicy(
        clf, [d.states for d in demos], 4, low=model.low, high=model.high, max_speed=0.1, seed=0
    )
    assert model.mode_of(policy.goal[None])[0] == 3  # the demos' mean end lies in the last (convex) polygon
    res = evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=30, perturbed=False, seed=2)
    assert res["success_rate"] >= 0.95, res


def test_paths_keep_clear_of_forbidden_learned_modes(setting: tuple) -> None:
    import shapely

    model, _ = setting
    grid_map = LearnedModeMap(_Oracle(model), model.low, model.high, 0.05)
    allowed = frozenset({0, 1})
    poly = model.polygons[1]  # mode 2: forbidden from free space
    inner = poly.representative_point()
    assert grid_map.clearance(np.array([[inner.x, inner.y]]), allowed)[0] == 0.0
    # a segment along one of its outer edges, 0.15 outside: inside the allowed modes, but not 0.3 clear
    coords = np.asarray(poly.exterior.coords)
    for e0, e1 in itertools.pairwise(coords):
        mid, d = (e0 + e1) / 2, (e1 - e0) / np.linalg.norm(e1 - e0)
        normal = np.array([-d[1], d[0]])
        normal = normal if not poly.contains(shapely.Point(*(mid + 0.05 * normal))) else -normal
        a, b = mid + 0.15 * normal - 0.2 * d, mid + 0.15 * normal + 0.2 * d
        if (
            set(model.mode_of(np.linspace(a, b, 50)).tolist()) == {0}
            and model.mode_of((mid + 0.5 * normal)[None])[0] == 0
        ):
            break
    else:
        pytest.fail("no free outer edge on polygon 2 of this layout")
    assert grid_map.segment_ok(a, b, allowed, 0.02)
    assert not grid_map.segment_ok(a, b, allowed, 0.02, min_clearance=0.3)
    assert grid_map.segment_ok(a, b, allowed, 0.02, min_clearance=0.05)


def test_glide_bc_runs_one_policy_per_mode(setting: tuple) -> None:
    model, demos = setting
    policy = GlideBCPolicy(
        _Oracle(model),
        [d.states for d in demos],
        [d.actions for d in demos],
        4,
        max_speed=0.1,
        seed=0,
        config=GlideBCConfig(steps=200),
    )
    assert isinstance(policy, GlideBC) and sum(p is not None for p in policy.policies) >= 3
    assert np.all(np.isfinite(policy.attractors[:3]))
    v = policy.act(np.random.default_rng(0).uniform(-8, 8, (30, 2)))
    assert v.shape == (30, 2) and np.all(np.linalg.norm(v, axis=1) <= 0.1 + 1e-9)


def test_perturbation_schedule_validates() -> None:
    with pytest.raises(ValueError, match="probability"):
        PerturbationSchedule(probability=2.0)


def test_grounding_scores_for_cheap_variants() -> None:
    env_id = "steer_envs/PolygonNav-3Mode-v0"
    km = learn_grounding(env_id, 0, "kmeans", 0, setup=GlideSetup(n_demos=4))
    scores, labels = grounding_scores(env_id, 0, km.predictor, resolution=50)
    assert 0 <= scores["overlap"] <= 1 and len(scores["iou"]) == 3 and labels.shape == (50 * 50,)
    assert scores["overlap"] < scores["all_free_overlap"]  # the thesis's point: clustering is not grounding
    with pytest.raises(ValueError, match="variant"):
        learn_grounding(env_id, 0, "oracle", 0)
    with pytest.raises(ValueError, match="env_id"):
        learn_grounding("steer_envs/PolygonNav-9Mode-v0", 0, "kmeans", 0)
    with pytest.raises(ValueError, match="env_id"):
        grounding_scores("steer_envs/PolygonNav-9Mode-v0", 0, km.predictor)


def test_demos_into_the_goal_change_the_data_cache_key() -> None:
    """GLiDE's demos go on to the goal polygon's centroid; the data and classifier keys must say so."""
    from dataclasses import replace

    setup = GlideSetup()
    short = replace(setup, demo_goal_steps=0)
    assert setup.demo_goal_steps > 0
    assert setup.key(fields=GlideSetup.DATA_FIELDS) != short.key(fields=GlideSetup.DATA_FIELDS)
    assert setup.key(fields=GlideSetup.CLASSIFIER_FIELDS) != short.key(fields=GlideSetup.CLASSIFIER_FIELDS)
    plain = polygon_demonstrations(ENV_ID, 0, 2, 0)
    longer = polygon_demonstrations(ENV_ID, 0, 2, 0, goal_steps=setup.demo_goal_steps)
    for p, q in zip(plain, longer, strict=True):
        assert len(q) > len(p) and np.all(q.modes[len(p) - 1 :] == 3)
    with pytest.raises(ValueError, match="goal_steps"):
        polygon_demonstrations(ENV_ID, 0, 2, 0, goal_steps=-1)


class _DiscWorld:
    """Mode 2 is the unit disc (forbidden from free space), mode 1 the half-plane x > 4, free space elsewhere;
    with ``wall`` a mode-2 wall at 2 < x < 3 cuts the goal off."""

    def __init__(self, wall: bool = False) -> None:
        self.wall = wall

    def predict(self, states: np.ndarray) -> np.ndarray:
        x = np.asarray(states, dtype=np.float64)
        modes = np.where(x[:, 0] > 4, 1, 0)
        blocked = np.linalg.norm(x, axis=1) < 1
        if self.wall:
            blocked |= (x[:, 0] > 2) & (x[:, 0] < 3)
        return np.where(blocked, 2, modes)


def _polyline(start: np.ndarray, path: list[np.ndarray], spacing: float = 0.01) -> np.ndarray:
    pts = [start, *path]
    pieces = []
    for a, b in itertools.pairwise(pts):
        t = np.linspace(0, 1, max(2, int(np.linalg.norm(b - a) / spacing)))[:, None]
        pieces.append(a + t * (b - a))
    return np.concatenate(pieces)


def test_costmap_path_keeps_its_distance_where_it_is_cheap_to() -> None:
    grid_map = LearnedModeMap(_DiscWorld(), np.full(2, -6.0), np.full(2, 6.0), 0.05)
    allowed, start, goal = frozenset({0, 1}), np.array([-4.0, 0.1]), np.array([4.5, 0.0])
    shortest = grid_map.shortest_path(start, goal, allowed, weight=0.0, radius=2.0, spacing=0.02)
    wary = grid_map.shortest_path(start, goal, allowed, weight=10.0, radius=2.0, spacing=0.02)
    assert shortest is not None and wary is not None
    for path in (shortest, wary):
        np.testing.assert_array_equal(path[-1], goal)
        pts = _polyline(start, path)
        assert np.all(np.isin(grid_map.mode(pts), [0, 1]))  # never enters the forbidden disc
    gap = {name: np.linalg.norm(_polyline(start, p), axis=1).min() - 1 for name, p in (("s", shortest), ("w", wary))}
    assert gap["s"] < 0.2  # the plain shortest path grazes the disc
    assert gap["w"] > 0.8  # the exposure cost keeps the path away from it
    length = {
        n: np.linalg.norm(np.diff(_polyline(start, p), axis=0), axis=1).sum() for n, p in (("s", shortest), ("w", wary))
    }
    assert length["s"] < 8.5 * 1.05 + 0.3 and length["w"] < 1.3 * length["s"]  # string-pulled, not a grid staircase


def test_costmap_returns_none_when_the_goal_is_cut_off_and_checks_its_settings() -> None:
    grid_map = LearnedModeMap(_DiscWorld(wall=True), np.full(2, -6.0), np.full(2, 6.0), 0.1)
    start, goal = np.array([-4.0, 0.0]), np.array([4.5, 0.0])
    assert grid_map.shortest_path(start, goal, frozenset({0, 1}), 10.0, 2.0, 0.02) is None
    with pytest.raises(ValueError, match="free_space_planner"):
        PlannerConfig(free_space_planner="astar")
    with pytest.raises(ValueError, match="exposure_radius"):
        PlannerConfig(exposure_radius=-1.0)


def test_evaluation_episode_length_is_configurable(setting: tuple) -> None:
    """``max_steps`` caps the episodes: too short to reach the goal, every episode times out."""
    model, demos = setting
    policy = GlidePlanningPolicy(
        _Oracle(model), [d.states for d in demos], 4, low=model.low, high=model.high, max_speed=0.1, seed=0
    )
    short = evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=10, perturbed=False, seed=1, max_steps=5)
    assert short["success_rate"] == 0.0 and short["timeout_rate"] == 1.0 and short["mean_steps"] == 5.0
    full = evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=10, perturbed=False, seed=1, max_steps=1000)
    assert full["timeout_rate"] == 0.0 and full["success_rate"] + full["violation_rate"] == 1.0
    with pytest.raises(ValueError, match="max_steps"):
        evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=2, perturbed=False, seed=1, max_steps=0)


def test_episodes_can_start_inside_the_first_polygon(setting: tuple) -> None:
    """``start="first_mode"``: the public env's reset; the chain from there is one polygon shorter."""
    model, demos = setting
    policy = GlidePlanningPolicy(
        _Oracle(model), [d.states for d in demos], 4, low=model.low, high=model.high, max_speed=0.1, seed=0
    )
    free = evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=20, perturbed=False, seed=1)
    inside = evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=20, perturbed=False, seed=1, start="first_mode")
    assert inside["success_rate"] >= 0.95 and inside["mean_steps"] < free["mean_steps"]
    pushed = evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=20, perturbed=True, seed=1, start="first_mode")
    assert pushed["perturbed_episodes"] > 0 and pushed["violation_rate"] == 0.0
    with pytest.raises(ValueError, match="start"):
        evaluate_polygon_policy(policy, ENV_ID, 0, n_rollouts=2, perturbed=False, seed=1, start="goal")


def test_planner_settings_that_can_never_work_are_refused() -> None:
    from steer_envs.baselines.glide.planners import MAX_GRID_CELLS

    with pytest.raises(TypeError, match="rrt_iterations"):
        PlannerConfig(rrt_iterations=1000.0)  # type: ignore[arg-type]  # used to fail deep in numpy
    with pytest.raises(ValueError, match="rrt_iterations"):
        PlannerConfig(rrt_iterations=10**12)  # an RRT that would never return
    with pytest.raises(TypeError, match="grid_resolution"):
        PlannerConfig(grid_resolution="0.05")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="k_rep"):
        PlannerConfig(k_rep=float("nan"))
    with pytest.raises(ValueError, match=f"more than {MAX_GRID_CELLS}"):
        LearnedModeMap(_DiscWorld(wall=False), np.full(2, -6.0), np.full(2, 6.0), 1e-6)
    with pytest.raises(TypeError, match="classifier"):
        LearnedModeMap(object(), np.full(2, -6.0), np.full(2, 6.0), 0.1)  # type: ignore[arg-type]
    free = lambda p: True  # noqa: E731
    with pytest.raises(TypeError, match="iterations"):
        rrt(np.zeros(2), np.ones(2), free, lambda a, b: False, -np.ones(2), np.ones(2), np.random.default_rng(0),
            iterations=5.5)  # type: ignore[arg-type]  # fmt: skip
    with pytest.raises(ValueError, match="goal"):
        rrt(np.zeros(2), np.ones(3), free, lambda a, b: False, -np.ones(2), np.ones(2), np.random.default_rng(0))
    with pytest.raises(TypeError, match="max_speed"):
        train_bc(np.zeros((4, 2)), np.zeros((4, 2)), max_speed="0.1")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="states"):
        train_bc([["0", "0"]] * 4, np.zeros((4, 2)), max_speed=0.1)
