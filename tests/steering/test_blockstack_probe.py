"""The BlockStack policy probe: valid / distinct unsteered plans on held-out scenes, read off real sim states."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from robosuite_helpers import ROBOSUITE_MARKS

from steer_envs.steering.blockstack_probe import probe_policy

pytestmark = ROBOSUITE_MARKS
CHECKPOINT = Path(__file__).resolve().parents[2] / "baselines" / "checkpoints" / "blockstack" / "dp.safetensors"


class PickCubeZero:
    """A policy that always closes the gripper at cube 0's observed position (never opens it)."""

    def sample(self, obs: Any, n: int, generator: Any = None) -> np.ndarray:
        cube0 = np.asarray(obs, dtype=np.float32)[5:8]
        plan = np.concatenate([np.tile(cube0, (32, 1)), np.ones((32, 1), np.float32)], axis=1)
        return np.repeat(plan[None], n, axis=0)


def test_probe_reads_picks_as_valid_and_a_plan_that_never_opens_as_no_place() -> None:
    result = probe_policy(PickCubeZero(), scenes=1, states=2, samples=3)
    assert result.states == 2 and result.samples == 3
    assert result.picks_valid == 1.0 and result.places_valid == 0.0  # state 0: hand free; state 1: holding
    assert result.valid == pytest.approx(0.5) and result.distinct == pytest.approx(0.5)
    assert result.legal == pytest.approx(4.0)  # 4 cubes to pick; then 3 tops + the table to place on
    assert "valid 50.0 %" in result.summary()


@pytest.mark.parametrize("bad", [{"scenes": 0}, {"states": 0}, {"samples": 0}, {"seed": -1}])
def test_probe_refuses_bad_sizes(bad: dict[str, int]) -> None:
    with pytest.raises(ValueError, match=next(iter(bad))):
        probe_policy(PickCubeZero(), **bad)


def test_guide_sweep_refuses_bad_ratios() -> None:
    from steer_envs.steering.blockstack_probe import guide_sweep

    with pytest.raises(TypeError, match="guide_ratios"):
        guide_sweep(PickCubeZero(), [])
    with pytest.raises(ValueError, match="guide_ratios"):
        guide_sweep(PickCubeZero(), [-1.0])
    with pytest.raises(TypeError, match="use_clipped_model_output"):
        guide_sweep(PickCubeZero(), [1.0], use_clipped_model_output=1)  # type: ignore[arg-type]


@pytest.mark.skipif(not CHECKPOINT.is_file(), reason="the BlockStack checkpoint is not built")
def test_guide_sweep_scores_gd_batches_on_the_users_sketch() -> None:
    from steer_envs.baselines.pretrained import load_pretrained
    from steer_envs.steering.blockstack_probe import guide_sweep

    rows = guide_sweep(load_pretrained("blockstack"), [0.0, 5.0], scenes=1, states=1, samples=2)
    assert [r.guide_ratio for r in rows] == [0.0, 5.0]
    for row in rows:
        assert 0.0 <= row.aligned <= row.valid <= 1.0 and np.isfinite(row.cost) and row.cost > 0
