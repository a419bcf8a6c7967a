"""Cuts (QCQP), Gamma, DS modulation, the modulation wrapper and the single-mode protocol."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.baselines.lpv_ds.cuts import Cut, CutSet, FailureRecord, resolve_cuts, solve_cut
from steer_envs.baselines.lpv_ds.lpvds import LPVDS
from steer_envs.baselines.lpv_ds.modulation import ModulatedPolicy, gamma, modulate, modulation_matrix
from steer_envs.baselines.lpv_ds.single_mode import rollout, sample_starts
from steer_envs.bench.suites.tli.protocol import THESIS_SUCCESS, single_mode_trial
from steer_envs.core.policy import VelocityPolicy
from steer_envs.data.experts import make_expert
from steer_envs.data.tli_demos import convex_mode_demos
from steer_envs.wrappers import DSModulationWrapper, LTLReplanWrapper

DT, MAX_SPEED = 0.01, 20.0
ANGLES = np.linspace(0.0, 2.0 * np.pi, 100_000, endpoint=False)
CIRCLE = np.stack([np.cos(ANGLES), np.sin(ANGLES)], axis=1)


def _constraints(f, fail, x0, att, vis, margin=0.4):
    """Rows ``a`` and bounds ``c`` of ``a n <= c`` as documented (points at ``f`` itself impose nothing)."""
    pts = [p for p in [*np.asarray(vis).reshape(-1, len(f)), x0] if np.linalg.norm(p - f) > 1e-12]
    a = np.vstack([att - f, *(p - f for p in pts), -(fail - f)])
    c = np.zeros(len(a))
    c[0] = -margin
    return a, c


def _on_circle(a: np.ndarray) -> np.ndarray:
    """``CIRCLE @ a.T`` by broadcasting (no BLAS threads: fast on a busy machine)."""
    return CIRCLE[:, :1] * a[:, 0] + CIRCLE[:, 1:] * a[:, 1]


# ------------------------------------------------------------------------- QCQP
point = st.tuples(st.floats(-6, 6), st.floats(-6, 6)).map(np.array)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(f=point, att=point, x0=point, vis=st.lists(point, max_size=3), step=point)
def test_2d_cut_is_the_exact_qcqp_optimum(f, att, x0, vis, step) -> None:
    """Against brute force over 100k unit normals: never worse, always feasible; infeasible claims verified."""
    fail = f + 0.05 * step
    if np.linalg.norm(att - f) < 1e-3 or np.linalg.norm(fail - f) < 1e-6:
        return
    vis = np.array(vis).reshape(-1, 2)
    u, w = (att - f) / np.linalg.norm(att - f), (fail - f) / np.linalg.norm(fail - f)
    if u @ w > 1 - 1e-12:  # failure straight toward the attractor: no plane separates them
        with pytest.raises(ValueError, match="no cut"):
            solve_cut(f, fail, x0, att, vis)
        return
    cut = solve_cut(f, fail, x0, att, vis)
    # the program as posed; its margin shrinks to 0.9 |att - f| near the attractor (reported as relaxed "margin")
    a, c = _constraints(f, fail, x0, att, vis, margin=min(0.4, 0.9 * np.linalg.norm(att - f)))
    slack = _on_circle(a) - c
    solves_posed = bool(np.all(a @ cut.normal - c <= 1e-8))
    if cut.relaxed and not solves_posed:
        assert not np.all(slack <= -1e-9, axis=1).any()  # the program as posed really has no (robust) solution
        return
    assert solves_posed
    feasible = np.all(slack <= 1e-9, axis=1)  # a grid cannot hit single-point feasible sets exactly
    assert feasible.any()
    brute = np.min(_on_circle((att - f)[None])[feasible, 0] ** 2)
    assert (cut.normal @ (att - f)) ** 2 <= brute + 1e-7
    assert abs(np.linalg.norm(cut.normal) - 1) < 1e-12


def test_cut_geometry_and_relaxation() -> None:
    att, f, step = np.zeros(2), np.array([3.0, 0.0]), np.array([0.1, 0.0])
    cut = solve_cut(f, f + step, np.array([-3.0, 0.0]), att)
    assert cut.relaxed == ()
    assert cut.signed_distance(att[None])[0] <= -0.4 + 1e-9  # the 0.4-ball around the attractor stays inside
    assert cut.signed_distance((f + step)[None])[0] >= 0  # the failure state is outside
    assert abs(cut.normal @ (att - f)) == pytest.approx(0.4)  # as close to the attractor as allowed
    # an earlier last-in-mode state on the wrong side of every admissible plane is dropped, and that is recorded
    blocked = solve_cut(f, f + step, np.array([-3.0, 0.0]), att, visited=np.array([[3.2, 0.0], [3.1, 1.5]]))
    assert "visited" in blocked.relaxed
    with pytest.raises(ValueError, match="attractor"):
        solve_cut(att, att + 1, f, att)
    with pytest.raises(ValueError, match="differ"):
        solve_cut(f, f, att, att)


def test_3d_cut_matches_a_sampled_sphere_search() -> None:
    rng = np.random.default_rng(0)
    sphere = rng.normal(size=(200_000, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    checked = 0
    for _ in range(8):
        f, att, x0 = rng.uniform(-5, 5, size=(3, 3))
        fail = f + 0.1 * rng.normal(size=3)
        vis = rng.uniform(-5, 5, size=(2, 3))
        cut = solve_cut(f, fail, x0, att, vis, restarts=24)
        if cut.relaxed:
            continue
        a, c = _constraints(f, fail, x0, att, vis)
        assert np.all(a @ cut.normal - c <= 1e-6)
        proj = sum(sphere[:, j : j + 1] * a[:, j] for j in range(3))  # sphere @ a.T without BLAS
        ok = np.all(proj - c <= 0, axis=1)
        assert (cut.normal @ (att - f)) ** 2 <= np.min(proj[ok, 0] ** 2) + 1e-6
        checked += 1
    assert checked >= 3


# ---------------------------------------------------------------- Gamma, modulation
def _square() -> CutSet:
    r = np.zeros(2)
    normals = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]
    return CutSet(r, [Cut(np.array(n) * 2.0, np.array(n)) for n in normals])


def test_gamma_levels() -> None:
    cuts = _square()
    g = gamma(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [-1.0, 1.5]]), cuts)
    np.testing.assert_allclose(g, [0.0, 0.5, 1.0, 1.5, 0.75])
    assert list(cuts.inside(np.array([[1.9, 1.9], [2.1, 0.0]]))) == [True, False]
    assert np.all(gamma(np.ones((3, 2)), CutSet(np.zeros(2))) == 0)
    with pytest.raises(ValueError, match="reference"):
        CutSet(np.zeros(2), [Cut(np.array([1.0, 0.0]), np.array([-1.0, 0.0]))])  # attractor outside


def test_closed_form_equals_eigen_decomposition() -> None:
    rng = np.random.default_rng(0)
    ref = np.array([0.5, -0.3])
    cut = Cut(np.array([2.0, 1.0]), np.array([1.0, 0.4]))
    cuts = CutSet(ref, [cut])
    x = rng.uniform(-1, 2, size=(400, 2))
    x = x[cuts.inside(x) & (cuts.gammas(x)[:, 0] > 0.05)]
    v = rng.normal(size=x.shape) * 5
    v[v @ cut.normal < 0] *= -1  # all approaching the cut
    m = modulation_matrix(x, cut, ref)
    np.testing.assert_allclose(modulate(x, v, cuts), np.einsum("nij,nj->ni", m, v), atol=1e-9)
    # eigen-structure: r_hat is scaled by 1 - Gamma, the cut's tangent is kept
    r_hat = (x - ref) / np.linalg.norm(x - ref, axis=1, keepdims=True)
    g = cuts.gammas(x)[:, 0]
    np.testing.assert_allclose(np.einsum("nij,nj->ni", m, r_hat), (1 - g)[:, None] * r_hat, atol=1e-9)
    tangent = np.array([-cut.normal[1], cut.normal[0]])
    np.testing.assert_allclose(m @ tangent, np.broadcast_to(tangent, x.shape), atol=1e-9)


def test_modulation_only_when_approaching_inside() -> None:
    cuts = _square()
    x = np.array([[1.0, 0.0], [1.0, 0.0], [3.0, 0.0], [1.999999, 0.0]])
    v = np.array([[-1.0, 0.3], [1.0, 0.3], [1.0, 0.0], [1.0, 1.0]])
    out = modulate(x, v, cuts)
    np.testing.assert_allclose(out[0], v[0])  # moving away from every cut
    assert out[1] @ np.array([1.0, 0.0]) < v[1] @ np.array([1.0, 0.0])  # approaching: slowed toward the cut
    np.testing.assert_allclose(out[2], v[2])  # outside the cuts: nominal
    assert abs(out[3, 0]) < 1e-5  # on the cut the normal component vanishes
    clipped = modulate(x, v * 100, cuts, max_speed=MAX_SPEED)
    assert np.all(np.linalg.norm(clipped, axis=1) <= MAX_SPEED + 1e-9)
    with pytest.raises(ValueError, match="shape"):
        modulate(x, v[:2], cuts)


def test_a_cut_holds_states_beyond_another_cut() -> None:
    """'Outside' is per cut: beyond the x = 2 cut but on the y = 2 cut, moving up, the y-velocity vanishes."""
    cuts = _square()
    out = modulate(np.array([[3.0, 1.999999]]), np.array([[0.5, 1.0]]), cuts)
    # M v = v - (n . v) (x - r) / h against the y cut only: (0.5, 1) - 1 * (3, 2) / 2
    np.testing.assert_allclose(out[0], [-1.0, 0.0], atol=1e-5)


# --------------------------------------------------------- the Done-when properties
def _random_ds(rng: np.random.Generator, k: int) -> LPVDS:
    """A random certified LPV-DS: A_k = P^-1 (W_k - S_k), S_k > 0, W_k skew  =>  A_k^T P + P A_k = -2 S_k."""
    att = rng.uniform(-2, 2, size=2)
    root = rng.normal(size=(2, 2))
    p = root @ root.T + 0.3 * np.eye(2)
    p_inv = np.linalg.inv(p)
    a = []
    for _ in range(k):
        s = rng.normal(size=(2, 2))
        w = rng.normal(size=(2, 2)) * 3
        a.append(p_inv @ (w - w.T - (s @ s.T + 0.1 * np.eye(2))))
    covs = np.stack([np.eye(2) * rng.uniform(1, 9) for _ in range(k)])
    return LPVDS.from_parameters(att, p, np.stack(a), np.ones(k), rng.uniform(-6, 6, size=(k, 2)), covs)


def _random_cuts(rng: np.random.Generator, ref: np.ndarray, n: int) -> CutSet:
    cuts = []
    for _ in range(n):
        theta = rng.uniform(0, 2 * np.pi)
        normal = np.array([np.cos(theta), np.sin(theta)])
        along = np.array([-normal[1], normal[0]]) * rng.normal() * 3
        cuts.append(Cut(ref + rng.uniform(0.4, 4.0) * normal + along, normal))
    return CutSet(ref, cuts)


def _check_invariance(policy: VelocityPolicy, ds: LPVDS, cuts: CutSet, starts: np.ndarray, steps: int) -> None:
    """Forward Euler (dt = 0.01, |x'| <= 20): no state ever leaves the cuts and V decreases along the flow."""
    x = starts
    v0 = ds.lyapunov(x)
    for _ in range(steps):
        v = policy(x)
        vdot = ds.lyapunov_derivative(x, v)
        moving = np.linalg.norm(x - ds.attractor, axis=1) > 1e-6
        assert np.all(vdot[moving] < 0), "V must decrease along the modulated flow"
        assert np.all(vdot <= 0)
        x = x + DT * v
        assert np.all(cuts.inside(x)), "a modulated trajectory crossed a cut"
    assert np.all(ds.lyapunov(x) <= v0)


def _starts_inside(rng: np.random.Generator, cuts: CutSet, n: int, half_width: float = 10.0) -> np.ndarray:
    """``n`` uniform states strictly inside the cuts (and a box around the reference)."""
    got: list[np.ndarray] = []
    while sum(len(g) for g in got) < n:
        cand = cuts.reference + rng.uniform(-half_width, half_width, size=(20_000, 2))
        got.append(cand[cuts.gammas(cand).max(axis=1) < 1 - 1e-9])
    return np.concatenate(got)[:n]


STARTS_PER_EXAMPLE = 1_000
EXAMPLES = 12  # 12 x 1,000 = 12,000 random starts (and another 10,000 in the fitted-DS test below)


@settings(max_examples=EXAMPLES, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), n_cuts=st.integers(1, 7), k=st.integers(1, 4))
def test_modulated_ds_never_crosses_a_cut(seed: int, n_cuts: int, k: int) -> None:
    """Random certified DS, random cuts, random starts inside them: 0 violations, V decreasing."""
    rng = np.random.default_rng(seed)
    ds = _random_ds(rng, k)
    cuts = _random_cuts(rng, ds.attractor, n_cuts)
    starts = _starts_inside(rng, cuts, STARTS_PER_EXAMPLE)
    _check_invariance(ModulatedPolicy(ds, cuts, max_speed=MAX_SPEED), ds, cuts, starts, steps=150)


