"""LTL-DS: per-mode DS fitting from segmented demos, automaton-driven acting, cuts from invariance failures."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.baselines.lpv_ds.cuts import Cut, CutSet
from steer_envs.baselines.lpv_ds.lpvds import LPVDS
from steer_envs.baselines.lpv_ds.ltl_ds import LTLDSPolicy, ModeDynamics, fit_mode_dynamics
from steer_envs.baselines.lpv_ds.modulation import hold_beyond_cuts
from steer_envs.data.demos import collect_demonstrations
from steer_envs.data.segmentation import segment_demonstrations
from steer_envs.envs.soup_scoop import GREEN, PINK, YELLOW
from steer_envs.ltl.specs import for_env

ENV_ID = "steer_envs/SoupScoop-v0"


@pytest.fixture(scope="module")
def env():
    e = gym.make(ENV_ID, max_episode_steps=3000)
    yield e
    e.close()


@pytest.fixture(scope="module")
def expert_demos():
    return collect_demonstrations(ENV_ID, 2, seed=0)


@pytest.fixture(scope="module")
def dynamics(env, expert_demos):
    return fit_mode_dynamics(expert_demos, env.unwrapped.task, random_state=0)


def _linear(attractor, a_matrix):
    att, a = np.asarray(attractor, dtype=float), np.asarray(a_matrix, dtype=float)
    return lambda x: (np.asarray(x, dtype=float) - att) @ a.T


def _spiral_dynamics(w: float) -> dict[str, ModeDynamics]:
    """Certified linear DSs per mode (A + A^T = -2 I); mode c spirals with rate ``w`` toward green."""
    atts = {"a": [-3.0, -4.3], "b": [2.3, -5.0], "c": [4.0, 6.3]}
    mats = {"a": -np.eye(2), "b": -np.eye(2), "c": [[-1.0, -w], [w, -1.0]]}
    empty = np.zeros((0, 2))
    dyn = {m: ModeDynamics(m, _linear(atts[m], mats[m]), np.asarray(atts[m]), m, empty, empty) for m in "abc"}
    dyn["d"] = ModeDynamics("d", dyn["c"].policy, dyn["c"].attractor, "c", empty, empty)
    return dyn


def _episode(env, policy, seed=0):
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info)
    while True:
        obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
        if terminated or truncated:
            policy.observe(obs, info)
            return info


def test_fit_segments_demos_into_stable_mode_dynamics(env, expert_demos, dynamics) -> None:
    model = env.unwrapped.model
    assert set(dynamics) == {"a", "b", "c", "d"}
    # guard attractors lie just inside the next mode's region: the flow crosses the guard in finite time
    regions = {m: int(model.regions(dynamics[m].attractor[None])[0]) for m in "abc"}
    assert regions == {"a": YELLOW, "b": PINK, "c": GREEN}
    for m in "abc":
        assert dynamics[m].source == m
        assert isinstance(dynamics[m].policy, LPVDS) and dynamics[m].policy.check_stability().stable
        assert len(dynamics[m].entry_states) == len(expert_demos) == len(dynamics[m].last_states)
    # the goal mode is one final state per demo: it reuses the transport DS (public TLI code)
    assert dynamics["d"].source == "c" and dynamics["d"].policy is dynamics["c"].policy
    # the thesis rule: the mean of the last in-mode states (segmentation's attractor)
    last = fit_mode_dynamics(expert_demos, env.unwrapped.task, attractor_rule="last")
    seg = segment_demonstrations([(d.states[:-1], d.modes[:-1]) for d in expert_demos], task=env.unwrapped.task)
    np.testing.assert_allclose(last["b"].attractor, seg["b"].attractor)
    pushed = fit_mode_dynamics(expert_demos, env.unwrapped.task, overshoot=0.5)
    assert np.linalg.norm(pushed["a"].attractor - dynamics["a"].attractor) == pytest.approx(0.5)
    assert pushed["a"].attractor[1] < dynamics["a"].attractor[1]  # further down into the soup


def test_fit_rejects_bad_input(env, expert_demos) -> None:
    task = env.unwrapped.task
    demo = expert_demos[0]
    stop = int(np.argmax(demo.modes == 2))  # cut the demonstration before it ever scoops
    short = (demo.states[:stop], demo.modes[:stop], demo.actions[: stop - 1])
    with pytest.raises(ValueError, match=r"never visit mode\(s\) \['c', 'd'\]"):
        fit_mode_dynamics([short], task)
    with pytest.raises(ValueError, match="attractor_rule"):
        fit_mode_dynamics(expert_demos, task, attractor_rule="mean")
    with pytest.raises(ValueError, match="overshoot"):
        fit_mode_dynamics(expert_demos, task, overshoot=-1.0)
    with pytest.raises(TypeError, match="Demonstration"):
        fit_mode_dynamics([np.zeros((5, 2))], task)
    with pytest.raises(ValueError, match="velocities must have shape"):
        fit_mode_dynamics([(demo.states, demo.modes, demo.actions[:-3])], task)
    with pytest.raises(ValueError, match="non-empty"):
        fit_mode_dynamics([], task)


def test_nominal_episode_follows_the_plan(env, dynamics) -> None:
    policy = LTLDSPolicy(env.unwrapped.task, for_env(env), dynamics, max_speed=10.0, dt=0.01)
    info = _episode(env, policy)
    assert info["success"]
    assert [(e.source, e.target, e.kind) for e in policy.events] == [
        ("a", "b", "planned"),
        ("b", "c", "planned"),
        ("c", "d", "planned"),
    ]
    assert policy.num_failures == 0 and policy.num_cuts == 0 and policy.mode == "d"


def test_modulation_ends_the_discrete_loop_that_plain_sequencing_repeats(env) -> None:
    """Thesis Fig. 3.6: a transport DS that spills loops a -> b -> c -> a forever; one cut ends it."""
    plain = LTLDSPolicy(env.unwrapped.task, for_env(env), _spiral_dynamics(1.0), modulation=False, max_speed=10.0)
    info = _episode(env, plain)
    assert not info["success"]  # capped at 3000 steps, still looping
    fails = [e for e in plain.events if e.kind == "failure"]
    assert len(fails) >= 4 and {(e.source, e.target) for e in fails} == {("c", "a")}
    assert plain.num_cuts == 0 and len(plain.failures["c"]) == len(fails)

    learned = LTLDSPolicy(env.unwrapped.task, for_env(env), _spiral_dynamics(1.0), modulation=True, max_speed=10.0)
    info = _episode(env, learned)
    assert info["success"]
    assert sum(e.kind == "failure" for e in learned.events) == 1  # each invariance failure is experienced once
    assert len(learned.cut_sets["c"]) == 1 and learned.num_cuts == 1
    cut = learned.cut_sets["c"].cuts[0]
    fail = next(e for e in learned.events if e.kind == "failure")
    np.testing.assert_allclose(cut.point, fail.before)  # the cut goes through the last in-mode state
    assert cut.signed_distance(fail.after[None])[0] > 0  # ... and puts the failure state outside
    # cuts persist across episodes (the learning); the next episode has no failure at all
    assert _episode(env, learned)["success"] and not any(e.kind == "failure" for e in learned.events)
    learned.clear_cuts()
    assert learned.num_cuts == 0 and learned.num_failures == 0


def test_pushes_are_not_failures(env, dynamics) -> None:
    policy = LTLDSPolicy(env.unwrapped.task, for_env(env), dynamics, max_speed=10.0, dt=0.01)
    base = env.unwrapped
    obs, info = env.reset(seed=1)
    policy.reset(obs, info)
    for _ in range(5):
        obs, _, _, _, info = env.step(policy.act(obs, info))
    info = base.perturb(to=np.array([-4.0, -6.0]))  # into the soup: a -> b by a push
    policy.act(base.state.astype(np.float32), info)
    assert policy.events[-1].kind == "push" and policy.mode == "b"
    # an unflagged jump is recognised from dt and the last command
    base.perturb(to=np.array([-4.0, 3.0]))
    jumped = {k: v for k, v in base._info(False).items() if k != "perturbed"}
    policy.act(base.state.astype(np.float32), jumped)
    assert policy.events[-1].kind == "push" and policy.mode == "a"
    assert policy.num_failures == 0


def test_hold_beyond_cuts_stops_outward_motion_and_lowers_v() -> None:
    cuts = CutSet(np.zeros(2), [Cut(np.array([1.0, 0.0]), np.array([1.0, 0.0]))])
    rng = np.random.default_rng(0)
    x = rng.uniform([-2.0, -3.0], [3.0, 3.0], size=(2000, 2))
    v = rng.normal(size=(2000, 2)) * 5
    out = hold_beyond_cuts(x, v, cuts)
    beyond = x[:, 0] > 1.0
    np.testing.assert_array_equal(out[~beyond], v[~beyond])  # inside: untouched (modulate handles it)
    assert np.all(out[beyond, 0] <= 1e-12)  # no motion further out
    moved = beyond & (v[:, 0] > 0)
    assert moved.any()
    assert np.all(np.einsum("ij,ij->i", x[moved], out[moved]) < np.einsum("ij,ij->i", x[moved], v[moved]))  # dV/dt
    np.testing.assert_array_equal(out[beyond & (v[:, 0] <= 0)], v[beyond & (v[:, 0] <= 0)])


def test_policy_rejects_bad_arguments(env, dynamics) -> None:
    task, spec = env.unwrapped.task, for_env(env)
    with pytest.raises(ValueError, match="lacks mode"):
        LTLDSPolicy(task, spec, {m: dynamics[m] for m in "abc"})
    with pytest.raises(TypeError, match="GR1Spec"):
        LTLDSPolicy(task, "soup", dynamics)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="max_speed"):
        LTLDSPolicy(task, spec, dynamics, max_speed=-1.0)
    policy = LTLDSPolicy(task, spec, dynamics)
    with pytest.raises(RuntimeError, match="reset"):
        _ = policy.mode
    obs, info = env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        policy.reset(np.zeros(3), info)
    with pytest.raises(KeyError, match="sensors"):
        policy.reset(obs, {"mode": 0})
    with pytest.raises(ValueError, match="mode must be one of"):
        policy.flow(np.zeros((1, 2)), "z")
    v = policy.act(obs, info)  # act before reset resets
    assert v.shape == (2,) and v.dtype == np.float32 and policy.mode == "a"
