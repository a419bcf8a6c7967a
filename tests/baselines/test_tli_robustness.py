"""The TLI robustness protocol: push schedules, drawn soup-scooping demos, paired scoop trials."""

from __future__ import annotations

import json

import numpy as np
import pytest

from steer_envs.bench.suites.tli.robustness import THESIS_SCOOP, WORKSPACE_SIZE, scoop_trial
from steer_envs.core.validation import BoundExceeded
from steer_envs.data.pushes import perturbation_schedule
from steer_envs.data.tli_demos import drawn_scoop_demos
from steer_envs.envs.soup_scoop import SoupScoopModel


def test_perturbation_schedule_is_finite_uniform_and_bounded() -> None:
    rng = np.random.default_rng(0)
    pushes = perturbation_schedule(rng, 5, 800, WORKSPACE_SIZE)
    steps = [s for s, _ in pushes]
    assert len(pushes) == 5 and steps == sorted(set(steps)) and 1 <= steps[0] and steps[-1] <= 800
    many = perturbation_schedule(np.random.default_rng(1), 4000, 10_000, 16.0)
    d = np.stack([delta for _, delta in many])
    size = np.linalg.norm(d, axis=1)
    assert size.max() <= 16.0 and size.mean() == pytest.approx(8.0, abs=0.4)  # uniform in [0, 16]
    unit = d / size[:, None]
    assert np.linalg.norm(unit.mean(axis=0)) < 0.05  # no preferred direction
    angles = np.arctan2(unit[:, 1], unit[:, 0])
    counts, _ = np.histogram(angles, bins=8, range=(-np.pi, np.pi))
    assert counts.min() > 0.8 * counts.mean()
    assert perturbation_schedule(rng, 0, 10, 16.0) == []
    with pytest.raises(ValueError, match="push_window"):
        perturbation_schedule(rng, 5, 3, 16.0)
    with pytest.raises(ValueError, match="magnitude"):
        perturbation_schedule(rng, 1, 10, -1.0)
    with pytest.raises(ValueError, match="n must be"):
        perturbation_schedule(rng, -1, 10, 1.0)


def test_drawn_demos_visit_the_modes_in_order_through_the_guards() -> None:
    model = SoupScoopModel()
    demos = drawn_scoop_demos(3, 2)
    assert len(demos) == 2
    for demo in demos:
        assert demo.success and demo.modes[0] == 0 and demo.modes[-1] == 3
        assert np.all(np.diff(demo.modes) >= 0) and set(demo.modes.tolist()) == {0, 1, 2, 3}
        assert np.linalg.norm(demo.actions, axis=1).max() < 10.0  # within SoupScoop's speed limit
        np.testing.assert_allclose(demo.states[1:], demo.states[:-1] + 0.01 * demo.actions, atol=1e-9)
        entered = demo.states[1:][np.diff(demo.modes) > 0]
        for name, x in zip(("yellow", "pink", "green"), entered, strict=True):
            x0, y0, x1, y1 = model.rects[name]
            assert x0 <= x[0] <= x1 and y0 <= x[1] <= y1  # a rectangle guard, not an attractor disc
    again = drawn_scoop_demos(3, 2)
    np.testing.assert_array_equal(again[0].states, demos[0].states)  # deterministic in the seed
    with pytest.raises(ValueError, match="n must be"):
        drawn_scoop_demos(0, 0)


