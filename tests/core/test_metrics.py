"""MA (min/avg L2), CS, TA and the aligned-success quadrants."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from steer_envs.core import (
    MotionAlignment,
    Sketch,
    aligned_success,
    constraint_satisfaction,
    motion_alignment,
    sketch_distances,
    task_alignment,
)


def test_motion_alignment_hand_computed() -> None:
    sketch = Sketch([[0.0, 0.0], [2.0, 0.0]])  # resampled to T=3: (0,0), (1,0), (2,0)
    trajs = np.array(
        [
            [[0, 0], [1, 0], [2, 0]],  # on the sketch: 0
            [[0, 1], [1, 1], [2, 1]],  # offset by 1 everywhere: 1
            [[0, 0], [1, 3], [2, 0]],  # one step 3 away: 1
            [[0, 2], [1, 2], [2, 2]],  # offset 2: 2
        ],
        dtype=float,
    )
    np.testing.assert_allclose(sketch_distances(trajs, sketch), [0.0, 1.0, 1.0, 2.0])
    ma = motion_alignment(trajs, sketch)
    assert isinstance(ma, MotionAlignment)
    assert ma == (0.0, 1.0)
    min_l2, avg_l2 = motion_alignment(trajs[1:], sketch.points, scale=4.0)
    assert min_l2 == pytest.approx(0.25) and avg_l2 == pytest.approx(4.0 / 3.0 / 4.0)


def test_motion_alignment_resamples_long_sketch_and_accepts_tensors() -> None:
    sketch = np.stack([np.linspace(0, 1, 50), np.zeros(50)], axis=1)
    trajs = np.stack([np.linspace(0, 1, 5), np.full(5, 0.5)], axis=1)[None]
    assert motion_alignment(trajs, sketch).min_l2 == pytest.approx(0.5)
    torch = pytest.importorskip("torch")
    assert motion_alignment(torch.as_tensor(trajs), sketch).avg_l2 == pytest.approx(0.5)


@pytest.mark.parametrize(
    ("trajs", "sketch", "kwargs", "exc", "match"),
    [
        (np.zeros((3, 2)), [[0, 0], [1, 1]], {}, ValueError, r"`trajs` must have shape \(B, T, d\)"),
        (np.zeros((0, 3, 2)), [[0, 0], [1, 1]], {}, ValueError, "at least one trajectory"),
        (np.full((1, 3, 2), np.nan), [[0, 0], [1, 1]], {}, ValueError, "`trajs` must be finite"),
        (np.zeros((1, 3, 2)), [[0, 0]], {}, ValueError, "`sketch` needs at least 2"),
        (np.zeros((1, 3, 2)), [[0, 0, 0], [1, 1, 1]], {}, ValueError, "`sketch` must have state dimension 2"),
        (np.zeros((1, 3, 2)), [[0, 0], [1, 1]], {"scale": 0.0}, ValueError, "`scale` must be a positive"),
        (np.zeros((1, 3, 2)), [[0, 0], [1, 1]], {"scale": np.inf}, ValueError, "`scale`"),
        (np.array([[["a", "b"]]]), [[0, 0], [1, 1]], {}, TypeError, "`trajs` must hold real numbers"),
    ],
)
def test_motion_alignment_errors(trajs: np.ndarray, sketch: list, kwargs: dict, exc: type, match: str) -> None:
    with pytest.raises(exc, match=match):
        motion_alignment(trajs, sketch, **kwargs)


def test_constraint_satisfaction_and_task_alignment() -> None:
    assert constraint_satisfaction([True, False, False, False]) == 0.75
    assert constraint_satisfaction(np.array([0, 1, 1, 1])) == 0.25
    assert constraint_satisfaction(np.zeros(3, dtype=bool)) == 1.0
    assert task_alignment([True, True, False]) == pytest.approx(2 / 3)
    assert task_alignment([1.0, 0.0]) == 0.5


@pytest.mark.parametrize(
    ("value", "exc", "match"),
    [
        ([], ValueError, "`violated` must not be empty"),
        ([[True]], ValueError, "1-D"),
        (True, ValueError, "1-D"),
        ([0, 2], ValueError, r"booleans \(or 0/1\)"),
        ([0.5], ValueError, "booleans"),
        ([np.nan], ValueError, "booleans"),
        (["yes"], TypeError, "`violated` must hold booleans"),
    ],
)
def test_flag_validation(value: object, exc: type, match: str) -> None:
    with pytest.raises(exc, match=match):
        constraint_satisfaction(value)


def test_aligned_success_reproduces_block_stacking_pr_column() -> None:
    # Thesis block stacking table, PR column: AS 33%, AF 0%, MS 67%, MF 0% -> TA 33%, CS 100%
    aligned = [True, False, False]
    success = [True, True, True]
    q = aligned_success(aligned, success)
    assert q == pytest.approx({"AS": 1 / 3, "AF": 0.0, "MS": 2 / 3, "MF": 0.0, "TA": 1 / 3, "CS": 1.0})


def test_aligned_success_hand_computed_all_quadrants() -> None:
    aligned = np.array([1, 1, 1, 0, 0, 0, 0, 1, 0, 1])
    success = np.array([1, 0, 1, 1, 0, 0, 1, 0, 0, 1])
    q = aligned_success(aligned, success)
    assert q == pytest.approx({"AS": 0.3, "AF": 0.2, "MS": 0.2, "MF": 0.3, "TA": 0.5, "CS": 0.5})
    assert q["TA"] == pytest.approx(task_alignment(aligned))
    assert q["CS"] == pytest.approx(constraint_satisfaction(~success.astype(bool)))


def test_aligned_success_errors() -> None:
    with pytest.raises(ValueError, match="same length"):
        aligned_success([True, False], [True])
    with pytest.raises(ValueError, match="`success` must not be empty"):
        aligned_success([True], [])
    with pytest.raises(ValueError, match="`aligned` must be a 1-D"):
        aligned_success([[True]], [True])


@settings(max_examples=80, deadline=None)
@given(st.lists(st.tuples(st.booleans(), st.booleans()), min_size=1, max_size=60))
def test_quadrants_partition_the_trials(pairs: list[tuple[bool, bool]]) -> None:
    aligned, success = (list(x) for x in zip(*pairs, strict=True))
    q = aligned_success(aligned, success)
    assert q["AS"] + q["AF"] + q["MS"] + q["MF"] == pytest.approx(1.0)
    assert all(0.0 <= q[key] <= 1.0 for key in q)
    assert q["TA"] == pytest.approx(task_alignment(aligned))
    assert q["CS"] == pytest.approx(1.0 - constraint_satisfaction(success))
    n = len(pairs)
    assert q["AS"] * n == pytest.approx(sum(a and s for a, s in pairs))
