"""Hypothesis strategies shared by the LTL tests: random formulas and lasso words."""

from __future__ import annotations

import random

from hypothesis import strategies as st

from steer_envs.ltl.syntax import BINARY_OPERATORS, FALSE, TRUE, UNARY_OPERATORS, Atom, Formula

APS = ("p0", "p1", "p2")
UNARY = UNARY_OPERATORS
BINARY = BINARY_OPERATORS


def formulas(depth: int = 5, aps: tuple[str, ...] = APS, *, top: bool = True) -> st.SearchStrategy[Formula]:
    """Random formulas over ``aps`` with operator nesting depth <= ``depth`` (every LTL operator).

    The root is always an operator and inner nodes are operators 5 times out of
    6, so most formulas reach depth 3-5.
    """
    leaves = st.sampled_from([Atom(a) for a in aps] + [TRUE, FALSE])
    if depth == 0:
        return leaves
    sub = formulas(depth - 1, aps, top=False)
    unary = st.builds(lambda op, a: op(a), st.sampled_from(UNARY), sub)
    binary = st.builds(lambda op, a, b: op(a, b), st.sampled_from(BINARY), sub, sub)
    if top:
        return st.one_of(unary, binary, binary)
    return st.one_of(unary, binary, binary, unary, binary, leaves)


def random_formula(rng: random.Random, depth: int = 5, aps: tuple[str, ...] = APS) -> Formula:
    """A random formula from Python's ``random`` (for the long, non-shrinking fuzz run)."""
    if depth == 0 or rng.random() < 0.1:
        return rng.choice([*(Atom(a) for a in aps), TRUE, FALSE])
    if rng.random() < 0.4:
        return rng.choice(UNARY)(random_formula(rng, depth - 1, aps))
    return rng.choice(BINARY)(random_formula(rng, depth - 1, aps), random_formula(rng, depth - 1, aps))


def lasso_words(
    num_aps: int = 3, max_prefix: int = 4, max_loop: int = 4
) -> st.SearchStrategy[tuple[list[int], list[int]]]:
    """Random ultimately periodic words ``(prefix, loop)`` of valuation ints over ``num_aps`` APs."""
    letter = st.integers(0, (1 << num_aps) - 1)
    return st.tuples(st.lists(letter, max_size=max_prefix), st.lists(letter, min_size=1, max_size=max_loop))