def test_scoop_trial_is_paired_and_reports_the_protocol() -> None:
    plain = scoop_trial(0, False, 3, n_demos=1, max_steps=3000, record=True)
    mod = scoop_trial(0, True, 3, n_demos=1, max_steps=3000, record=True)
    for r in (plain, mod):
        assert set(r) >= {"success", "steps", "invariance_failures", "mode_reentries", "pushes", "num_cuts"}
        assert r["n_demos"] == 1 and 0 <= r["pushes"] <= 3 and r["steps"] <= 3000
    assert plain["num_cuts"] == 0  # no modulation, no cuts (failures are still counted)
    assert plain["success"] == 1.0 and mod["success"] == 1.0
    # paired runs: same start state and push schedule (the first push hits the same step in both)
    assert plain["trajectory"][0][0] == mod["trajectory"][0][0]
    assert plain["push_log"][0]["step"] == mod["push_log"][0]["step"]
    json.dumps(plain, allow_nan=False)  # records must be JSON
    assert len(plain["trajectory"]) == len(plain["push_log"]) + 1  # one segment per push, plus the first
    assert set(plain["attractors"]) == {"a", "b", "c", "d"} and plain["cuts"] == {}
    assert THESIS_SCOOP["experiments"] == 10
    with pytest.raises(TypeError, match="modulation"):
        scoop_trial(0, 1, 1)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="seed"):
        scoop_trial("0", True, 1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="demos"):
        scoop_trial(0, True, 1, n_demos=1, demos="video")
    with pytest.raises(ValueError, match="max_steps"):
        scoop_trial(0, True, 1, max_steps=0)


@pytest.mark.slow
def test_ten_experiments_modulation_never_loops_twice() -> None:
    """Thesis 3.7.2 over 20 experiments with 5 pushes: LTL-DS+mod always succeeds; plain sequencing loops."""
    plain = [scoop_trial(s, False, 5) for s in range(20)]
    mod = [scoop_trial(s, True, 5) for s in range(20)]
    assert all(r["success"] == 1.0 for r in mod)
    assert sum(r["invariance_failures"] for r in mod) < sum(r["invariance_failures"] for r in plain)
    assert max(r["invariance_failures"] for r in plain) > 20  # a discrete loop without modulation


# ---------------------------------------------------------------- bounded rejection loops
class _Nowhere:
    """A mode that contains nothing: every rejection-sampling loop over it must give up."""

    demo_start = attractor = np.zeros(2)
    low, high = np.full(2, -1.0), np.full(2, 1.0)
    vertices = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])

    def inside(self, x: np.ndarray) -> np.ndarray:
        return np.zeros(len(np.atleast_2d(x)), dtype=bool)


def test_rejection_loops_give_up_with_a_named_bound(monkeypatch: pytest.MonkeyPatch) -> None:
    from steer_envs.baselines.lpv_ds import single_mode
    from steer_envs.data import tli_demos

    monkeypatch.setattr(single_mode, "MAX_DRAWS", 50)
    monkeypatch.setattr(tli_demos, "MAX_DRAWS", 50)
    with pytest.raises(BoundExceeded, match="MAX_DRAWS=50"):
        single_mode.sample_starts(_Nowhere(), np.zeros((3, 2)), 1.0, 4, np.random.default_rng(0))
    assert single_mode.sample_starts(_Nowhere(), np.zeros((3, 2)), 1.0, 0, np.random.default_rng(0)).shape == (0, 2)
    monkeypatch.setattr(tli_demos, "_make_env", lambda seed: _FakeEnv())
    with pytest.raises(BoundExceeded, match="control points inside the mode within MAX_DRAWS=50"):
        tli_demos.convex_mode_demos(0, 1)  # "drawn" demos: control points by rejection
    with pytest.raises(ValueError, match="max_cuts"):
        single_mode.cut_loop(lambda x: -x, _Nowhere(), np.zeros((1, 2)), max_cuts=-1)
    with pytest.raises(TypeError, match="n_steps"):
        single_mode.rollout(lambda x: -x, _Nowhere(), np.zeros((1, 2)), n_steps=10.5)  # type: ignore[arg-type]


class _FakeEnv:
    class unwrapped:
        model = _Nowhere()

    def close(self) -> None:
        pass


def test_drawn_scoop_demos_and_schedules_validate_their_bounds() -> None:
    with pytest.raises(TypeError, match="max_tries"):
        drawn_scoop_demos(0, 1, max_tries=2.5)  # type: ignore[arg-type]
    with pytest.raises(BoundExceeded, match=r"drew only 0 of 1 .* max_tries \* n = 1 tries"):
        drawn_scoop_demos(4, 1, max_tries=1)  # seed 4's first drawing is redrawn
    with pytest.raises(TypeError, match="magnitude"):
        perturbation_schedule(np.random.default_rng(0), 1, 10, "16")  # type: ignore[arg-type]