def test_fitted_ds_with_learned_cuts_is_invariant_and_reaches_the_attractor() -> None:
    """The single-mode setting: LPV-DS from drawn ConvexMode demos, cuts from its failures, 10,000 starts."""
    xs, vs, model = convex_mode_demos(0, 1)
    ds = LPVDS().fit(xs, vs, attractor=model.attractor)
    rng = np.random.default_rng(0)
    starts = sample_starts(model, np.concatenate(xs), 5.0, 300, rng)
    nominal = rollout(ds, model, starts, n_steps=400)
    assert nominal["left"].mean() > 0.2  # this mode has many invariance failures without cuts
    fails = [
        FailureRecord(nominal["last_in"][i], nominal["first_out"][i], starts[i])
        for i in np.nonzero(nominal["left"])[0][:4]
    ]
    cuts = CutSet(model.attractor, resolve_cuts(fails, model.attractor))
    policy = ModulatedPolicy(ds, cuts, max_speed=MAX_SPEED)
    inner = _starts_inside(rng, cuts, 10_000)
    _check_invariance(policy, ds, cuts, inner, steps=120)
    # reachability survives modulation: from inside the cuts and the mode everything converges, and the
    # mode exits that are left come from the slivers where 4 cuts do not yet cover the mode boundary
    both = inner[model.inside(inner)][:2000]
    out = rollout(policy, model, both, n_steps=1000)
    nominal = rollout(ds, model, both, n_steps=1000)
    assert np.all(np.linalg.norm(out["final"] - model.attractor, axis=1) < 0.05)
    assert out["left"].mean() < 0.01 < 0.3 < nominal["left"].mean()


