"""CounterfactualReplayer (GLiDE's perturbed demo replays) and the counterfactual data set."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import steer_envs  # noqa: F401
from steer_envs.core.validation import BoundExceeded
from steer_envs.data.counterfactual import CounterfactualReplayer
from steer_envs.data.counterfactual_dataset import KINDS, CounterfactualDataset, build_counterfactual_dataset
from steer_envs.data.demos import collect_demonstrations
from steer_envs.data.perturbations import PerturbedReference, gripper_toggle, kernel_perturbation, segment_perturbation

ENV_ID = "steer_envs/PolygonNav-4Mode-v0"


@pytest.fixture(scope="module")
def demos() -> list[np.ndarray]:
    return [d.states for d in collect_demonstrations(ENV_ID, 3, 0, layout_seed=0)]


def _env(**kwargs: object) -> gym.Env:
    return gym.make(ENV_ID, layout_seed=0, terminate_on_violation=False, max_episode_steps=5000, **kwargs)


def _full_path_success(model: object, modes: np.ndarray) -> bool:
    """Thesis criterion on a path's mode sequence: every transition allowed, ends in the last mode."""
    allowed = model.allowed  # type: ignore[attr-defined]
    return bool(np.all(allowed[modes[:-1], modes[1:]]) and modes[-1] == model.num_modes - 1)  # type: ignore[attr-defined]


# ------------------------------------------------------------------ pure perturbations
def test_segment_perturbation_replaces_xy_by_xz_zy() -> None:
    path = np.stack([np.linspace(0, 9, 10), np.zeros(10)], axis=1)
    rng = np.random.default_rng(3)
    out, (x, y), z = segment_perturbation(path, rng, [-8, -8], [8, 8])
    assert 0 <= x < y <= 9
    np.testing.assert_array_equal(out[: x + 1], path[: x + 1])
    np.testing.assert_array_equal(out[x + 1], z)
    np.testing.assert_array_equal(out[x + 2 :], path[y:])
    assert np.all(np.abs(z) <= 8)


def test_kernel_perturbation_follows_the_gaussian_window_and_keeps_the_ends() -> None:
    path = np.zeros((40, 2))
    rng = np.random.default_rng(0)
    out, (s, e), z = kernel_perturbation(path, rng, [-8, -8], [8, 8], sharpness=5.0, min_window=4)
    assert 1 <= s and e <= 38 and e - s >= 4
    c = 0.5 * (s + e)
    t = np.arange(40)
    w = np.where((t >= s) & (t <= e), np.exp(-5 * (t - c) ** 2 / (s - c) ** 2), 0.0)
    np.testing.assert_allclose(out, w[:, None] * z[None, :], atol=1e-12)
    np.testing.assert_array_equal(out[[0, -1]], path[[0, -1]])


def test_gripper_toggle_negates_a_5_to_20_step_window() -> None:
    g = np.ones(100)
    out, (a, b) = gripper_toggle(g, np.random.default_rng(1))
    assert 5 <= b - a + 1 <= 20
    assert np.all(out[a : b + 1] == -1) and np.sum(out == -1) == b - a + 1
    forced, _ = gripper_toggle(g, np.random.default_rng(1), force=0.0)
    assert np.sum(forced == 0.0) == b - a + 1


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: segment_perturbation(np.zeros((1, 2)), np.random.default_rng(), [-1, -1], [1, 1]), "T >= 2"),
        (lambda: segment_perturbation(np.zeros((5, 2)), np.random.default_rng(), [1, 1], [-1, -1]), "low < high"),
        (lambda: kernel_perturbation(np.zeros((4, 2)), np.random.default_rng(), [-1, -1], [1, 1]), "too short"),
        (lambda: gripper_toggle(np.ones(10), np.random.default_rng(), min_steps=5, max_steps=2), "min_steps"),
    ],
)
def test_perturbations_reject_bad_input(call: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        call()  # type: ignore[operator]


# ------------------------------------------------------------------------ replayer
def test_replayer_validates_its_arguments() -> None:
    env = _env()
    with pytest.raises(ValueError, match="unknown perturbation kind"):
        CounterfactualReplayer(env, "teleport")
    with pytest.raises(ValueError, match="gripper"):
        CounterfactualReplayer(env, "gripper")
    with pytest.raises(ValueError, match="execution"):
        CounterfactualReplayer(env, execution="fly")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="execution"):
        build_counterfactual_dataset(ENV_ID, [np.zeros((3, 2))], execution="fly", layout_seed=0)
    with pytest.raises(TypeError, match=r"gymnasium\.Env"):
        CounterfactualReplayer("env")  # type: ignore[arg-type]
    replayer = CounterfactualReplayer(env, {"segment": 1.0, "kernel": 3.0})
    assert replayer.kind_weights == {"segment": 0.25, "kernel": 0.75}
    with pytest.raises(TypeError, match="PerturbedReference"):
        replayer.replay_batch([np.zeros((3, 2))])  # type: ignore[list-item]


