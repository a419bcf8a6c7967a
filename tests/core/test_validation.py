"""The shared argument checks (core.validation) and the core value objects built on them refuse bad input clearly.

Property tests throw random bad values at every helper and at Point / Sketch /
Nudge / TaskSpec / the metrics: each call ends in a result or a ``TypeError`` /
``ValueError`` naming the argument, never in a coerced value.
"""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from steer_envs.core.interaction import Nudge, Point, Sketch, make_interaction
from steer_envs.core.metrics import constraint_satisfaction, motion_alignment
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import (
    BoundExceeded,
    bool_array,
    boolean,
    frozen_array,
    integer,
    one_of,
    real_array,
    real_scalar,
)
from steer_envs.steering.objectives import nudge_cost, point_cost

# values that are no real number (or no array of them) in any numeric slot
NOT_REAL = [
    "0.5",
    ["1", "2"],
    b"12",
    1 + 2j,
    [1 + 0j, 2],
    np.array([1.0, 2.0], dtype=object),
    [object(), 1.0],
    {"x": 1.0},
    {1.0, 2.0},
    None,
    np.array([True, False]),
    [True, False],
    torch.tensor([1.0, 2.0], dtype=torch.complex64),
    torch.tensor([True, False]),
]


@pytest.mark.parametrize("bad", NOT_REAL, ids=lambda v: type(v).__name__)
def test_real_array_refuses_anything_that_is_no_real_number(bad: object) -> None:
    with pytest.raises(TypeError, match="delta"):
        real_array(bad, "delta", owner="Env.perturb")


def test_real_array_reads_tensors_detached_and_keeps_values() -> None:
    t = torch.tensor([0.25, -1.5], requires_grad=True)
    out = real_array(t, "action")
    assert out.dtype == np.float64 and out.tolist() == [0.25, -1.5] and out.flags.writeable
    assert real_array(torch.tensor([1.0], dtype=torch.bfloat16), "a").tolist() == [1.0]
    with pytest.raises(ValueError, match="finite"):
        real_array([1.0, math.nan], "action")
    with pytest.raises(ValueError, match=r"shape \(2,\)"):
        real_array([1.0, 2.0, 3.0], "action", shape=(2,))
    with pytest.raises(ValueError, match="rectangular"):
        real_array([[1.0], [1.0, 2.0]], "plans")


def test_frozen_arrays_cannot_be_made_writable() -> None:
    for arr in (np.arange(6.0).reshape(2, 3), np.zeros((0, 2)), real_array([1, 2], "x", readonly=True)):
        frozen = frozen_array(arr) if arr.flags.writeable else arr
        assert not frozen.flags.writeable
        with pytest.raises(ValueError):
            frozen.setflags(write=True)
        np.testing.assert_array_equal(frozen, arr)


def test_bool_array_takes_real_bools_only() -> None:
    assert bool_array(np.array([True, False]), "mask", shape=(2,)).tolist() == [True, False]
    for bad in ([1, 0], ["no", "yes"], [0.0, 1.0], "yes", None, [None, True]):
        with pytest.raises(TypeError, match="mask"):
            bool_array(bad, "mask")
    with pytest.raises(ValueError, match="shape"):
        bool_array([True], "mask", shape=(2,))


def test_scalar_helpers_name_the_argument() -> None:
    assert real_scalar(np.float32(0.5), "p", low=0.0, high=1.0) == 0.5
    assert integer(np.int64(3), "n", low=1) == 3 and isinstance(integer(np.int64(3), "n"), int)
    assert boolean(np.bool_(False), "flag") is False
    for bad, exc in (("no", TypeError), (1, TypeError), (None, TypeError)):
        with pytest.raises(exc, match="flag"):
            boolean(bad, "flag")
    with pytest.raises(TypeError, match="n must be an int"):
        integer(True, "n")
    with pytest.raises(ValueError, match="choice"):
        one_of(["unhashable"], "choice", {"a", "b"})
    assert issubclass(BoundExceeded, RuntimeError)


@settings(max_examples=150, deadline=None)
@given(
    st.one_of(
        st.text(max_size=5),
        st.complex_numbers(allow_nan=True),
        st.lists(st.one_of(st.text(max_size=3), st.complex_numbers(), st.none(), st.booleans()), min_size=1),
        st.floats(allow_nan=True, allow_infinity=True),
        st.integers(),
        st.none(),
        st.booleans(),
    )
)
def test_property_helpers_refuse_or_return_exactly(value: object) -> None:
    """Whatever comes in: a real number comes back unchanged, anything else is a clean TypeError/ValueError."""
    for helper in (lambda v: real_scalar(v, "x"), lambda v: integer(v, "x"), lambda v: real_array(v, "x")):
        try:
            out = helper(value)
        except (TypeError, ValueError) as err:
            assert "x" in str(err)
        else:
            assert not isinstance(value, (str, bool, complex)) and value is not None
            if isinstance(out, float):  # an int comes back as its nearest float (2**53 + 1 -> 2**53)
                assert math.isfinite(out) and out == float(value)  # type: ignore[arg-type]


