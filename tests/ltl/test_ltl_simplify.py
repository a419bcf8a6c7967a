"""NNF and rewrites: shape checks and semantic equivalence on random words."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from ltl_strategies import APS, formulas, lasso_words

from steer_envs.ltl import Atom, Equiv, Formula, Implies, Not, Xor, evaluate, nnf, parse, simplify


def _is_nnf(f: Formula) -> bool:
    for g in f.subformulas():
        if isinstance(g, (Implies, Equiv, Xor)):
            return False
        if isinstance(g, Not) and not isinstance(g.arg, Atom):
            return False
    return True


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("!(a U b)", "!a R !b"),
        ("!(a W b)", "!a M !b"),
        ("!G F a", "FG!a"),
        ("!X a", "X!a"),
        ("a -> b", "!a | b"),
        ("!(a & !b)", "!a | b"),
    ],
)
def test_nnf(text: str, expected: str) -> None:
    assert nnf(text) is parse(expected)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("F F a", "F a"),
        ("G G a", "G a"),
        ("F(a U b)", "F b"),
        ("G(a R b)", "G b"),
        ("true U b", "F b"),
        ("false R b", "G b"),
        ("a U false", "false"),
        ("a W false", "G a"),
        ("a M true", "F a"),
        ("G a & G b", "G(a & b)"),
        ("F a | F b", "F(a | b)"),
        ("X a & X b", "X(a & b)"),
        ("a & !a", "false"),
        ("a | !a", "true"),
        ("b & a & b", "a & b"),
        ("a & (a | b)", "a"),
        ("F G F a", "G F a"),
        ("X true", "true"),
    ],
)
def test_rewrites(text: str, expected: str) -> None:
    assert simplify(text) is simplify(expected)


@settings(max_examples=300, deadline=None)
@given(formulas(5), st.lists(lasso_words(), min_size=10, max_size=10))
def test_nnf_and_simplify_preserve_semantics(f: Formula, words: list) -> None:
    n, s = nnf(f), simplify(f)
    assert _is_nnf(n) and _is_nnf(s)
    for prefix, loop in words:
        expected = evaluate(f, prefix, loop, aps=APS)
        assert evaluate(n, prefix, loop, aps=APS) is expected
        assert evaluate(s, prefix, loop, aps=APS) is expected, (str(f), str(s), prefix, loop)