# --------------------------------------------------------------------- wrapper
@pytest.fixture(scope="module")
def convex_ds() -> tuple[LPVDS, object, np.ndarray]:
    xs, vs, model = convex_mode_demos(0, 1)
    ds = LPVDS().fit(xs, vs, attractor=model.attractor)
    starts = sample_starts(model, np.concatenate(xs), 5.0, 60, np.random.default_rng(1))
    return ds, model, starts


def _episode(env: gym.Env, policy: VelocityPolicy, start: np.ndarray) -> list[dict]:
    env.reset(options={"state": start})
    infos = []
    for _ in range(1000):
        action = policy(env.unwrapped.state[None])[0]
        _, _, terminated, truncated, info = env.step(action)
        infos.append(info)
        if terminated or truncated:
            break
    return infos


def test_protocol_rollout_matches_the_env(convex_ds) -> None:
    ds, model, starts = convex_ds
    vec = rollout(ds, model, starts[:12], n_steps=1000)
    env = gym.make("steer_envs/ConvexMode-v0", layout_seed=0)
    for i, start in enumerate(starts[:12]):
        infos = _episode(env, ds, start)
        left = any(info["constraint_violation"] for info in infos)
        assert left == vec["left"][i]
        assert infos[-1]["success"] == (not left)


def test_wrapper_learns_cuts_from_failures_and_then_stays_in_mode(convex_ds) -> None:
    ds, model, starts = convex_ds
    env = DSModulationWrapper(gym.make("steer_envs/ConvexMode-v0", layout_seed=0), attractor=model.attractor)
    failing = np.nonzero(rollout(ds, model, starts, n_steps=1000)["left"])[0]
    assert len(failing) >= 5
    first_pass = []
    for i in failing[:6]:
        infos = _episode(env, ds, starts[i])
        failed = any(info["invariance_failure"] for info in infos)
        first_pass.append(failed)
        if failed:
            assert infos[-1]["cut_added"] and infos[-1]["constraint_violation"]
    assert env.num_cuts == sum(first_pass) >= 1
    cuts = env.cut_sets[0]
    assert all(c.relaxed == () or "visited" in c.relaxed for c in cuts.cuts)
    second_pass = [any(info["constraint_violation"] for info in _episode(env, ds, starts[i])) for i in failing[:6]]
    assert sum(second_pass) < sum(first_pass)
    # with learning off and no cuts, the wrapper is transparent
    bare = DSModulationWrapper(gym.make("steer_envs/ConvexMode-v0", layout_seed=0), model.attractor, learn=False)
    infos = _episode(bare, ds, starts[failing[0]])
    assert infos[-1]["constraint_violation"] and bare.num_cuts == 0 and not any(i["modulated"] for i in infos)