# ------------------------------------------------------------------ value objects
@pytest.mark.parametrize(
    ("cls", "data"), [(Point, [1.0, 2.0]), (Sketch, [[0.0, 0.0], [1.0, 1.0]]), (Nudge, [[0.5, 0.5]])]
)
def test_interaction_arrays_stay_read_only_and_hashes_stable(cls: type, data: list) -> None:
    obj = cls(data)
    h = hash(obj)
    with pytest.raises(ValueError):
        obj.array.setflags(write=True)
    with pytest.raises(ValueError):
        obj.array[...] = 7.0
    assert hash(obj) == h and hash(pickle.loads(pickle.dumps(obj))) == h
    assert not pickle.loads(pickle.dumps(obj)).array.flags.writeable


@pytest.mark.parametrize("bad", NOT_REAL, ids=lambda v: type(v).__name__)
def test_interactions_refuse_coercion(bad: object) -> None:
    with pytest.raises((TypeError, ValueError), match="target"):
        Point(bad)


def test_interactions_accept_tensors_that_require_grad() -> None:
    t = torch.tensor([[0.0, 1.0], [2.0, 3.0]], requires_grad=True)
    assert Sketch(t) == Sketch(t.detach().numpy())
    with pytest.raises(TypeError, match="dim"):
        Point([1.0, 2.0]).validate("2")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="kind"):
        make_interaction(["point"], [1.0])  # type: ignore[arg-type]


@settings(max_examples=120, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.floats(allow_nan=True, allow_infinity=True),
            st.text(max_size=3),
            st.booleans(),
            st.complex_numbers(),
            st.none(),
        ),
        min_size=2,
        max_size=6,
    )
)
def test_property_sketch_is_valid_or_refused(values: list) -> None:
    pts = [values[: len(values) // 2 * 2][i : i + 2] for i in range(0, len(values) // 2 * 2, 2)]
    try:
        sketch = Sketch(pts)
    except (TypeError, ValueError) as err:
        assert "points" in str(err)
    else:
        assert all(isinstance(v, float) and math.isfinite(v) for v in values[: len(pts) * 2])
        assert not sketch.points.flags.writeable


# ---------------------------------------------------------------------- task spec
TASK = TaskSpec(
    name="t",
    modes=("idle", "busy"),
    sensors=("on",),
    sensor_modes={frozenset(): "idle", frozenset({"on"}): "busy"},
    transitions=frozenset({("idle", "busy")}),
)


@pytest.mark.parametrize("bad", ["False", "True", math.nan, 1, 0, None, [True]])
def test_task_sensor_readings_must_be_real_bools(bad: object) -> None:
    with pytest.raises(TypeError, match="on"):
        TASK.mode_of({"on": bad})
    assert TASK.mode_of({"on": np.bool_(False)}) == "idle"


def test_task_spec_refuses_names_that_are_no_strings() -> None:
    with pytest.raises(TypeError, match="modes"):
        TaskSpec(name="t", modes="ab")
    with pytest.raises(TypeError, match="modes"):
        TaskSpec(name="t", modes=(1, 2))  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="name"):
        TaskSpec(name=3, modes=("a",))  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="transitions"):
        TaskSpec(name="t", modes=("a", "b"), transitions=frozenset({"ab"}))  # type: ignore[arg-type]
    assert TaskSpec(name="t", modes=("a", "done"), goal="done").goal == ("done",)


# --------------------------------------------------------------- metrics, costs
def test_metric_and_cost_arguments_are_checked_by_kind() -> None:
    with pytest.raises(TypeError, match="scale"):
        motion_alignment(np.zeros((1, 3, 2)), [[0, 0], [1, 1]], scale="2")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="trajs"):
        motion_alignment("abc", [[0, 0], [1, 1]])
    with pytest.raises(TypeError, match="atol"):
        nudge_cost(torch.zeros(1, 3, 2), Nudge([[0.0, 0.0]]), atol="0.1")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="target"):
        point_cost(torch.zeros(1, 3, 2), torch.tensor([1 + 1j, 0j]))
    with pytest.raises(TypeError, match="violated"):
        constraint_satisfaction(["no"])