@pytest.mark.parametrize("execution", ["tracking", "jump"])
def test_replays_follow_the_reference_and_are_labelled_by_the_env(demos: list[np.ndarray], execution: str) -> None:
    env = _env()
    model = env.unwrapped.model
    replayer = CounterfactualReplayer(env, ["segment", "kernel"], execution=execution)  # type: ignore[arg-type]
    replays = replayer.rollouts(demos, 60, seed=0, batch_size=30)
    assert len(replays) == 60
    labels = np.array([r.success for r in replays])
    assert 0 < labels.mean() < 1  # both outcomes occur
    for r in replays:
        # the replay starts and ends where its reference does
        np.testing.assert_allclose(r.states[0], r.reference.waypoints[0], atol=1e-5)
        np.testing.assert_allclose(r.states[-1], r.reference.waypoints[-1], atol=1e-4)
        # the recorded modes are the env's (float64 state); observations are float32
        assert np.mean(r.modes == model.mode_of(r.states)) > 0.97
        assert r.success == _full_path_success(model, r.modes)
        assert (r.violation_step >= 0) == (not r.success)
        step = np.linalg.norm(np.diff(r.states, axis=0), axis=1).max()
        if execution == "tracking":
            assert step <= 0.1 + 1e-5  # the env's speed limit
    if execution == "jump":  # one env step per waypoint
        assert all(len(r.states) <= len(r.reference.waypoints) for r in replays)


def test_vectorized_and_single_env_replays_agree(demos: list[np.ndarray]) -> None:
    replayer = CounterfactualReplayer(_env(), "segment")
    rng = np.random.default_rng(5)
    refs = [replayer.sample(demos[i % len(demos)], rng, source=i % len(demos)) for i in range(12)]
    batched = replayer.replay_batch(refs)
    single = [replayer.replay(r) for r in refs]
    for a, b in zip(batched, single, strict=True):
        assert a.success == b.success and a.violation_step == b.violation_step
        assert a.states.shape == b.states.shape
        np.testing.assert_allclose(a.states, b.states, atol=1e-5)  # float32 round trips at episode restarts


def test_unperturbed_demos_succeed_and_rollouts_are_seeded(demos: list[np.ndarray]) -> None:
    replayer = CounterfactualReplayer(_env(), "kernel")
    assert all(r.success for r in replayer.replay_batch([replayer.unperturbed(d) for d in demos]))
    a = replayer.rollouts(demos, 8, seed=4)
    b = replayer.rollouts(demos, 8, seed=4)
    assert [r.success for r in a] == [r.success for r in b]
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.reference.waypoints, y.reference.waypoints)


def test_gripper_references_need_a_gripper_controller(demos: list[np.ndarray]) -> None:
    replayer = CounterfactualReplayer(_env(), "segment")
    ref = PerturbedReference(demos[0], "gripper", 0, (0, 5), np.full(2, np.nan), np.ones(len(demos[0])))
    with pytest.raises(ValueError, match="gripper"):
        replayer.replay(ref)


