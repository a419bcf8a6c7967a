"""The smoke and quick suites: planning (missing envs skipped), a real smoke trial, the throughput plot."""

from __future__ import annotations

import importlib.util

import pytest

from steer_envs.bench.executors import execute_trial
from steer_envs.bench.runner import build_request, plan_trials
from steer_envs.bench.suite import Trial, get_suite
from steer_envs.bench.suites import smoke as suites_smoke
from steer_envs.bench.suites.quick import quick_sections

TINY = {"episodes": 1, "single_steps": 100, "num_envs": 64, "vec_steps": 3}


def test_smoke_plan_skips_envs_whose_module_is_missing(monkeypatch):
    smoke = get_suite("smoke")
    target = "steer_envs/SoupScoop-v0"
    monkeypatch.setattr(
        suites_smoke, "_missing_env_module", lambda env: "steer_envs.envs.soup_scoop" if env == target else None
    )
    plan = plan_trials(smoke, build_request(smoke, seeds=2))
    envs = {t.env for t in plan.trials}
    assert target not in envs and len(plan.trials) == 2 * len(envs) == 2 * (len(smoke.env_list()) - 1)
    assert any(target in note and "does not exist" in note for note in plan.notes)


def test_smoke_params_and_trials_option():
    smoke = get_suite("smoke")
    plan = plan_trials(smoke, build_request(smoke, envs=["ConvexMode-v0"], trials=4, params={"num_envs": 256}))
    assert [t.seed for t in plan.trials] == [0, 1, 2] and plan.trials[0].env == "steer_envs/ConvexMode-v0"
    assert plan.trials[0].params == {
        "episodes": 4, "single_steps": 2000, "num_envs": 256, "vec_steps": 50, "raw_steps": 200, "render_frames": 10
    }  # fmt: skip
    with pytest.raises(ValueError, match="num_envs"):
        plan_trials(smoke, build_request(smoke, params={"num_envs": 0}))
    for bad in ({"raw_steps": 0}, {"render_frames": -1}, {"render_frames": 1001}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            plan_trials(smoke, build_request(smoke, params=bad))


def test_quick_tours_every_suite_with_quick_settings():
    quick = get_suite("quick")
    smoke = get_suite("smoke")
    assert smoke in quick_sections() and get_suite("selftest") not in quick_sections()
    plan = plan_trials(quick, build_request(quick, envs=["ConvexMode-v0", "SoupScoop-v0"]))
    smoke_trials = [t for t in plan.trials if t.suite == "smoke"]  # other suites on these envs join the tour
    assert len(smoke_trials) == 2  # quick_seeds = 1
    assert smoke_trials[0].params == {**smoke.defaults.to_json(), **smoke.quick}
    override = plan_trials(quick, build_request(quick, envs=["ConvexMode-v0"], seeds=2, params={"episodes": 5}))
    assert [t.params["episodes"] for t in override.trials if t.suite == "smoke"] == [5, 5]
    with pytest.raises(ValueError, match="no suite of the tour has parameter"):
        plan_trials(quick, build_request(quick, params={"bogus": 1}))


def _kinematic_env_with_module() -> str:
    for env in ("steer_envs/ConvexMode-v0", "steer_envs/PolygonNav-3Mode-v0", "steer_envs/SoupScoop-v0"):
        if suites_smoke._missing_env_module(env) is None:
            return env
    pytest.skip("no kinematic env module exists yet")


def test_smoke_trial_on_a_kinematic_env_is_deterministic_in_its_values():
    env = _kinematic_env_with_module()
    smoke = get_suite("smoke")
    trial = Trial("smoke", env, "expert", 0, TINY, smoke.fn)
    first, second = execute_trial(trial), execute_trial(trial)
    assert first.ok, first.error
    m = first.record["metrics"]
    assert set(m) == {x.name for x in smoke.metrics}
    assert 0.0 <= m["success_rate"] <= 1.0 and 0.0 <= m["violation_rate"] <= 1.0 and m["episode_len"] >= 1
    assert m["env_sps"] > 0 and m["vec_sps"] > 0 and m["vec_speedup"] == pytest.approx(m["vec_sps"] / m["env_sps"])
    values = [x.name for x in smoke.metrics if x.kind == "value"]
    assert {k: m[k] for k in values} == {k: second.record["metrics"][k] for k in values}


@pytest.mark.filterwarnings("ignore::DeprecationWarning", "ignore::UserWarning")
@pytest.mark.skipif(importlib.util.find_spec("robosuite") is None, reason="the robosuite extra is not installed")
def test_smoke_trial_on_a_robosuite_env_times_the_raw_sim_and_rgbd_frames():
    smoke = get_suite("smoke")
    params = {**TINY, "episodes": 0, "raw_steps": 50, "render_frames": 2}
    result = execute_trial(Trial("smoke", "steer_envs/Lift-v0", "expert", 0, params, smoke.fn))
    assert result.ok, result.error
    m = result.record["metrics"]
    assert m["env_sps"] > 0 and m["raw_sps"] > 0 and m["adapter_ratio"] == pytest.approx(m["env_sps"] / m["raw_sps"])
    assert m["rgbd_ms"] > 0 and m["vec_sps"] is None and m["success_rate"] is None  # no episodes asked for


def _record(env, seed, **metrics):
    return {"config": {"suite": "smoke", "env": env, "method": "expert", "params": TINY}, "seed": seed,
            "metrics": metrics}  # fmt: skip


def test_smoke_findings_check_the_adapter_goals():
    from steer_envs.bench.report import summarize

    lift, can = "steer_envs/Lift-v0", "steer_envs/Can-v0"
    records = [_record(lift, 0, adapter_ratio=0.97, rgbd_ms=18.0), _record(can, 0, adapter_ratio=0.85, rgbd_ms=20.0)]
    ratio, rgbd = suites_smoke.smoke_findings(summarize(records)[0])
    assert ratio.holds is False and "Can-v0" in ratio.detail and "0.85" in ratio.detail
    assert rgbd.holds is True
    kinematic_only = summarize([_record("steer_envs/ConvexMode-v0", 0, env_sps=1000.0)])[0]
    assert [f.holds for f in suites_smoke.smoke_findings(kinematic_only)] == [None, None]


def test_throughput_plot_from_records(tmp_path):
    pytest.importorskip("matplotlib")
    records = [
        {"config": {"suite": "smoke", "env": f"steer_envs/{name}", "method": "expert", "params": TINY}, "seed": s,
         "metrics": {"env_sps": 1000.0 + s, "vec_sps": vec, "vec_speedup": None if vec is None else vec / 1000}}
        for name, vec in (("ConvexMode-v0", 50_000.0), ("Maze2D-Umaze-v0", None))
        for s in range(2)
    ]  # fmt: skip
    paths = suites_smoke.plot_throughput(get_suite("smoke"), records, str(tmp_path))
    assert [p.rsplit("/", 1)[-1] for p in paths] == ["smoke_throughput.png"]
    assert (tmp_path / "smoke_throughput.png").read_bytes()[:4] == b"\x89PNG"


def test_find_spec_based_module_check():
    assert suites_smoke._missing_env_module("steer_envs/ConvexMode-v0") in (None, "steer_envs.envs.convex_mode")
    if importlib.util.find_spec("steer_envs.envs.convex_mode") is not None:
        assert suites_smoke._missing_env_module("steer_envs/ConvexMode-v0") is None
