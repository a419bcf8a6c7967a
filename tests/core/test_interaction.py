"""Point / Sketch / Nudge: validation, immutability, resampling."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from steer_envs.core import Interaction, Nudge, Point, Sketch, make_interaction, resample_path

SQUARE = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]


# ----------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("cls", "good"),
    [(Point, [1.0, 2.0]), (Sketch, SQUARE), (Nudge, [[0.5, 0.5]])],
)
def test_valid_construction_stores_readonly_float64_copy(cls: type[Interaction], good: list) -> None:
    source = np.array(good, dtype=np.float32)
    obj = cls(source, dim=2)
    assert obj.array.dtype == np.float64
    assert obj.dim == 2
    np.testing.assert_allclose(obj.array, source)
    assert not obj.array.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        obj.array[0] = 7.0  # type: ignore[index]
    source[0] = 99.0  # the object owns a copy
    assert not np.any(obj.array == 99.0)
    with pytest.raises(AttributeError, match="immutable"):
        obj.foo = 1  # type: ignore[attr-defined]
    assert obj.kind == cls.__name__.lower()


def test_named_accessors() -> None:
    assert Point([1, 2]).target.tolist() == [1.0, 2.0]
    assert Sketch(SQUARE).points.shape == (3, 2)
    nudge = Nudge([[0, 0], [1, 1]])
    assert nudge.states.shape == (2, 2) and nudge.k == 2 and len(nudge) == 2


@pytest.mark.parametrize(
    ("cls", "bad", "exc", "match"),
    [
        (Point, [1.0, float("nan")], ValueError, r"Point: `target` must be finite"),
        (Point, [1.0, float("inf")], ValueError, "finite"),
        (Point, [[1.0, 2.0]], ValueError, r"`target` must have shape \(d,\)"),
        (Point, 3.0, ValueError, "1-D"),
        (Point, [], ValueError, "at least 1"),
        (Point, "ab", TypeError, "`target` must be an array of real numbers"),
        (Point, ["1", "2"], TypeError, "real numbers"),
        (Point, [True, False], TypeError, "real numbers"),
        (Point, [1 + 2j, 0], TypeError, "real numbers"),
        (Point, [object(), 1], TypeError, "real numbers"),
        (Sketch, [[0.0, 0.0]], ValueError, r"Sketch: `points` needs at least 2"),
        (Sketch, [0.0, 1.0], ValueError, "2-D"),
        (Sketch, np.zeros((3, 2, 1)), ValueError, "2-D"),
        (Sketch, [[0.0, 0.0], [1.0]], ValueError, "rectangular"),
        (Sketch, [[0.0, np.nan], [1.0, 1.0]], ValueError, "finite"),
        (Sketch, np.zeros((3, 0)), ValueError, "state dimension >= 1"),
        (Nudge, np.zeros((0, 2)), ValueError, r"Nudge: `states` needs at least 1"),
        (Nudge, [1.0, 2.0], ValueError, "2-D"),
        (Nudge, [["a", "b"]], TypeError, "real numbers"),
    ],
)
def test_bad_input_raises_naming_the_argument(cls: type, bad: object, exc: type, match: str) -> None:
    with pytest.raises(exc, match=match):
        cls(bad)


@pytest.mark.parametrize(("cls", "good"), [(Point, [1.0, 2.0]), (Sketch, SQUARE), (Nudge, [[0.5, 0.5]])])
def test_expected_dimension(cls: type[Interaction], good: list) -> None:
    with pytest.raises(ValueError, match="state dimension 3"):
        cls(good, dim=3)
    obj = cls(good)
    assert obj.validate(2) is obj
    with pytest.raises(ValueError, match="expected state dimension 3, got 2"):
        obj.validate(3)
    with pytest.raises(ValueError, match="`dim` must be a positive integer"):
        cls(good, dim=0)


def test_accepts_torch_tensors_including_ones_that_require_grad() -> None:
    torch = pytest.importorskip("torch")
    t = torch.tensor([[0.0, 1.0], [2.0, 3.0]], requires_grad=True)
    sketch = Sketch(t)
    np.testing.assert_array_equal(sketch.points, [[0.0, 1.0], [2.0, 3.0]])
    back = sketch.as_tensor()
    assert back.dtype == torch.float64 and back.shape == (2, 2)
    assert Point([1, 2]).as_tensor(dtype=torch.float32).dtype == torch.float32
    back[0, 0] = 5.0  # a tensor copy, the sketch is untouched
    assert sketch.points[0, 0] == 0.0


def test_equality_hash_and_pickle_roundtrip() -> None:
    a, b = Sketch(SQUARE), Sketch(np.array(SQUARE))
    assert a == b and hash(a) == hash(b)
    assert a != Sketch([[0, 0], [1, 0], [1, 2]])
    assert Nudge(SQUARE) != a  # same data, different kind
    assert len({a, b, Point([0, 0])}) == 2
    c = pickle.loads(pickle.dumps(a))
    assert c == a and not c.points.flags.writeable
    assert "Sketch(points=" in repr(a)


def test_make_interaction() -> None:
    assert make_interaction("point", [1, 2]) == Point([1, 2])
    assert isinstance(make_interaction("sketch", SQUARE, dim=2), Sketch)
    assert isinstance(make_interaction("nudge", [[0, 0]]), Nudge)
    with pytest.raises(ValueError, match="`kind` must be one of"):
        make_interaction("wave", [1, 2])
    with pytest.raises(ValueError, match="state dimension 3"):
        make_interaction("point", [1, 2], dim=3)


# ----------------------------------------------------------------- resampling
def test_resample_hand_computed() -> None:
    # idx = linspace(0, 2, 5) = [0, .5, 1, 1.5, 2]
    out = resample_path(SQUARE, 5)
    np.testing.assert_allclose(out, [[0, 0], [0.5, 0], [1, 0], [1, 0.5], [1, 1]])
    # down-sampling 5 -> 3 keeps indices 0, 2, 4
    path = np.arange(10.0).reshape(5, 2)
    np.testing.assert_allclose(resample_path(path, 3), path[[0, 2, 4]])
    # uniform in index, not arc length: a long second segment still gets half the points
    skew = [[0.0, 0.0], [0.1, 0.0], [10.0, 0.0]]
    np.testing.assert_allclose(resample_path(skew, 5)[:, 0], [0.0, 0.05, 0.1, 5.05, 10.0])
    # n == 1 -> first point; n == G -> identity
    np.testing.assert_allclose(resample_path(SQUARE, 1), [[0.0, 0.0]])
    np.testing.assert_allclose(resample_path(SQUARE, 3), SQUARE)


def test_resample_errors() -> None:
    with pytest.raises(ValueError, match="`n` must be a positive integer"):
        resample_path(SQUARE, 0)
    with pytest.raises(ValueError, match="`n`"):
        resample_path(SQUARE, 2.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="`n` must be an integer >= 2"):
        Sketch(SQUARE).resample(1)
    with pytest.raises(ValueError, match="`path` must be finite"):
        resample_path([[0, 0], [np.nan, 1]], 3)


def test_sketch_resample_returns_sketch_and_arc_length() -> None:
    s = Sketch(SQUARE).resample(7)
    assert isinstance(s, Sketch) and len(s) == 7
    assert Sketch(SQUARE).arc_length() == pytest.approx(2.0)
    assert s.arc_length() == pytest.approx(2.0)  # linear interpolation keeps the polyline


finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(
    path=st.integers(2, 12).flatmap(lambda g: arrays(np.float64, (g, 3), elements=finite)),
    n=st.integers(2, 40),
)
def test_resample_properties(path: np.ndarray, n: int) -> None:
    out = Sketch(path).resample(n).points
    assert out.shape == (n, 3)
    np.testing.assert_allclose(out[0], path[0])
    np.testing.assert_allclose(out[-1], path[-1], atol=1e-9)
    # every resampled point lies inside the bounding box of the path
    assert np.all(out >= path.min(axis=0) - 1e-9) and np.all(out <= path.max(axis=0) + 1e-9)
    # resampling to the same length is the identity
    np.testing.assert_allclose(Sketch(path).resample(len(path)).points, path, atol=1e-9)
