"""Parser, formula tree and printer: Spot syntax, precedence, errors, round trips."""

from __future__ import annotations

import copy
import pickle

import pytest
from hypothesis import given, settings
from ltl_strategies import formulas

from steer_envs import ltl
from steer_envs.ltl import LTLParseError, parse

a, b, c = ltl.Atom("a"), ltl.Atom("b"), ltl.Atom("c")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("a", a),
        ("true", ltl.TRUE),
        ("TRUE", ltl.TRUE),
        ("1", ltl.TRUE),
        ("false", ltl.FALSE),
        ("0", ltl.FALSE),
        ("!a", ltl.Not(a)),
        ("~a", ltl.Not(a)),
        ("a & b", ltl.And(a, b)),
        ("a && b", ltl.And(a, b)),
        ("a /\\ b", ltl.And(a, b)),
        ("a | b", ltl.Or(a, b)),
        ("a || b", ltl.Or(a, b)),
        ("a \\/ b", ltl.Or(a, b)),
        ("a -> b", ltl.Implies(a, b)),
        ("a => b", ltl.Implies(a, b)),
        ("a --> b", ltl.Implies(a, b)),
        ("a <-> b", ltl.Equiv(a, b)),
        ("a <=> b", ltl.Equiv(a, b)),
        ("a xor b", ltl.Xor(a, b)),
        ("a ^ b", ltl.Xor(a, b)),
        ("X a", ltl.Next(a)),
        ("Xa", ltl.Next(a)),
        ("F a", ltl.Finally(a)),
        ("<> a", ltl.Finally(a)),
        ("G a", ltl.Globally(a)),
        ("[] a", ltl.Globally(a)),
        ("[]<>a", ltl.Globally(ltl.Finally(a))),
        ("GFa", ltl.Globally(ltl.Finally(a))),
        ("a U b", ltl.Until(a, b)),
        ("a R b", ltl.Release(a, b)),
        ("a V b", ltl.Release(a, b)),
        ("a W b", ltl.WeakUntil(a, b)),
        ("a M b", ltl.StrongRelease(a, b)),
        ("a Ub", ltl.Until(a, b)),  # after an operand, U starts a binary operator (Spot)
        ("aUb", ltl.Atom("aUb")),  # ... but an identifier keeps its letters
        ("X1", ltl.Atom("X1")),  # F/G/X followed by a digit is an AP (Spot)
        ('"my ap" & "x\\"y"', ltl.And(ltl.Atom("my ap"), ltl.Atom('x"y'))),
        ("a.b_c9", ltl.Atom("a.b_c9")),
    ],
)
def test_parse_syntax(text: str, expected: object) -> None:
    assert parse(text) is expected


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        # -> and <-> bind loosest and associate to the right
        ("a -> b -> c", ltl.Implies(a, ltl.Implies(b, c))),
        ("a <-> b -> c", ltl.Equiv(a, ltl.Implies(b, c))),
        ("a | b -> c", ltl.Implies(ltl.Or(a, b), c)),
        # | < xor < & (Spot's priorities)
        ("a | b xor c", ltl.Or(a, ltl.Xor(b, c))),
        ("a xor b & c", ltl.Xor(a, ltl.And(b, c))),
        ("a xor b xor c", ltl.Xor(ltl.Xor(a, b), c)),
        ("a & b | c", ltl.Or(ltl.And(a, b), c)),
        # & < U R W M (right associative) < unary
        ("a U b & c", ltl.And(ltl.Until(a, b), c)),
        ("a U b U c", ltl.Until(a, ltl.Until(b, c))),
        ("a U b R c", ltl.Until(a, ltl.Release(b, c))),
        ("!a U b", ltl.Until(ltl.Not(a), b)),
        ("F a U b", ltl.Until(ltl.Finally(a), b)),
        ("G(a -> X b)", ltl.Globally(ltl.Implies(a, ltl.Next(b)))),
        ("!(a & b)", ltl.Not(ltl.And(a, b))),
        ("((a))", a),
        ("(a & b) & c", ltl.And(a, b, c)),  # n-ary operators flatten
        ("a & (b & c)", ltl.And(a, b, c)),
    ],
)
def test_precedence_and_associativity(text: str, expected: object) -> None:
    assert parse(text) is expected


@pytest.mark.parametrize(
    ("text", "column", "expected_fragment"),
    [
        ("a &", 4, "a formula"),
        ("a & & b", 5, "a formula"),
        ("(a | b", 7, "')' to close the '(' at column 1"),
        ("a b", 3, "a binary operator or end of input"),
        ("a)", 2, "unbalanced"),
        ("", 1, "a formula"),
        ("()", 2, "inside '()'"),
        ("a % b", 3, "a binary operator"),
        ('"abc', 1, "closing"),
        ("{a}", 1, "PSL/SERE"),
        ("12ab", 1, "not starting with a digit"),
        ("G U a", 3, "a formula"),
    ],
)
def test_parse_errors_name_column_and_expectation(text: str, column: int, expected_fragment: str) -> None:
    with pytest.raises(LTLParseError) as info:
        parse(text)
    err = info.value
    assert isinstance(err, ValueError)
    assert err.column == column
    assert expected_fragment in err.expected
    assert f"column {column}" in str(err)


def test_parse_rejects_non_text() -> None:
    with pytest.raises(TypeError, match="text"):
        parse(3)  # type: ignore[arg-type]
    assert parse(a) is a  # formulas pass through


def test_nodes_are_interned_and_immutable() -> None:
    f = parse("G(a -> F b)")
    assert f is ltl.Globally(ltl.Implies(a, ltl.Finally(ltl.Atom("b"))))
    assert hash(f) == hash(parse("G(a->Fb)"))
    with pytest.raises(AttributeError):
        f.foo = 1  # type: ignore[attr-defined]
    with pytest.raises(AttributeError):
        f._args = ()  # type: ignore[misc]
    assert pickle.loads(pickle.dumps(f)) is f
    assert copy.deepcopy(f) is f
    assert f.atoms() == {"a", "b"}
    assert f.depth == 3
    assert not f.is_boolean and parse("a & !b | c").is_boolean


def test_constructor_validation() -> None:
    with pytest.raises(TypeError, match="Formula"):
        ltl.And(a, "b")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="name"):
        ltl.Atom("")
    assert ltl.And() is ltl.TRUE and ltl.Or() is ltl.FALSE and ltl.And(a) is a
    assert (a & b) is ltl.And(a, b) and (a | b) is ltl.Or(a, b) and ~a is ltl.Not(a) and (a >> b) is ltl.Implies(a, b)


@pytest.mark.parametrize(
    "text",
    [
        "G((a -> (Xa | Xb)) & (b -> (Xa | Xb | Xc)))",
        "!(a U b) <-> (c xor d)",
        '"F" & "true" & "xor" & "U" & "1a" & "a b" & "Xa"',
        "X true & F false",
        "a U (b U c)",
        "(a U b) U c",
        "a -> (b -> c)",
        "(a -> b) -> c",
        "X1 & XX1",
    ],
)
def test_printing_round_trips(text: str) -> None:
    f = parse(text)
    assert parse(str(f)) is f


@settings(max_examples=300, deadline=None)
@given(formulas(5))
def test_printing_round_trips_on_random_formulas(f: object) -> None:
    assert parse(str(f)) is f
