"""The Kitchen study (``steer_envs.steering.kitchen``): one steered rollout per method end to end, the sweep,
the method samplers, the probe, bad input.

The policy is an untrained tiny Diffusion Policy (8-waypoint plans keep the
executed skills short): its plans do nothing in particular, so the test checks
the rollout's bookkeeping, not the study's numbers (``steer-bench run
itps-kitchen`` does those with the shipped checkpoint).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from robosuite_helpers import ROBOSUITE_MARKS

pytestmark = ROBOSUITE_MARKS


def tiny_policy(horizon: int = 8) -> Any:
    """An untrained DP with the Kitchen plan layout (17-D observation, [x, y, z, yaw, gripper] waypoints)."""
    from steer_envs.baselines.diffusion import DiffusionConfig, DiffusionPolicy

    cfg = DiffusionConfig(
        obs_dim=17,
        action_dim=5,
        horizon=horizon,
        n_obs_steps=1,
        down_dims=(8, 16),
        step_embed_dim=16,
        kernel_size=3,
        obs_embed_dim=16,
        obs_octaves=2,
        num_inference_steps=10,
        prediction="epsilon",
        relative=False,
    )
    low, high = [-0.35, -0.5, 0.8, -2.0, -1.0], [0.25, 0.6, 1.3, 2.0, 1.0]
    stats = {"observation": {"min": [-2.0] * 17, "max": [2.0] * 17}, "action": {"min": low, "max": high}}
    policy = DiffusionPolicy(cfg, stats, seed=0)
    policy.interaction_dims = (0, 1, 2)
    return policy


@pytest.fixture(scope="module")
def env() -> Iterator[Any]:
    from steer_envs.steering.kitchen import make_env

    made = make_env("microwave")
    yield made
    made.close()


@pytest.mark.parametrize("method", ["DP-RS", "DP-GD", "DP-SS", "DP-OP"])
def test_one_interaction_per_method_scores_in_range(env: Any, method: str) -> None:
    from steer_envs.steering.kitchen import decode_frame, kitchen_trial

    m, extra = kitchen_trial(
        0, tiny_policy(), method, batch=4, max_interactions=1, max_skills=1, env=env, keep_frames=True
    )
    assert m["interactions"] == 1 and m["skills"] == 1 and extra["task"] == "microwave"
    for key in ("TA", "CS", "AS", "AF", "MS", "MF", "goal"):
        assert 0.0 <= m[key] <= 1.0, key  # type: ignore[operator]
    assert sum(m[k] for k in ("AS", "AF", "MS", "MF")) == pytest.approx(1.0)  # type: ignore[misc]
    assert m["TA"] == pytest.approx(m["AS"] + m["AF"]) and m["CS"] == pytest.approx(m["AS"] + m["MS"])  # type: ignore[operator]
    assert m["latency_ms"] > 0  # type: ignore[operator]
    check_validity_and_execution(m, extra)
    (row,) = extra["interactions"]
    assert row["intended"] != row["watched"] and row["mode"] == "closed_table"
    assert row["intended"] in ("open_door", "pick_bowl") and row["click_error"] < 0.01
    first, end = extra["frames"]
    assert decode_frame(first).shape == (128, 128, 3) and np.asarray(first["plan_uv"]).shape == (8, 2)
    assert end["end"] is True


def check_validity_and_execution(m: dict[str, Any], extra: dict[str, Any]) -> None:
    """``valid`` is the share of interactions whose plan is a skill; ``executed_ok`` that of the valid ones done."""
    rows = extra["interactions"]
    assert m["valid"] == pytest.approx(np.mean([r["valid"] for r in rows]))
    valid = [r for r in rows if r["valid"]]
    assert m["executed_ok"] == (pytest.approx(np.mean([r["executed_ok"] for r in valid])) if valid else None)
    for r in rows:
        assert r["valid"] == (r["planned"] is not None) and r["regrasps"] >= 0
        assert r["executed_ok"] == (r["valid"] and r["executed"] == r["planned"] and r["success"])


def test_closed_loop_execution_is_scored_apart_from_validity(env: Any) -> None:
    from steer_envs.steering.kitchen import kitchen_trial

    m, extra = kitchen_trial(
        0, tiny_policy(), "DP-RS", batch=2, max_interactions=1, max_skills=1, env=env, execution="closed_loop"
    )
    assert m["interactions"] == 1
    check_validity_and_execution(m, extra)


def test_the_sweep_reports_a_share_per_ratio(env: Any) -> None:
    from steer_envs.steering.kitchen import guide_ratio_sweep

    out = guide_ratio_sweep(tiny_policy(), [0.0, 5.0], seeds=1, batch=2, env=env)
    assert out["ratios"] == [0.0, 5.0] and set(out["share"]) == {"DP-GD", "DP-SS"}
    assert all(0.0 <= s <= 1.0 for shares in out["share"].values() for s in shares)
    with pytest.raises(ValueError, match="ratios"):
        guide_ratio_sweep(tiny_policy(), [], env=env)
    with pytest.raises(ValueError, match="ratios"):
        guide_ratio_sweep(tiny_policy(), [-1.0], env=env)
    for bad in ([], [3], "0"):
        with pytest.raises(ValueError, match="starts"):
            guide_ratio_sweep(tiny_policy(), [1.0], starts=bad, env=env)  # type: ignore[arg-type]
    out = guide_ratio_sweep(tiny_policy(), [1.0], seeds=2, batch=2, starts=[0], env=env)
    assert {scene["mode"] for scene in out["scenes"]} <= {"closed_table"}  # the task's start state only


def test_methods_map_to_the_thesis_samplers() -> None:
    from steer_envs.steering.kitchen import make_method_sampler

    gd, ss = make_method_sampler("DP-GD"), make_method_sampler("DP-SS")
    assert (gd.name, gd.guide_ratio, gd.min_guided_t) == ("GD", 5.0, 0)
    assert (ss.name, ss.guide_ratio, ss.mcmc_steps) == ("SS", 100.0, 4)
    assert make_method_sampler("DP-RS").name == make_method_sampler("DP-OP").name == "RS"
    assert make_method_sampler("DP-GD", gd_ratio=20.0).guide_ratio == 20.0
    with pytest.raises(ValueError, match="method"):
        make_method_sampler("DP-PR")


def test_bad_trial_arguments_are_refused(env: Any) -> None:
    from steer_envs.steering.kitchen import kitchen_trial

    policy = tiny_policy()
    with pytest.raises(ValueError, match="batch"):
        kitchen_trial(0, policy, "DP-RS", batch=0, env=env)
    with pytest.raises(ValueError, match="op_distance"):
        kitchen_trial(0, policy, "DP-OP", op_distance=-0.1, env=env)
    with pytest.raises(ValueError, match="task"):
        kitchen_trial(1, policy, "DP-RS", env=env)  # seed 1 is a sink rollout; the env is the microwave one
    with pytest.raises(ValueError, match="tasks"):
        kitchen_trial(0, policy, "DP-RS", tasks="sink", env=env)
    with pytest.raises(ValueError, match="kitchen_trial: execution must be one of"):
        kitchen_trial(0, policy, "DP-RS", execution="closed", env=env)


def test_the_probe_counts_valid_and_distinct_plans_per_scene(env: Any) -> None:
    from steer_envs.steering.kitchen_probe import probe_policy

    res = probe_policy(tiny_policy(), scenes=2, samples=3, env=env)
    assert (res.scenes, res.samples) == (2, 3)
    assert 0.0 <= res.valid <= 1.0 and 0.0 <= res.distinct <= 2.0 and res.legal == 2.0
    assert set(res.skills_by_mode) == {"closed_table", "open_table"}
    assert sum(sum(c.values()) for c in res.skills_by_mode.values()) == 6
    assert set(res.distinct_by_mode) == {"closed_table", "open_table"}
    assert sum(res.distinct_by_mode.values()) == pytest.approx(2 * res.distinct)  # one scene per mode
    assert "2 scenes x 3 plans" in res.summary() and "distinct a scene)" in res.summary()
    with pytest.raises(ValueError, match="scenes"):
        probe_policy(tiny_policy(), scenes=0, env=env)


def test_the_probe_command_refuses_bad_usage(tmp_path: Any) -> None:
    from steer_envs.bench.suites.itps_kitchen.probe import main

    for argv in (["--scenes", "0"], ["--checkpoint", str(tmp_path / "missing.safetensors")]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
