"""Parser, formula tree and printer: Spot syntax, precedence, errors, round trips."""

from __future__ import annotations

import copy
import pickle

import pytest
from hypothesis import given, settings
from ltl_strategies import formulas

from steer_envs.ltl import (
    FALSE,
    TRUE,
    And,
    Atom,
    Equiv,
    Finally,
    Globally,
    Implies,
    LTLParseError,
    Next,
    Not,
    Or,
    Release,
    StrongRelease,
    Until,
    WeakUntil,
    Xor,
    parse,
)

a, b, c = Atom("a"), Atom("b"), Atom("c")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("a", a),
        ("true", TRUE),
        ("TRUE", TRUE),
        ("1", TRUE),
        ("false", FALSE),
        ("0", FALSE),
        ("!a", Not(a)),
        ("~a", Not(a)),
        ("a & b", And(a, b)),
        ("a && b", And(a, b)),
        ("a /\\ b", And(a, b)),
        ("a | b", Or(a, b)),
        ("a || b", Or(a, b)),
        ("a \\/ b", Or(a, b)),
        ("a -> b", Implies(a, b)),
        ("a => b", Implies(a, b)),
        ("a --> b", Implies(a, b)),
        ("a <-> b", Equiv(a, b)),
        ("a <=> b", Equiv(a, b)),
        ("a xor b", Xor(a, b)),
        ("a ^ b", Xor(a, b)),
        ("X a", Next(a)),
        ("Xa", Next(a)),
        ("F a", Finally(a)),
        ("<> a", Finally(a)),
        ("G a", Globally(a)),
        ("[] a", Globally(a)),
        ("[]<>a", Globally(Finally(a))),
        ("GFa", Globally(Finally(a))),
        ("a U b", Until(a, b)),
        ("a R b", Release(a, b)),
        ("a V b", Release(a, b)),
        ("a W b", WeakUntil(a, b)),
        ("a M b", StrongRelease(a, b)),
        ("a Ub", Until(a, b)),  # after an operand, U starts a binary operator (Spot)
        ("aUb", Atom("aUb")),  # ... but an identifier keeps its letters
        ("X1", Atom("X1")),  # F/G/X followed by a digit is an AP (Spot)
        ('"my ap" & "x\\"y"', And(Atom("my ap"), Atom('x"y'))),
        ("a.b_c9", Atom("a.b_c9")),
    ],
)
def test_parse_syntax(text: str, expected: object) -> None:
    assert parse(text) is expected


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        # -> and <-> bind loosest and associate to the right
        ("a -> b -> c", Implies(a, Implies(b, c))),
        ("a <-> b -> c", Equiv(a, Implies(b, c))),
        ("a | b -> c", Implies(Or(a, b), c)),
        # | < xor < & (Spot's priorities)
        ("a | b xor c", Or(a, Xor(b, c))),
        ("a xor b & c", Xor(a, And(b, c))),
        ("a xor b xor c", Xor(Xor(a, b), c)),
        ("a & b | c", Or(And(a, b), c)),
        # & < U R W M (right associative) < unary
        ("a U b & c", And(Until(a, b), c)),
        ("a U b U c", Until(a, Until(b, c))),
        ("a U b R c", Until(a, Release(b, c))),
        ("!a U b", Until(Not(a), b)),
        ("F a U b", Until(Finally(a), b)),
        ("G(a -> X b)", Globally(Implies(a, Next(b)))),
        ("!(a & b)", Not(And(a, b))),
        ("((a))", a),
        ("(a & b) & c", And(a, b, c)),  # n-ary operators flatten
        ("a & (b & c)", And(a, b, c)),
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
    assert f is Globally(Implies(a, Finally(Atom("b"))))
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
        And(a, "b")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="name"):
        Atom("")
    assert And() is TRUE and Or() is FALSE and And(a) is a
    assert (a & b) is And(a, b) and (a | b) is Or(a, b) and ~a is Not(a) and (a >> b) is Implies(a, b)


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
