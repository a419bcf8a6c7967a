"""``itps-blockstack``: Table 2.2's findings on synthetic tables, parameters, a missing policy, one real trial."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from steer_envs.bench.suites.itps_blockstack.suite import ENV_ID, SUITE_NAME, TABLE_2_2, SteerParams

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning", "ignore::UserWarning")
needs_robosuite = pytest.mark.skipif(
    importlib.util.find_spec("robosuite") is None, reason="the robosuite extra is not installed"
)
CHECKPOINT = Path(__file__).resolve().parents[2] / "baselines" / "checkpoints" / "blockstack" / "dp.safetensors"


def _record(method: str, seed: int, values: dict[str, float]) -> dict[str, Any]:
    config = {"suite": SUITE_NAME, "env": ENV_ID, "method": method, "params": {}}
    return {"config": config, "seed": seed, "metrics": dict(values), "key": f"{method}-{seed}"}


def _all_verdicts(cells: dict[str, dict[str, float]]) -> list[bool | None]:
    from steer_envs.bench.report import summarize

    (table,) = summarize([_record(m, s, v) for m, v in cells.items() for s in (0, 1)])
    return [f.holds for f in table.findings]


def _verdicts(cells: dict[str, dict[str, float]]) -> list[bool | None]:
    """Table 2.2's six findings (the safety cost's come after them)."""
    return _all_verdicts(cells)[:6]


def test_findings_check_the_safety_cost_raises_cs() -> None:
    plain = {m: {"TA": 0.8, "CS": 0.2, "AS": 0.2} for m in ("DP-GD", "DP-GD-B25", "DP-SS")}
    safer = {f"{m}+safe": {"TA": 0.8, "CS": 0.5, "AS": 0.4} for m in plain}
    assert _all_verdicts({**TABLE_2_2, **plain, **safer})[6:9] == [True, True, True]
    worse = {**safer, "DP-SS+safe": {"TA": 0.8, "CS": 0.2, "AS": 0.2}}
    assert _all_verdicts({**TABLE_2_2, **plain, **worse})[6:9] == [True, True, False]
    assert _all_verdicts({**TABLE_2_2, **plain})[6:9] == [None, None, None]


def test_findings_check_table_2_2s_trade_off() -> None:
    extra = {"DP-GD-B25": {"TA": 0.7, "CS": 0.4, "AS": 0.3}, "DP-SS": {"TA": 0.8, "CS": 0.9, "AS": 0.7}}
    thesis = {**TABLE_2_2, **extra}
    assert _verdicts(thesis) == [True] * 6
    methods = ("DP-PR", "DP-GD", "DP-GD-I50", "DP-GD-B25", "DP-SS")
    flat = {key: {"TA": 0.5, "CS": 0.5, "AS": 0.25} for key in methods}
    assert _verdicts(flat) == [False, False, True, False, False, False]
    assert _verdicts({"DP-PR": TABLE_2_2["DP-PR"]}) == [None] * 6
    # the beta-25 finding is checked on its own
    assert _verdicts({**TABLE_2_2, "DP-GD-B25": {"TA": 0.2, "CS": 0.9, "AS": 0.2}})[4] is False
    # the findings read the thesis's TA (the plan heads for the intended block), never the strict TA_skill
    no_skill = {**thesis, "DP-GD": {**thesis["DP-GD"], "TA_skill": 0.0, "AS_skill": 0.0}}
    assert _verdicts(no_skill) == [True] * 6
    assert _verdicts({**thesis, "DP-GD": {**thesis["DP-GD"], "TA": 0.3}})[0] is False
    low_pr = {**thesis, "DP-PR": {"TA": 0.3, "CS": 0.24, "AS": 0.2}, "DP-GD": {"TA": 0.5, "CS": 0.12, "AS": 0.1}}
    assert _verdicts(low_pr)[1] is True  # half of PR's CS is "far below" when PR's is low
    assert _verdicts({**low_pr, "DP-GD": {"TA": 0.5, "CS": 0.13, "AS": 0.1}})[1] is False


def test_params_refuse_bad_values() -> None:
    for bad in ({"batch": 0}, {"max_interactions": 0}, {"guide_ratio": -1.0}, {"torch_threads": -1}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            SteerParams.from_json(bad)


def test_an_unknown_method_is_refused() -> None:
    from steer_envs.steering.blockstack import make_method_sampler

    with pytest.raises(ValueError, match="unknown method 'DP-XX'"):
        make_method_sampler("DP-XX")
    assert make_method_sampler("DP-GD-I50").min_guided_t == 50
    assert make_method_sampler("DP-GD", guide_ratio=25.0).guide_ratio == 25.0
    # the guide_ratio parameter replaces the table's beta 100, never the text's beta 25
    assert make_method_sampler("DP-GD-B25").guide_ratio == 25.0
    assert make_method_sampler("DP-GD-B25", guide_ratio=50.0).guide_ratio == 25.0
    assert make_method_sampler("DP-GD-I50", guide_ratio=50.0).guide_ratio == 50.0
    assert make_method_sampler("DP-GD").use_clipped_model_output  # the suite's default
    assert not make_method_sampler("DP-GD-I50", use_clipped_model_output=False).use_clipped_model_output
    assert make_method_sampler("DP-SS").use_clipped_model_output
    assert make_method_sampler("DP-PR", use_clipped_model_output=True).name == "PR"


def test_a_missing_policy_skips_the_suite_with_a_note(tmp_path: Path) -> None:
    from steer_envs.bench.runner import run_suite

    params = {"loader": "steer_envs.no_such_module:load"}
    result = run_suite(SUITE_NAME, tmp_path / "run", seeds=[0], params=params, progress=False)
    assert result.planned == 0 and any("not available" in n for n in result.notes)


@needs_robosuite
@pytest.mark.skipif(not CHECKPOINT.is_file(), reason="the BlockStack checkpoint is not built")
def test_one_trial_scores_its_interactions() -> None:
    from steer_envs.baselines.pretrained import load_pretrained
    from steer_envs.steering.blockstack import tower_trial

    m, extra = tower_trial(0, load_pretrained("blockstack"), "DP-PR", batch=4, max_interactions=2, keep_plans=True)
    assert m["interactions"] == 2 and len(extra["interactions"]) == 2
    quadrants = sum(m[k] for k in ("AS", "AF", "MS", "MF"))  # type: ignore[misc]
    assert quadrants == pytest.approx(1.0)
    assert m["TA"] == pytest.approx(m["AS"] + m["AF"]) and m["CS"] == pytest.approx(m["AS"] + m["MS"])  # type: ignore[operator]
    assert m["TA_skill"] <= m["TA"] and m["AS_skill"] <= m["AS"]  # type: ignore[operator]
    assert all(r["aligned"] or not r["skill_aligned"] for r in extra["interactions"])  # a skill heads somewhere
    kept = extra["plans"][0]
    assert np.asarray(kept["plans"]).shape == (4, 32, 4) and len(kept["sketch"]) == 32
    assert sorted(extra["order"]) == [0, 1, 2, 3]


def test_safe_methods_name_their_sampler_and_refuse_rs() -> None:
    from steer_envs.steering.blockstack import make_method_sampler

    assert make_method_sampler("DP-GD+safe").guide_ratio == 100.0
    with pytest.raises(ValueError, match=r"unknown method 'DP-RS\+safe'.*DP-SS\+safe"):
        make_method_sampler("DP-RS+safe")
    with pytest.raises(ValueError, match="safety_weight"):
        SteerParams.from_json({"safety_weight": 0.0})


def _line_plan(start: np.ndarray, end: np.ndarray, switch_at: int, gripper: float) -> np.ndarray:
    """32 waypoints from ``start`` to ``end`` (reached at waypoint 20), the gripper ``-gripper`` then ``gripper``."""
    t = np.clip(np.arange(32) / 20, 0.0, 1.0)[:, None]
    plan = np.zeros((32, 4))
    plan[:, :3] = start + t * (end - start)
    plan[:, 3] = np.where(np.arange(32) >= switch_at, gripper, -gripper)
    return plan


@needs_robosuite
def test_the_safety_cost_guards_grasps_and_releases_in_the_scene() -> None:
    import torch

    from steer_envs.control.blockstack import classify_plan, execute_plan
    from steer_envs.data.blockstack_skills import make_env
    from steer_envs.steering.blockstack import tower_safety_cost

    env = make_env()
    try:
        env.reset(seed=1000)
        base = env.unwrapped
        cube = base.cube_pos[0].copy()
        grasp = _line_plan(base.state[:3], cube, 22, 1.0)
        assert classify_plan(env, grasp) == "pick_0"
        cost = tower_safety_cost(env)
        astray = grasp + np.array([0.1, 0.0, 0.0, 0.0])  # closes 10 cm beside the cube
        values = cost(torch.as_tensor(np.stack([grasp, astray])))
        assert values[0] < 1e-3 and values[1] > 0.05
        below = grasp - np.array([0.0, 0.0, 0.1, 0.0])  # the hand 8 cm into the table
        assert cost(torch.as_tensor(below[None]))[0] > 0.01
        # gradient: the guard pulls the stray grasp back toward the cube
        x = torch.as_tensor(astray[None]).requires_grad_(True)
        cost(x).sum().backward()
        assert x.grad is not None and x.grad[0, 22, 0] > 0

        assert execute_plan(env, grasp, home_yaw=0.0).success and base.held_cube == 0
        holding = tower_safety_cost(env)
        lift = cube[2] - base.table_z  # the hand is at the cube's centre when it holds it
        spot = np.array([*cube[:2], base.table_z + lift + 0.005])
        place = _line_plan(base.state[:3], spot, 22, -1.0)
        assert classify_plan(env, place) == "place_0_on_table"
        drop = place + np.array([0.0, 0.0, 0.15, 0.0])  # opens 15 cm up: the cube would fall
        values = holding(torch.as_tensor(np.stack([place, drop])))
        assert values[0] < 1e-3 and values[1] > 0.05
    finally:
        env.close()


def test_flow_methods_run_dps_samplers() -> None:
    from steer_envs.steering.blockstack import make_method_sampler

    for method in ("RS", "PR", "GD", "GD-I50", "GD-B25", "SS"):
        assert repr(make_method_sampler(f"FLOW-{method}", 50.0)) == repr(make_method_sampler(f"DP-{method}", 50.0))
    with pytest.raises(ValueError, match=r"unknown method 'FLOW-RS\+safe'"):
        make_method_sampler("FLOW-RS+safe")
    with pytest.raises(ValueError, match="flow_steps"):
        SteerParams.from_json({"flow_steps": -1})


@pytest.fixture(scope="module")
def tiny_blockstack_flow(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An untrained flow policy of the shipped BlockStack DP's layout and statistics: the plumbing, not the quality."""
    from steer_envs.baselines.flow import FlowConfig, FlowPolicy
    from steer_envs.baselines.pretrained import load_pretrained

    dp = load_pretrained("blockstack")
    fields = {**dp.config.to_dict(), "down_dims": (8, 16), "obs_embed_dim": 8}
    fields = {k: v for k, v in fields.items() if k in FlowConfig.field_names()}
    policy = FlowPolicy(FlowConfig.from_dict(fields), dp.stats)
    return policy.save(tmp_path_factory.mktemp("flow") / "flow.safetensors")


