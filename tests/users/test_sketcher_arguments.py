"""SketchUser refuses arguments of the wrong kind (strings, bools, complex numbers) by name, never coerces them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from steer_envs.envs.maze_grid import MazeGrid, maze_map
from steer_envs.users.sketcher import SketchUser

GRID = MazeGrid(maze_map("umaze"))


@pytest.mark.parametrize(
    ("kwargs", "exc", "name"),
    [
        ({"through_wall": True}, TypeError, "through_wall"),
        ({"through_wall": "0.3"}, TypeError, "through_wall"),
        ({"min_length": "4"}, TypeError, "min_length"),
        ({"max_length": math.nan}, ValueError, "max_length"),
        ({"points": 8.0}, TypeError, "points"),
        ({"points": 10**9}, ValueError, "points"),
        ({"hand_jitter": 1 + 0j}, TypeError, "hand_jitter"),
        ({"seed": "0"}, TypeError, "seed"),
        ({"seed": 1.5}, TypeError, "seed"),
        ({"seed": -1}, ValueError, "seed"),
    ],
)
def test_constructor_arguments_are_checked_by_kind(kwargs: dict, exc: type[Exception], name: str) -> None:
    with pytest.raises(exc, match=name):
        SketchUser(GRID, **kwargs)


def test_draw_inputs_are_not_coerced() -> None:
    user = SketchUser(GRID, seed=0, points=8, min_length=2.0, max_length=4.0)
    for bad, exc in (
        (["1", "1"], TypeError),
        ([1 + 1j, 1.0], TypeError),
        ([True, True], TypeError),
        ([math.inf, 1.0], ValueError),
    ):
        with pytest.raises(exc, match="start"):
            user.draw(bad)
    with pytest.raises(ValueError, match="kind"):
        user.draw([1.0, 1.0], kind=["follow"])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="starts"):
        user.draws(np.ones((2, 3)))
    assert SketchUser(GRID, seed=np.random.SeedSequence(0)).draw([1.0, 1.0]).sketch.points.shape == (64, 2)


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.text(max_size=3), st.complex_numbers(), st.booleans(), st.floats(allow_nan=True), st.none()))
def test_property_numeric_arguments_refuse_junk(value: object) -> None:
    for name in ("through_wall", "min_length", "hand_jitter", "points"):
        try:
            SketchUser(GRID, **{name: value})
        except (TypeError, ValueError) as err:
            assert name in str(err)
        else:
            assert isinstance(value, float) and math.isfinite(value)