# ------------------------------------------------------------------------- data set
def test_dataset_is_balanced_and_round_trips_atomically(demos: list[np.ndarray], tmp_path: object) -> None:
    data = build_counterfactual_dataset(ENV_ID, demos, n_success=20, n_failure=25, seed=1, layout_seed=0)
    assert int(data.is_demo.sum()) == len(demos)
    perturbed = ~data.is_demo
    assert int(data.success[perturbed].sum()) == 20 and int((~data.success[perturbed]).sum()) == 25
    assert set(np.unique(data.kind)) <= {KINDS.index("demo"), KINDS.index("segment")}
    assert 0 < data.meta["raw_success_rate"] < 1
    path = data.save(tmp_path / "cf.npz")  # type: ignore[operator]
    assert [p.name for p in path.parent.iterdir()] == ["cf.npz"]  # no temp file left behind
    back = CounterfactualDataset.load(path)
    np.testing.assert_array_equal(back.states, data.states)
    np.testing.assert_array_equal(back.success, data.success)
    assert back.meta["env_id"] == ENV_ID and back.meta["n_failure"] == 25
    np.testing.assert_array_equal(back.trajectory(3), data.trajectory(3))
    sub = data.subset(data.success)
    assert len(sub) == int(data.success.sum()) and bool(sub.success.all())
    np.testing.assert_array_equal(sub.trajectory(0), data.trajectory(int(np.flatnonzero(data.success)[0])))


def test_dataset_rejects_bad_arguments(demos: list[np.ndarray], tmp_path: object) -> None:
    with pytest.raises(ValueError, match="n_success"):
        build_counterfactual_dataset(ENV_ID, demos, n_success=-1, layout_seed=0)
    with pytest.raises(ValueError, match="demos"):
        build_counterfactual_dataset(ENV_ID, [], layout_seed=0)
    data = build_counterfactual_dataset(ENV_ID, demos, n_success=2, n_failure=2, seed=0, layout_seed=0)
    with pytest.raises(ValueError, match=r"\.npz"):
        data.save(tmp_path / "cf.txt")  # type: ignore[operator]


# ------------------------------------------------------------------- bounds (no hangs)
class _Hang(Exception):
    pass


@contextlib.contextmanager
def _deadline(seconds: float) -> Iterator[None]:
    """Fail instead of hanging: SIGALRM after ``seconds`` (the old code looped for ever here)."""

    def fire(*_: object) -> None:
        raise _Hang(f"still running after {seconds} s")

    old = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _far_reference(dim: int = 2) -> PerturbedReference:
    wps = np.array([[0.0, 0.0], [50.0, 50.0], [0.0, 0.0]])[:, :dim]
    return PerturbedReference(wps, "segment", 0, (0, 1), np.array([50.0, 50.0])[:dim])


@pytest.mark.parametrize("execution", ["jump", "tracking"])
def test_a_waypoint_outside_the_workspace_is_refused_up_front(execution: str) -> None:
    env = gym.make("steer_envs/PolygonNav-3Mode-v0", layout_seed=0, terminate_on_violation=False)
    replayer = CounterfactualReplayer(env, "segment", execution=execution)  # type: ignore[arg-type]
    with _deadline(20), pytest.raises(ValueError, match=r"waypoint 1 \[50.0, 50.0\] lies outside the workspace"):
        replayer.replay(_far_reference())
    with _deadline(20), pytest.raises(ValueError, match="outside the workspace"):
        replayer.replay_batch([replayer.unperturbed(np.zeros((3, 2))), _far_reference()])


