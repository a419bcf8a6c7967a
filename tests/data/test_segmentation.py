"""Sensor-based segmentation of demonstrations into modes; attractor = mean of the last in-mode states."""

from __future__ import annotations

import numpy as np
import pytest

from steer_envs.core.task import TaskSpec
from steer_envs.data.segmentation import segment_demonstration, segment_demonstrations


def _table_demos() -> tuple[np.ndarray, np.ndarray, list[str], list[str]]:
    """The appendix table: two 10-step demos over three AP regions (red, blue, green)."""
    rng = np.random.default_rng(0)
    x1, x2 = rng.normal(size=(10, 2)), rng.normal(size=(10, 2))
    lab1 = ["red"] * 2 + ["blue"] * 4 + ["green"] * 4
    lab2 = ["red"] * 4 + ["blue"] * 5 + ["green"] * 1
    return x1, x2, lab1, lab2


def test_appendix_table_attractors() -> None:
    x1, x2, lab1, lab2 = _table_demos()
    seg = segment_demonstrations([(x1, lab1), (x2, lab2)])
    assert seg.order == ("red", "blue", "green")
    # x^{2,1} & x^{4,2}, x^{6,1} & x^{9,2}, x^{10,1} & x^{10,2} (1-based in the thesis)
    np.testing.assert_allclose(seg["red"].attractor, (x1[1] + x2[3]) / 2)
    np.testing.assert_allclose(seg["blue"].attractor, (x1[5] + x2[8]) / 2)
    np.testing.assert_allclose(seg["green"].attractor, (x1[9] + x2[9]) / 2)
    blue = seg["blue"]
    assert [len(s) for s in blue.segments] == [4, 5]
    np.testing.assert_allclose(blue.entry_states, [x1[2], x2[4]])
    np.testing.assert_allclose(blue.last_states, [x1[5], x2[8]])
    assert [s.demo for s in blue.segments] == [0, 1]
    assert set(seg.attractors) == {"red", "blue", "green"}


def test_velocities_travel_with_segments() -> None:
    x1, x2, lab1, lab2 = _table_demos()
    v1 = np.arange(20.0).reshape(10, 2)
    seg = segment_demonstrations([(x1, lab1, v1), (x2, lab2, v1 + 100)])
    np.testing.assert_allclose(seg["blue"].velocities[0], v1[2:6])
    np.testing.assert_allclose(seg["blue"].states[1], x2[4:9])
    no_vel = segment_demonstrations([(x1, lab1)])
    with pytest.raises(ValueError, match="without velocities"):
        _ = no_vel["red"].velocities


def test_sensor_rows_and_dicts_map_to_task_modes() -> None:
    task = TaskSpec(
        name="scoop",
        modes=("reach", "scoop", "transport"),
        sensors=("r", "s"),
        sensor_modes={frozenset(): "reach", frozenset({"r"}): "scoop", frozenset({"s"}): "transport"},
        transitions=frozenset({("reach", "scoop"), ("scoop", "transport")}),
    )
    x = np.linspace(0, 1, 7)[:, None] * np.ones((1, 2))
    rows = np.array([[0, 0], [0, 0], [1, 0], [1, 0], [1, 0], [0, 1], [0, 1]], dtype=bool)
    by_rows = segment_demonstrations([(x, rows)], task=task)
    assert by_rows.order == ("reach", "scoop", "transport")
    np.testing.assert_allclose(by_rows["scoop"].attractor, x[4])
    dicts = [{"r": bool(a), "s": bool(b)} for a, b in rows]
    by_dicts = segment_demonstrations([(x, dicts)], task=task)
    assert by_dicts.order == by_rows.order
    # mode indices are normalised to names with a task; without one, each sensor state is a mode
    by_index = segment_demonstrations([(x, [0, 0, 1, 1, 1, 2, 2])], task=task)
    assert by_index.order == ("reach", "scoop", "transport")
    raw = segment_demonstrations([(x, rows)])
    assert raw.order == ((False, False), (True, False), (False, True))


def test_chatter_is_merged_and_revisits_are_kept() -> None:
    x = np.arange(12.0)[:, None] * np.ones((1, 2))
    labels = [0, 0, 0, 1, 0, 0, 2, 2, 2, 0, 0, 0]  # a 1-step flicker to mode 1, then a real revisit of mode 0
    segs = segment_demonstration(x, labels, min_length=2)
    assert [(s.mode, s.start, s.stop) for s in segs] == [(0, 0, 6), (2, 6, 9), (0, 9, 12)]
    seg = segment_demonstrations([(x, labels)], min_length=2)
    np.testing.assert_allclose(seg[0].attractor, (x[5] + x[11]) / 2)  # both visits' last states
    assert len(segment_demonstration(x, labels)) == 5


def test_bad_input_is_rejected() -> None:
    x = np.zeros((5, 2))
    with pytest.raises(ValueError, match="length 5"):
        segment_demonstration(x, [0, 1])
    with pytest.raises(ValueError, match="finite"):
        segment_demonstration(np.full((5, 2), np.nan), [0] * 5)
    with pytest.raises(ValueError, match="velocities"):
        segment_demonstration(x, [0] * 5, np.zeros((4, 2)))
    with pytest.raises(ValueError, match="non-empty"):
        segment_demonstrations([])
    with pytest.raises(ValueError, match="dimension"):
        segment_demonstrations([(x, [0] * 5), (np.zeros((5, 3)), [0] * 5)])
    with pytest.raises(ValueError, match="min_length"):
        segment_demonstration(x, [0] * 5, min_length=0)
    with pytest.raises(TypeError, match="labels"):
        segment_demonstration(x, [[0], [0], [0], [0], [0]])


def test_classifier_labels_segment_like_any_other_labels() -> None:
    """GLiDE's classifier only provides per-step labels; the segmentation is this module's."""
    from steer_envs.baselines.glide import label_demonstrations, mode_entry_points

    class LeftRight:
        def predict(self, states: np.ndarray) -> np.ndarray:
            return (np.asarray(states)[:, 0] > 0).astype(np.int64)

    demo = np.stack([np.linspace(-1.0, 1.0, 11), np.zeros(11)], axis=1)
    labels = label_demonstrations(LeftRight(), [demo], 2)
    seg = segment_demonstrations([(demo, labels[0])])
    assert seg.order == (0, 1)
    np.testing.assert_array_equal(seg[1].entry_states, demo[6:7])
    np.testing.assert_array_equal(mode_entry_points([demo], labels, 2)[1], demo[6])