def test_pushes_and_planned_exits_are_not_failures(convex_ds) -> None:
    _, model, _ = convex_ds
    outside = np.array([7.9, 7.9])
    assert not model.inside(outside[None])[0]
    env = DSModulationWrapper(
        gym.make("steer_envs/ConvexMode-v0", layout_seed=0, terminate_on_violation=False), model.attractor
    )
    env.reset(options={"state": model.demo_start})
    env.perturb(to=outside)  # a push out of the mode
    _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert not info["invariance_failure"] and env.num_cuts == 0
    env.reset(options={"state": model.demo_start})
    env.unwrapped.perturb(to=outside)  # pushed behind the wrapper's back: also not the policy's failure
    _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert not info["invariance_failure"] and env.num_cuts == 0
    # a plan that asks for the exit
    planned = DSModulationWrapper(
        gym.make("steer_envs/ConvexMode-v0", layout_seed=0), model.attractor, plan=lambda mode, info: {1}
    )
    planned.reset(options={"state": model.vertices.mean(axis=0)})
    info = {"mode": 0}
    for _ in range(400):
        _, _, term, _, info = planned.step(np.array([20.0, 0.0], dtype=np.float32))
        if term:
            break
    assert info["mode"] == 1 and not info["invariance_failure"] and planned.num_cuts == 0