def test_a_replay_that_cannot_finish_hits_its_step_bound(monkeypatch: pytest.MonkeyPatch) -> None:
    import steer_envs.data.counterfactual as cf

    assert cf.DEFAULT_MAX_REPLAY_STEPS == 100_000
    monkeypatch.setattr(cf, "DEFAULT_MAX_REPLAY_STEPS", 2000)  # the same bound, reached sooner
    env = gym.make(ENV_ID, layout_seed=0, terminate_on_violation=False).unwrapped  # no step limit at all
    still = CounterfactualReplayer(env, "segment", controller=lambda x, w: np.zeros(2, dtype=np.float32))
    ref = PerturbedReference(np.array([[0.0, 0.0], [1.0, 1.0]]), "segment", 3, (0, 1), np.ones(2))
    with _deadline(60), pytest.raises(BoundExceeded, match=r"reference 0 \(segment of demo 3\).*max_steps=2000"):
        still.replay(ref)
    short = CounterfactualReplayer(env, "segment", max_steps=5)
    with pytest.raises(BoundExceeded, match="waypoint 1 of 2 within max_steps=5"):
        short.replay(PerturbedReference(np.array([[-7.0, -7.0], [7.0, 7.0]]), "segment", 0, (0, 1), np.ones(2)))
    # the derived bound leaves room: a full-diagonal reference still completes
    full = CounterfactualReplayer(env, "segment").replay(
        PerturbedReference(np.array([[-7.0, -7.0], [7.0, 7.0]]), "segment", 0, (0, 1), np.ones(2))
    )
    np.testing.assert_allclose(full.states[-1], [7.0, 7.0], atol=1e-4)


def test_references_and_replayer_arguments_are_validated() -> None:
    env = _env()
    with pytest.raises(ValueError, match="waypoints must be finite"):  # a NaN waypoint is never reached
        PerturbedReference(np.array([[0.0, 0.0], [np.nan, 0.0]]), "segment", 0, (0, 1), np.zeros(2))
    with pytest.raises(TypeError, match="waypoints must hold real numbers"):
        PerturbedReference([["0", "0"], ["1", "1"]], "segment", 0, (0, 1), np.zeros(2))
    with pytest.raises(ValueError, match="kind"):
        PerturbedReference(np.zeros((2, 2)), "teleport", 0, (0, 1), np.zeros(2))
    with pytest.raises(TypeError, match="source"):
        PerturbedReference(np.zeros((2, 2)), "segment", "0", (0, 1), np.zeros(2))  # type: ignore[arg-type]
    replayer = CounterfactualReplayer(env, "segment")
    with pytest.raises(ValueError, match="state dimension 2"):
        replayer.replay(PerturbedReference(np.zeros((2, 3)), "segment", 0, (0, 1), np.zeros(3)))
    with pytest.raises(ValueError, match="max_steps"):
        CounterfactualReplayer(env, "segment", max_steps=0)
    with pytest.raises(TypeError, match="gripper"):
        CounterfactualReplayer(env, "segment", gripper="no")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="kernel_sharpness"):
        CounterfactualReplayer(env, "kernel", kernel_sharpness="5")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="demo must hold real numbers"):
        replayer.sample([["0", "0"], ["1", "1"]], np.random.default_rng(0))
    with pytest.raises(TypeError, match="n must be an int"):
        replayer.rollouts([np.zeros((3, 2))], 2.0, seed=0)  # type: ignore[arg-type]


@settings(max_examples=40, deadline=None)
@given(
    st.one_of(
        st.lists(
            st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=2, max_size=2), min_size=1, max_size=4
        ),
        st.lists(st.lists(st.text(max_size=3), min_size=2, max_size=2), min_size=1, max_size=3),
        st.lists(st.lists(st.complex_numbers(), min_size=2, max_size=2), min_size=1, max_size=3),
        st.lists(st.floats(-100, 100), min_size=0, max_size=4),
    )
)
def test_property_replays_of_any_reference_end_or_refuse(waypoints: object) -> None:
    """A reference either replays to its end quickly or is refused with TypeError/ValueError."""
    replayer = _PROPERTY_REPLAYER
    with _deadline(10):
        try:
            ref = PerturbedReference(waypoints, "segment", 0, (0, 1), np.zeros(2))  # type: ignore[arg-type]
            replay = replayer.replay(ref)
        except (TypeError, ValueError):
            return
    np.testing.assert_allclose(replay.states[-1], ref.waypoints[-1], atol=1e-4)


_PROPERTY_REPLAYER = CounterfactualReplayer(
    gym.make("steer_envs/PolygonNav-3Mode-v0", layout_seed=0, terminate_on_violation=False), "segment", execution="jump"
)
