"""Negation normal form and language-preserving rewrites of LTL formulas.

:func:`nnf` pushes negations down to atoms using the dualities
``!X a = X !a``, ``!(a U b) = !a R !b``, ``!(a W b) = !a M !b``, ``!F a = G !a``
(and back), and removes ``->``, ``<->`` and ``xor``.

:func:`simplify` returns an equivalent NNF formula after the usual bottom-up
rewrites (Spot's "basic" rules, a subset): constant folding, idempotence and
complementary literals in ``&``/``|``, sorted deduplicated operands, and
temporal identities such as ``F F a = F a``, ``G(a R b) = G b``,
``F(a U b) = F b``, ``false R b = G b``, ``true U b = F b``, ``G a & G b =
G(a & b)``, ``F a | F b = F(a | b)``, ``X a & X b = X(a & b)``. Every rule is
checked against the lasso-word semantics by the property tests.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

from steer_envs.core.validation import BoundExceeded
from steer_envs.ltl import syntax as s
from steer_envs.ltl.parser import parse
from steer_envs.ltl.syntax import Formula, check_depth, check_text_length

__all__ = ["clear_caches", "conjunction", "disjunction", "nnf", "simplify"]


# ---------------------------------------------------------------- NNF
def nnf(formula: str | Formula) -> Formula:
    """Negation normal form: ``!`` only on atoms; no ``->``, ``<->``, ``xor``.

    Raises :class:`~steer_envs.ltl.syntax.FormulaTooDeep` for formulas nested
    deeper than :data:`~steer_envs.ltl.syntax.MAX_FORMULA_DEPTH`.

    >>> str(nnf("!G(a -> b)"))
    'F(a & !b)'
    """
    f = parse(formula)
    check_depth(f, "nnf")
    return _nnf(f, False)


@lru_cache(maxsize=65536)
def _nnf(f: Formula, neg: bool) -> Formula:
    if isinstance(f, s.Const):
        return s.Const(f.value != neg)
    if isinstance(f, s.Atom):
        return s.Not(f) if neg else f
    if isinstance(f, s.Not):
        return _nnf(f.arg, not neg)
    if isinstance(f, s.And):
        parts = [_nnf(a, neg) for a in f.args]
        return s.Or(*parts) if neg else s.And(*parts)
    if isinstance(f, s.Or):
        parts = [_nnf(a, neg) for a in f.args]
        return s.And(*parts) if neg else s.Or(*parts)
    # the derived operators recurse straight into their operands (one stack frame per level)
    if isinstance(f, s.Implies):  # a -> b == !a | b; !(a -> b) == a & !b
        left, right = _nnf(f.left, not neg), _nnf(f.right, neg)
        return s.And(left, right) if neg else s.Or(left, right)
    if isinstance(f, s.Equiv | s.Xor):  # a <-> b == (a & b) | (!a & !b); a xor b == !(a <-> b)
        a, b = f.left, f.right
        if neg != isinstance(f, s.Xor):  # a xor b
            return s.Or(s.And(_nnf(a, False), _nnf(b, True)), s.And(_nnf(a, True), _nnf(b, False)))
        return s.Or(s.And(_nnf(a, False), _nnf(b, False)), s.And(_nnf(a, True), _nnf(b, True)))
    if isinstance(f, s.Next):
        return s.Next(_nnf(f.arg, neg))
    if isinstance(f, s.Finally):
        return s.Globally(_nnf(f.arg, True)) if neg else s.Finally(_nnf(f.arg, False))
    if isinstance(f, s.Globally):
        return s.Finally(_nnf(f.arg, True)) if neg else s.Globally(_nnf(f.arg, False))
    if isinstance(f, s.Until | s.Release | s.WeakUntil | s.StrongRelease):
        dual: dict[type[Formula], type[s.Until | s.Release | s.WeakUntil | s.StrongRelease]] = {
            s.Until: s.Release,
            s.Release: s.Until,
            s.WeakUntil: s.StrongRelease,
            s.StrongRelease: s.WeakUntil,
        }
        a, b = f.args
        cls = dual[type(f)] if neg else type(f)
        return cls(_nnf(a, neg), _nnf(b, neg))
    raise TypeError(f"nnf: unknown formula node {type(f).__name__}")  # pragma: no cover


def clear_caches() -> None:
    """Forget memoised NNF/simplification results (for cold-start timings)."""
    _nnf.cache_clear()
    _simp.cache_clear()


# ----------------------------------------------------------- smart builders
def _negated_literal(f: Formula) -> Formula | None:
    if isinstance(f, s.Atom):
        return s.Not(f)
    if isinstance(f, s.Not) and isinstance(f.arg, s.Atom):
        return f.arg
    return None


def conjunction(*args: Formula) -> Formula:
    """``a & b & ...`` flattened, deduplicated, sorted; ``false`` on ``p & !p``.

    Only structural rules: it never rewrites an operand, so the translator can
    use it to canonicalise automaton states without renaming eventualities.
    """
    return _junction(args, s.And, s.TRUE, s.FALSE)


def disjunction(*args: Formula) -> Formula:
    """``a | b | ...`` flattened, deduplicated, sorted; ``true`` on ``p | !p``."""
    return _junction(args, s.Or, s.FALSE, s.TRUE)


def _junction(args: tuple[Formula, ...], cls: type, unit: s.Const, zero: s.Const) -> Formula:
    items: set[Formula] = set()
    stack = list(args)
    while stack:
        a = stack.pop()
        if type(a) is cls:
            stack.extend(a.args)
        elif a is zero:
            return zero
        elif a is not unit:
            items.add(a)
    for a in items:
        neg = _negated_literal(a)
        if neg is not None and neg in items:
            return zero
    if not items:
        return unit
    if len(items) == 1:
        return next(iter(items))
    return cls(*sorted(items, key=Formula.sort_key))


# ----------------------------------------------------------- simplification
def simplify(formula: str | Formula) -> Formula:
    """An equivalent, usually smaller formula in negation normal form.

    Raises :class:`~steer_envs.ltl.syntax.FormulaTooDeep` for formulas nested
    deeper than :data:`~steer_envs.ltl.syntax.MAX_FORMULA_DEPTH` or whose NNF
    text exceeds :data:`~steer_envs.ltl.syntax.MAX_FORMULA_TEXT`. The rewrites
    run to a fixpoint, at most :data:`MAX_SIMPLIFY_ROUNDS` rounds
    (:class:`~steer_envs.core.validation.BoundExceeded` beyond).

    >>> str(simplify("!(a U b)")), str(simplify("G G a & G b"))
    ('!a R !b', 'G(a & b)')
    """
    f = nnf(formula)
    check_text_length(f, "simplify")  # operands are ordered by their text
    for _ in range(MAX_SIMPLIFY_ROUNDS):
        g = _simp(f)
        if g is f:
            return f
        f = g
    raise BoundExceeded(  # pragma: no cover - every round shrinks the formula or stops
        f"simplify: no fixpoint after MAX_SIMPLIFY_ROUNDS={MAX_SIMPLIFY_ROUNDS} rounds of rewriting"
    )


#: rounds of bottom-up rewriting :func:`simplify` runs before giving up (a fixpoint takes a few)
MAX_SIMPLIFY_ROUNDS = 1_000


@lru_cache(maxsize=65536)
def _simp(f: Formula) -> Formula:
    if not f.args or isinstance(f, s.Not):  # constants, atoms and (NNF) literals
        return f
    args = [_simp(a) for a in f.args]
    if isinstance(f, s.And):
        return _mk_and(args)
    if isinstance(f, s.Or):
        return _mk_or(args)
    if isinstance(f, s.Next):
        return _mk_next(args[0])
    if isinstance(f, s.Finally):
        return _mk_finally(args[0])
    if isinstance(f, s.Globally):
        return _mk_globally(args[0])
    a, b = args
    if isinstance(f, s.Until | s.Release):
        return _mk_until_or_release(a, b, type(f))
    if isinstance(f, s.WeakUntil | s.StrongRelease):
        return _mk_weak_until_or_strong_release(a, b, type(f))
    raise TypeError(f"simplify: unexpected non-NNF node {type(f).__name__}")  # pragma: no cover


def _merge(
    items: list[Formula], cls: type[s.Globally | s.Finally | s.Next], combine: Callable[..., Formula]
) -> list[Formula]:
    """Merge all operands of type ``cls`` (e.g. every ``G x``) into ``cls(combine(xs))``."""
    group = [a for a in items if type(a) is cls]
    if len(group) < 2:
        return items
    rest = [a for a in items if type(a) is not cls]
    return [*rest, cls(combine(*(a.args[0] for a in group)))]


def _mk_and(args: list[Formula]) -> Formula:
    return _mk_junction(args, s.And, conjunction, s.Globally, _mk_and_flat, s.Or)


def _mk_or(args: list[Formula]) -> Formula:
    return _mk_junction(args, s.Or, disjunction, s.Finally, _mk_or_flat, s.And)


def _mk_junction(
    args: list[Formula],
    cls: type[s.And | s.Or],
    build: Callable[..., Formula],
    temporal: type[s.Globally | s.Finally],
    flat: Callable[..., Formula],
    dual: type[s.And | s.Or],
) -> Formula:
    """``build(*args)`` (a ``cls``) simplified: its ``temporal`` and ``X`` operands merged (``G a & G b = G (a & b)``,
    ``F a | F b = F (a | b)``) and the ``dual`` operands it absorbs dropped (``a & (a | b) = a``)."""
    f = build(*args)
    if not isinstance(f, cls):
        return f
    items = list(f.args)
    items = _merge(items, temporal, flat)
    items = _merge(items, s.Next, flat)
    present = set(items)
    items = [a for a in items if not (isinstance(a, dual) and any(x in present for x in a.args))]
    return build(*items)


def _mk_and_flat(*args: Formula) -> Formula:
    return _mk_and(list(args))


def _mk_or_flat(*args: Formula) -> Formula:
    return _mk_or(list(args))


def _mk_next(a: Formula) -> Formula:
    if isinstance(a, s.Const):
        return a
    return s.Next(a)


def _is_gf(a: Formula) -> bool:
    return isinstance(a, s.Globally) and isinstance(a.arg, s.Finally)


def _is_fg(a: Formula) -> bool:
    return isinstance(a, s.Finally) and isinstance(a.arg, s.Globally)


def _mk_finally(a: Formula) -> Formula:
    if isinstance(a, s.Const) or isinstance(a, s.Finally) or _is_gf(a):
        return a  # F true, F false, F F x = F x, F G F x = G F x
    if isinstance(a, s.Until):
        return _mk_finally(a.right)  # F(x U y) = F y
    if isinstance(a, s.StrongRelease):
        return _mk_finally(_mk_and([a.left, a.right]))  # F(x M y) = F(x & y)
    return s.Finally(a)


def _mk_globally(a: Formula) -> Formula:
    if isinstance(a, s.Const) or isinstance(a, s.Globally) or _is_fg(a):
        return a  # G G x = G x, G F G x = F G x
    if isinstance(a, s.Release):
        return _mk_globally(a.right)  # G(x R y) = G y
    if isinstance(a, s.WeakUntil):
        return _mk_globally(_mk_or([a.left, a.right]))  # G(x W y) = G(x | y)
    return s.Globally(a)


def _mk_until_or_release(a: Formula, b: Formula, cls: type[s.Until | s.Release]) -> Formula:
    """``a U b`` or its dual ``a R b`` simplified (the comments give the ``U`` rule, then the ``R`` one)."""
    zero, one, unary = (s.FALSE, s.TRUE, _mk_finally) if cls is s.Until else (s.TRUE, s.FALSE, _mk_globally)
    if isinstance(b, s.Const) or a is zero or a is b:
        return b  # x U true, x U false, false U y, y U y; x R true, x R false, true R y, y R y
    if a is one:
        return unary(b)  # true U y = F y; false R y = G y
    if isinstance(b, cls) and b.left is a:
        return b  # x U (x U y) = x U y; x R (x R y) = x R y
    return cls(a, b)


def _mk_weak_until_or_strong_release(a: Formula, b: Formula, cls: type[s.WeakUntil | s.StrongRelease]) -> Formula:
    """``a W b`` or its dual ``a M b`` simplified (the comments give the ``W`` rule, then the ``M`` one)."""
    top, bottom, unary = (s.TRUE, s.FALSE, _mk_globally) if cls is s.WeakUntil else (s.FALSE, s.TRUE, _mk_finally)
    if b is top or a is top:
        return top  # x W true, true W y; x M false, false M y
    if a is bottom or a is b:
        return b  # false W y, y W y; true M y, y M y
    if b is bottom:
        return unary(a)  # x W false = G x; x M true = F x
    return cls(a, b)