class _PlanInfo(gym.Wrapper):
    """Adds ``info["plan"]`` like the LTL replanner: the current mode, then the planned next one."""

    def reset(self, **kw):
        obs, info = self.env.reset(**kw)
        return obs, dict(info, plan=["inside", "outside"])

    def step(self, action):
        obs, r, term, trunc, info = self.env.step(action)
        return obs, r, term, trunc, dict(info, plan=["inside", "outside"])


def test_info_plan_is_read_by_default(convex_ds) -> None:
    _, model, _ = convex_ds
    env = DSModulationWrapper(_PlanInfo(gym.make("steer_envs/ConvexMode-v0", layout_seed=0)), model.attractor)
    env.reset(options={"state": model.vertices.mean(axis=0)})
    for _ in range(400):
        _, _, term, _, info = env.step(np.array([20.0, 0.0], dtype=np.float32))
        if term:
            break
    assert info["mode"] == 1 and not info["invariance_failure"]


def test_composes_with_the_ltl_replanner_on_soup_scoop() -> None:
    """Around LTLReplanWrapper, the planned a -> b -> c -> d transitions of a demonstration are not failures."""
    attractors = {0: [-6.47, -4.13], 1: [2.06, -6.98], 2: [4.69, 6.03]}  # the public demos' per-segment attractors

    def run(env: gym.Env, unwrap_obs: bool) -> tuple[int, set[int], bool]:
        expert = make_expert(env)
        obs, info = env.reset(seed=0)
        obs = obs["observation"] if unwrap_obs else obs
        expert.reset(obs, info)
        failures, modes = 0, {info["mode"]}
        for _ in range(2000):
            obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
            obs = obs["observation"] if unwrap_obs else obs
            failures += info["invariance_failure"]
            modes.add(info["mode"])
            if terminated or truncated:
                break
        return failures, modes, info["success"]

    planned = DSModulationWrapper(LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0")), attractors, learn=False)
    failures, modes, success = run(planned, unwrap_obs=True)
    assert success and modes == {0, 1, 2, 3} and failures == 0
    unplanned = DSModulationWrapper(gym.make("steer_envs/SoupScoop-v0"), attractors, learn=False)
    assert run(unplanned, unwrap_obs=False)[0] == 3  # without a plan every mode exit looks like a failure


def test_wrapper_rejects_bad_arguments() -> None:
    base = gym.make("steer_envs/ConvexMode-v0", layout_seed=0)
    with pytest.raises(ValueError, match="attractor"):
        DSModulationWrapper(base, attractor=[np.nan, 0.0])
    with pytest.raises(TypeError, match="plan"):
        DSModulationWrapper(base, attractor=[0.0, 0.0], plan=3)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="margin"):
        DSModulationWrapper(base, attractor=[0.0, 0.0], margin=-1.0)
    with pytest.raises(TypeError, match="policy"):
        ModulatedPolicy(3, CutSet(np.zeros(2)))  # type: ignore[arg-type]


