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
    assert plan.trials[0].params == {"episodes": 4, "single_steps": 2000, "num_envs": 256, "vec_steps": 50}
    with pytest.raises(ValueError, match="num_envs"):
        plan_trials(smoke, build_request(smoke, params={"num_envs": 0}))


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
