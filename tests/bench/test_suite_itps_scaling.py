"""``itps-maze2d-scaling``: pilot names, the power-law extrapolation, one tiny pilot trained, resumed and scored."""

from __future__ import annotations

from pathlib import Path

import pytest

from steer_envs.bench.report import summarize
from steer_envs.bench.suite import Trial, get_suite
from steer_envs.bench.suites.itps.scaling import (
    PILOTS,
    ScalingParams,
    parse_pilot,
    pilot_checkpoint,
    run_scaling_trial,
    samples_needed,
    scaling_findings,
)


def test_pilot_names_and_params_are_checked() -> None:
    assert parse_pilot("w16@0.5M") == (16, 0.5)
    assert all(parse_pilot(p) for p in PILOTS)
    for bad in ("w12@1M", "x16@1M", "w16@-1M", "w16", 3):
        with pytest.raises(ValueError, match="pilot"):
            parse_pilot(bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="precision"):
        ScalingParams(precision="fp16")
    with pytest.raises(ValueError, match="eval_starts"):
        ScalingParams(eval_starts=0)


def test_samples_needed_extrapolates_a_falling_power_law() -> None:
    assert samples_needed([(1.0, 0.4), (4.0, 0.2)]) == pytest.approx(64.0)
    assert samples_needed([(1.0, 0.2), (4.0, 0.2)]) is None  # no fall, no estimate
    assert samples_needed([(1.0, 0.2)]) is None
    assert samples_needed([(1.0, 0.04), (2.0, 0.02)]) == pytest.approx(0.8)


def _records(values: dict[str, float]) -> list[dict[str, object]]:
    return [
        {
            "config": {"suite": "itps-maze2d-scaling", "env": None, "method": m, "params": {}},
            "seed": 0,
            "metrics": {"collision_RS": c},
        }
        for m, c in values.items()
    ]


def test_findings_read_the_curves() -> None:
    (table,) = summarize(_records({"w16@0.5M": 0.6, "w16@1M": 0.4, "w32@0.5M": 0.3, "w32@1M": 0.15}))
    falls, reach = scaling_findings(table)
    assert falls.holds is True and "w16: 0.5M 0.600, 1M 0.400" in falls.detail
    assert reach.holds is True and "w32: 3.0 M" in reach.detail  # halving per doubling: 0.05 at 0.5 * 6 M
    (table,) = summarize(_records({"w16@0.5M": 0.3, "w16@1M": 0.35}))
    falls, reach = scaling_findings(table)
    assert falls.holds is False and reach.holds is None


def test_a_tiny_pilot_trains_resumably_and_is_scored(tmp_path: Path) -> None:
    params = ScalingParams(
        batch_size=16, eval_starts=1, batch=4, cache_dir=str(tmp_path), fused_optimizer=False, walk_steps=20_000
    )
    trial = Trial(
        "itps-maze2d-scaling",
        "steer_envs/Maze2D-Large-v0",
        "w8@0.0008M",  # 50 steps of batch 16
        0,
        params.to_json(),
        "steer_envs.bench.suites.itps.scaling:run_scaling_trial",
    )
    result = run_scaling_trial(trial)
    metrics = result.metrics
    assert metrics["samples_m"] == 0.0008 and 0 < metrics["parameters_m"] < 0.5  # type: ignore[operator]
    assert all(0.0 <= metrics[f"collision_{s}"] <= 1.0 for s in ("RS", "PR", "BI", "GD", "SS"))  # type: ignore[operator]
    assert 0 <= metrics["findings_held"] <= 4  # type: ignore[operator]
    path = pilot_checkpoint(params, "w8@0.0008M", 0)
    assert (
        path.exists() and (path.parent / "state.safetensors").exists() and (path.parent / "run.json").exists() is False
    )
    mtime = path.stat().st_mtime_ns
    assert pilot_checkpoint(params, "w8@0.0008M", 0) == path and path.stat().st_mtime_ns == mtime  # not retrained
    assert (tmp_path / "maze2d-large-randomwalk-20000-seed0.npz").exists()


def test_the_suite_is_registered_with_its_pilots() -> None:
    suite = get_suite("itps-maze2d-scaling")
    assert suite.method_list() == list(PILOTS)
    assert suite.quick is None  # hours of training: never in the quick tour


def test_the_figure_is_drawn_from_the_pilots(tmp_path: Path) -> None:
    from steer_envs.bench.suites.itps.scaling import _plot

    records = _records({"w16@0.5M": 0.6, "w16@1M": 0.4})
    (path,) = _plot(get_suite("itps-maze2d-scaling"), records, str(tmp_path))
    assert Path(path).name == "itps-maze2d-scaling_collision.png" and Path(path).stat().st_size > 10_000
    assert _plot(get_suite("itps-maze2d-scaling"), [], str(tmp_path)) == []