def test_convex_mode_integration_with_expert_demos() -> None:
    """DS from the scripted expert's demos (make_expert), env rollouts without and with modulation."""
    env = gym.make("steer_envs/ConvexMode-v0", layout_seed=4)  # uniform starts over the mode
    expert = make_expert(env)
    xs, vs = [], []
    for seed in range(2):
        obs, info = env.reset(seed=seed)
        expert.reset(obs, info)
        states, actions = [], []
        for _ in range(1000):
            action = expert.act(obs, info)
            states.append(env.unwrapped.state)
            actions.append(np.asarray(action, dtype=np.float64))
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        assert info["success"]
        xs.append(np.asarray(states))
        vs.append(np.asarray(actions))
    model = env.unwrapped.model
    ds = LPVDS().fit(xs, vs, attractor=model.attractor)
    assert ds.check_stability().stable

    def run(wrapped: gym.Env) -> tuple[int, int]:
        violations = successes = 0
        for i in range(40):
            wrapped.reset(seed=100 + i)
            for _ in range(1000):
                _, _, terminated, truncated, info = wrapped.step(ds(wrapped.unwrapped.state[None])[0])
                if terminated or truncated:
                    break
            violations += info["constraint_violation"]
            successes += info["success"]
        return violations, successes

    nominal = run(
        DSModulationWrapper(gym.make("steer_envs/ConvexMode-v0", layout_seed=4), model.attractor, learn=False)
    )
    modulated = DSModulationWrapper(gym.make("steer_envs/ConvexMode-v0", layout_seed=4), model.attractor)
    learning = run(modulated)  # cuts are learned from this pass's failures
    after = run(modulated)  # the same starts again, with the learned cuts
    assert nominal[0] >= 1 and nominal[0] + nominal[1] == 40  # a stable DS fails only by leaving the mode
    assert modulated.num_cuts >= 1 and learning[0] <= nominal[0]
    assert after[0] < nominal[0] and after[1] > nominal[1]


# --------------------------------------------------------------- single-mode protocol
def test_single_mode_trial_ds_vs_ds_mod() -> None:
    ds = single_mode_trial(0, 5.0, "ds", n_starts=60, seed=0, n_demos=1)
    mod = single_mode_trial(0, 5.0, "ds+mod", n_starts=60, seed=0, n_demos=1)
    assert ds["reachability_failure_rate"] == 0.0  # a stable DS only fails by leaving the mode
    assert ds["invariance_failure_rate"] > 0.2
    assert mod["success_rate"] > ds["success_rate"] + 0.3
    assert 1 <= mod["num_cuts"] <= 4 and len(mod["cut_round_success"]) == mod["num_cuts"] + 1
    assert mod["cut_round_success"][0] == ds["success_rate"]  # same starts, no cuts yet
    held_out = single_mode_trial(0, 5.0, "ds+mod", n_starts=60, seed=0, n_demos=1, cut_sigma=5.0)
    assert held_out["success_rate"] > ds["success_rate"]  # cuts learned on other starts carry over
    assert set(THESIS_SUCCESS) == {"bc", "bc+mod", "ds", "ds+mod"}
    with pytest.raises(ValueError, match="policy_kind"):
        single_mode_trial(0, 1.0, "dmp", n_starts=5)


@pytest.mark.parametrize("layout", [0, 16, 41])
def test_single_mode_ds_mod_is_perfect_where_it_used_to_fail(layout: int) -> None:
    """30 % noise: layout 0 and 16 once failed by starts beyond an older cut (then followed the nominal flow
    out), 41 by a start that stalled in the corner of two cuts; all three reach 100 % now."""
    res = single_mode_trial(layout, 5.0, "ds+mod", n_starts=100, seed=layout)
    assert res["success_rate"] == 1.0, res


@pytest.mark.slow
def test_single_mode_study_ordering() -> None:
    """Thesis table at the large noise level over 5 modes: BC < BC+mod < DS+mod, DS < DS+mod, DS+mod ~ 100 %."""
    kinds = tuple(THESIS_SUCCESS)
    mean = {
        k: np.mean([single_mode_trial(L, 5.0, k, n_starts=100, seed=0)["success_rate"] for L in range(5)])
        for k in kinds
    }
    assert mean["ds+mod"] >= 0.99
    assert mean["ds"] < mean["ds+mod"]
    assert mean["bc"] < mean["bc+mod"] < mean["ds+mod"]
