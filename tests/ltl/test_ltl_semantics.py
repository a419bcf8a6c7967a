"""Reference lasso-word semantics: hand-checked cases for every operator."""

from __future__ import annotations

import numpy as np
import pytest

from steer_envs.ltl import LassoWord, evaluate, evaluate_positions

A, B, NONE, AB = {"a"}, {"b"}, set(), {"a", "b"}


@pytest.mark.parametrize(
    ("formula", "prefix", "loop", "expected"),
    [
        ("a", [A], [NONE], True),
        ("a", [NONE], [A], False),
        ("X a", [NONE], [A], True),
        ("X X a", [NONE, A], [NONE], False),
        ("X X a", [NONE, NONE], [A], True),
        ("F a", [NONE, NONE], [A], True),
        ("F a", [], [NONE], False),
        ("G a", [A], [A, A], True),
        ("G a", [A], [A, NONE], False),
        ("G F a", [], [NONE, NONE, A], True),
        ("G F a", [A, A], [NONE], False),
        ("F G a", [NONE, NONE], [A], True),
        ("F G a", [], [A, NONE], False),
        ("a U b", [A, A], [B], True),
        ("a U b", [A, NONE], [B], False),
        ("a U b", [], [A], False),  # strong: b must happen
        ("a W b", [], [A], True),  # weak: a forever is fine
        ("a W b", [A, NONE], [B], False),
        ("a R b", [], [B], True),  # b forever
        ("a R b", [B, AB], [NONE], True),  # released by a (b still holds then)
        ("a R b", [B, A], [NONE], False),  # a without b: not released in time
        ("a M b", [], [B], False),  # strong release: a must happen
        ("a M b", [B, AB], [NONE], True),
        ("a -> X b", [NONE], [NONE], True),
        ("a <-> b", [AB], [NONE], True),
        ("a xor b", [AB], [NONE], False),
        ("G(a -> F b)", [A], [A, B], True),
        ("G(a -> F b)", [B], [A], False),
    ],
)
def test_operator_cases(formula: str, prefix: list, loop: list, expected: bool) -> None:
    assert evaluate(formula, prefix, loop) is expected


def test_letter_forms_and_positions() -> None:
    aps = ("a", "b")
    # ints (with an AP order), mappings and sets are the same letters
    assert evaluate("a U b", [1, 1], [2], aps=aps) is True
    assert evaluate("a U b", [{"a": True, "b": False}], [{"b": np.bool_(True)}]) is True
    word = LassoWord.of([1], [0, 2], aps)
    assert word.letters() == (frozenset({"a"}), frozenset(), frozenset({"b"}))
    assert [word.successor(i) for i in range(3)] == [1, 2, 1]
    assert evaluate_positions("F b", word) == (True, True, True)
    assert evaluate_positions("X a", word) == (False, False, False)
    assert evaluate("F b", word) is True


def test_invalid_words() -> None:
    with pytest.raises(ValueError, match="loop"):
        evaluate("a", [A], [])
    with pytest.raises(ValueError, match="aps"):
        evaluate("a", [1], [0])
    with pytest.raises(ValueError, match="out of range"):
        evaluate("a", [4], [0], aps=("a", "b"))
    with pytest.raises(TypeError, match="letter"):
        evaluate("a", [True], [0], aps=("a",))
    with pytest.raises(ValueError, match="loop"):
        evaluate("a", [A])
    with pytest.raises(TypeError, match="LassoWord"):
        evaluate_positions("a", [A])  # type: ignore[arg-type]
