"""How ``tower_trial`` runs the picked plans (``execution``) and scores validity and execution apart."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from steer_envs.bench.suites.itps_blockstack.suite import SUITE_NAME, SteerParams

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning", "ignore::UserWarning")
needs_robosuite = pytest.mark.skipif(
    importlib.util.find_spec("robosuite") is None, reason="the robosuite extra is not installed"
)
CHECKPOINT = Path(__file__).resolve().parents[2] / "baselines" / "checkpoints" / "blockstack" / "dp.safetensors"


def test_the_suite_takes_the_execution_and_declares_both_metrics() -> None:
    from steer_envs.bench.suite import get_suite

    assert SteerParams().execution == "open_loop" and SteerParams(execution="closed_loop").execution == "closed_loop"
    with pytest.raises(ValueError, match="execution"):
        SteerParams.from_json({"execution": "closed"})
    assert {"valid", "executed_ok"} <= {m.name for m in get_suite(SUITE_NAME).metrics}


@pytest.mark.parametrize("bad", ["closed", None])
def test_a_bad_execution_is_refused_before_any_env_is_made(bad: Any) -> None:
    from steer_envs.steering.blockstack import tower_trial

    with pytest.raises(ValueError, match="tower_trial: execution must be one of"):
        tower_trial(0, object(), "DP-RS", execution=bad)


@needs_robosuite
@pytest.mark.skipif(not CHECKPOINT.is_file(), reason="the BlockStack checkpoint is not built")
def test_a_closed_loop_trial_scores_validity_and_execution_apart() -> None:
    from steer_envs.baselines.pretrained import load_pretrained
    from steer_envs.steering.blockstack import tower_trial

    m, extra = tower_trial(
        0, load_pretrained("blockstack"), "DP-RS", batch=2, max_interactions=1, execution="closed_loop"
    )
    (row,) = extra["interactions"]
    assert row["valid"] == (row["planned"] is not None) and m["valid"] == float(row["valid"])
    assert row["executed_ok"] == (row["valid"] and row["executed"] == row["planned"] and row["success"])
    assert m["executed_ok"] == (float(row["executed_ok"]) if row["valid"] else None)
    assert row["regrasps"] >= 0 and np.isfinite(m["latency_ms"])  # type: ignore[arg-type]