def test_a_missing_flow_policy_skips_only_the_flow_methods(monkeypatch: pytest.MonkeyPatch) -> None:
    from steer_envs.baselines import pretrained
    from steer_envs.bench.runner import build_request, plan_trials
    from steer_envs.bench.suite import get_suite

    missing = pretrained.ShippedCheckpoint("blockstack/no-such-flow.safetensors", "flow", "a recipe", (0, 1, 2))
    monkeypatch.setitem(pretrained.CHECKPOINTS, "blockstack-flow", missing)
    monkeypatch.setattr(pretrained, "_SHARED", {})  # not the flow another test loaded in this process
    suite = get_suite(SUITE_NAME)
    plan = plan_trials(suite, build_request(suite, methods=["DP-PR", "FLOW-PR", "FLOW-GD"], seeds=1))
    assert [t.method for t in plan.trials] == ["DP-PR"]
    (note,) = plan.notes
    assert note.startswith("skipped FLOW-PR, FLOW-GD:") and "no-such-flow" in note


@needs_robosuite
def test_a_flow_trial_steers_the_flow_policy(tiny_blockstack_flow: Path) -> None:
    from steer_envs.bench.executors import execute_trial
    from steer_envs.bench.runner import build_request, plan_trials
    from steer_envs.bench.suite import get_suite

    suite = get_suite(SUITE_NAME)
    params = {"flow_checkpoint": str(tiny_blockstack_flow), "flow_steps": 4, "batch": 4, "max_interactions": 1}
    (trial,) = plan_trials(suite, build_request(suite, methods=["FLOW-GD-I50"], seeds=1, params=params)).trials
    assert SteerParams.from_json(trial.params).policy_for("FLOW-GD-I50").num_inference_steps == 4
    outcome = execute_trial(trial)
    assert outcome.ok, outcome.error
    assert outcome.record["metrics"]["interactions"] == 1


def test_findings_check_table_2_2_on_the_flow_policy() -> None:
    extra = {"DP-GD-B25": {"TA": 0.7, "CS": 0.4, "AS": 0.3}, "DP-SS": {"TA": 0.8, "CS": 0.9, "AS": 0.7}}
    thesis = {**TABLE_2_2, **extra}
    flow = {m.replace("DP-", "FLOW-"): v for m, v in thesis.items()}
    timed = {"DP-SS": {**extra["DP-SS"], "latency_ms": 900.0}, "FLOW-SS": {**extra["DP-SS"], "latency_ms": 300.0}}
    verdicts = _all_verdicts({**thesis, **flow, **timed})
    assert verdicts[:6] == verdicts[9:15] == [True] * 6 and verdicts[15] is True
    assert _all_verdicts(thesis)[9:] == [None] * 7
    flat = {m: {"TA": 0.5, "CS": 0.5, "AS": 0.25, "latency_ms": 1000.0} for m in flow}
    assert _all_verdicts({**thesis, **flat, **{"DP-SS": timed["DP-SS"]}})[9:] == [
        False,
        False,
        True,
        False,
        False,
        False,
        False,
    ]
