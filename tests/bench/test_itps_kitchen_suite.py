"""``itps-kitchen``: registration, Table 2.3's findings on synthetic tables, parameters, a missing policy, figures."""

from __future__ import annotations

import base64
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_helpers import check_figures

from steer_envs.bench.suites.itps_kitchen.suite import ENV_ID, SUITE_NAME, TABLE_2_3, SteerParams

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning", "ignore::UserWarning")


def _record(method: str, seed: int, values: dict[str, Any], **extra: Any) -> dict[str, Any]:
    config = {"suite": SUITE_NAME, "env": ENV_ID, "method": method, "params": {}}
    return {"config": config, "seed": seed, "metrics": dict(values), "key": f"{method}-{seed}", "extra": extra}


def _verdicts(cells: dict[str, dict[str, float]]) -> list[bool | None]:
    from steer_envs.bench.report import summarize

    (table,) = summarize([_record(m, s, v) for m, v in cells.items() for s in (0, 1)])
    return [f.holds for f in table.findings]


def test_the_suite_is_registered_beside_the_data_suite() -> None:
    from steer_envs.bench.suite import BUILTIN_SUITE_MODULES, get_suite

    assert "steer_envs.bench.suites.itps_kitchen.suite" in BUILTIN_SUITE_MODULES
    suite = get_suite(SUITE_NAME)
    assert suite.methods == ("DP-RS", "DP-GD", "DP-SS", "DP-OP") and suite.envs == (ENV_ID,)
    assert get_suite("itps-kitchen-data").envs == (ENV_ID,)
    assert suite.quick is None  # a trial runs whole skills on the arm: too slow for the quick tour
    assert len(suite.references) == 24 and {r.source for r in suite.references} == {"thesis Table 2.3"}
    for values in TABLE_2_3.values():
        assert sum(values[k] for k in ("AS", "AF", "MS", "MF")) == pytest.approx(1.0, abs=0.011)
    params = SteerParams()
    assert (params.gd_ratio, params.ss_ratio, params.tasks) == (5.0, 100.0, ("microwave", "sink"))
    assert params.execution == "open_loop" and SteerParams(execution="closed_loop").execution == "closed_loop"
    assert {"valid", "executed_ok"} <= {m.name for m in suite.metrics}


def test_findings_check_table_2_3() -> None:
    assert _verdicts(TABLE_2_3) == [True, True, True]
    flat = {m: {"TA": 0.5, "CS": 0.5, "AS": 0.25} for m in TABLE_2_3}
    assert _verdicts(flat) == [False, True, True]
    strong_gd = {**TABLE_2_3, "DP-GD": {"TA": 0.6, "CS": 0.8, "AS": 0.5}}
    assert _verdicts(strong_gd) == [True, True, False]
    assert _verdicts({"DP-RS": TABLE_2_3["DP-RS"]}) == [None, None, None]


@pytest.mark.parametrize(
    "bad",
    [
        {"batch": 0},
        {"max_interactions": 0},
        {"max_skills": 0},
        {"gd_ratio": -1.0},
        {"ss_ratio": -0.5},
        {"op_distance": 2.0},
        {"tasks": ["bake"]},
        {"torch_threads": -1},
        {"accelerate": "jit"},
        {"execution": "closed"},
    ],
)
def test_params_refuse_bad_values(bad: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match=next(iter(bad))):
        SteerParams.from_json(bad)


def test_a_missing_policy_skips_the_suite_with_a_note(tmp_path: Path) -> None:
    from steer_envs.bench.runner import run_suite

    params = {"loader": "steer_envs.no_such_module:load"}
    result = run_suite(SUITE_NAME, tmp_path / "run", seeds=[0], params=params, progress=False)
    assert result.planned == 0 and any("not available" in n for n in result.notes)


def test_figures_are_written_and_readable(tmp_path: Path, saved: list[Any]) -> None:
    from steer_envs.bench.suite import get_suite
    from steer_envs.bench.suites.itps_kitchen.plots import plot_kitchen, plot_sweep

    image = np.full((32, 32, 3), 200, dtype=np.uint8)
    frame = {"shape": [32, 32, 3], "rgb": base64.b64encode(image.tobytes()).decode("ascii")}
    step = {
        **frame,
        "pixel": [10.0, 12.0],
        "plan_uv": np.linspace([5.0, 5.0], [20.0, 25.0], 8).tolist(),
        "grip": [-1.0] * 4 + [1.0] * 4,
        "watched": "open_door",
        "intended": "pick_bowl",
        "planned": "pick_bowl",
        "aligned": True,
        "success": True,
    }
    records = []
    for method in ("DP-RS", "DP-SS"):
        metrics = {"TA": 0.5, "CS": 0.5, "AS": 0.4, "AF": 0.1, "MS": 0.1, "MF": 0.4}
        records.append(_record(method, 0, metrics, task="sink", frames=[step, {**frame, "end": True, "goal": False}]))
    written = plot_kitchen(get_suite(SUITE_NAME), records, str(tmp_path))
    assert sorted(Path(w).name for w in written) == ["itps-kitchen_quadrants.png", "itps-kitchen_rollout.png"]
    sweep = {"ratios": [1.0, 5.0, 100.0], "share": {"DP-GD": [0.1, 0.2, 0.1], "DP-SS": [0.1, 0.4, 0.8]}, "batch": 4}
    assert plot_sweep(sweep, tmp_path / "sweep.png").stat().st_size > 5_000
    check_figures(saved, 3)


def test_the_sweep_command_refuses_bad_usage(tmp_path: Path) -> None:
    from steer_envs.bench.suites.itps_kitchen.sweep import main

    for argv in (["--ratios", "1,x"], ["--ratios", "-1"], ["--seeds", "0"], ["--starts", "3"], ["--starts", "a"]):
        with pytest.raises(SystemExit) as exc:
            main([*argv, "--out", str(tmp_path)])
        assert exc.value.code == 2
    assert main(["--checkpoint", str(tmp_path / "absent.safetensors"), "--out", str(tmp_path)]) == 2
