"""LTL -> transition-based generalized Büchi automaton (native translator).

The construction is the *tableau by formula expansion* of Couvreur (FM'99),
the algorithm behind Spot's ``ltl2tgba_fm``:

- a state is an LTL formula in negation normal form (the obligation the rest
  of the word must meet); the initial state is the simplified input;
- a state ``phi`` is expanded into its one-step unfolding, a disjunction of
  terms ``guard & X next`` (``guard`` a truth table over the APs, ``next`` a
  conjunction of subformulas), using ``a U b = b | (a & X(a U b))``,
  ``a R b = b & (a | X(a R b))``, ``a W b = b | (a & X(a W b))``,
  ``a M b = b & (a | X(a M b))``, ``F a = a | X F a``, ``G a = a & X G a``;
  propositional subformulas are evaluated directly to one guard;
- each term becomes an edge ``phi --guard--> next``. A term that *postpones*
  an eventuality ``e`` (``a U b``, ``a M b``, ``F b``) carries the promise
  ``e``; acceptance set ``i`` holds the edges that do not postpone the ``i``-th
  eventuality, so an accepting run cannot postpone any of them forever.

States with equal formulas are shared (formulas are hash-consed), the result
is trimmed (states from which nothing is accepted are removed) and reduced
(bisimilar states merged). Correctness is checked in the property tests
against :mod:`steer_envs.ltl.semantics` on random formulas and lasso words.

:func:`translate` is the public entry point; ``backend="spot"`` delegates to
:mod:`steer_envs.ltl.spot_backend` when Spot's Python bindings are installed.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from typing import Any

from steer_envs.core.validation import boolean, describe, integer, name_tuple
from steer_envs.ltl.automaton import Automaton, Edge
from steer_envs.ltl.guards import MAX_APS, full_mask
from steer_envs.ltl.guards import formula_mask as _formula_mask
from steer_envs.ltl.parser import parse
from steer_envs.ltl.simplify import conjunction, nnf, simplify
from steer_envs.ltl.syntax import (
    FALSE,
    TRUE,
    And,
    Finally,
    Formula,
    Globally,
    Next,
    Or,
    Release,
    StrongRelease,
    Until,
    WeakUntil,
    check_depth,
    check_text_length,
)

__all__ = ["BACKENDS", "TranslationTooLarge", "translate", "translate_native"]

#: memory budget (bytes of edge guards held by the translator) before it gives up
GUARD_BUDGET_BYTES = 1 << 28
#: and at most this many expansion terms, whatever their size
MAX_TERMS = 1_000_000


class TranslationTooLarge(ValueError):
    """The formula is too large to translate: the tableau outgrew the translator's memory budget (see
    :data:`GUARD_BUDGET_BYTES`), or the formula nests deeper than
    :data:`~steer_envs.ltl.syntax.MAX_FORMULA_DEPTH` or prints longer than
    :data:`~steer_envs.ltl.syntax.MAX_FORMULA_TEXT`; the message names the limit."""


#: accepted values of ``translate(..., backend=...)``
BACKENDS = ("native", "spot", "auto")

# a term of an expansion: (guard, next-state formula, postponed eventualities)
_Term = tuple[int, Formula, frozenset[Formula]]


class _Expander:
    """Memoised one-step unfolding of NNF formulas over a fixed AP list."""

    def __init__(self, aps: Sequence[str], budget_terms: int | None = None) -> None:
        self.aps = tuple(aps)
        self.full = full_mask(len(self.aps))
        guard_bytes = max(8, (1 << len(self.aps)) // 8)
        default = min(MAX_TERMS, GUARD_BUDGET_BYTES // guard_bytes)
        self.budget_terms = default if budget_terms is None else budget_terms
        self.held_terms = 0
        self._masks: dict[Formula, int] = {}
        self._cache: dict[Formula, list[_Term]] = {}
        self._conj: dict[tuple[Formula, Formula], Formula] = {}
        self._conj_sets: dict[Formula, frozenset[Formula]] = {}

    def mask(self, f: Formula) -> int:
        return _formula_mask(f, self.aps, self._masks)

    def product(self, left: list[_Term], right: list[_Term]) -> list[_Term]:
        out: list[_Term] = []
        for g1, n1, p1 in left:
            for g2, n2, p2 in right:
                g = g1 & g2
                if not g:
                    continue
                key = (n1, n2)
                nxt = self._conj.get(key)
                if nxt is None:
                    nxt = self._conj[key] = conjunction(n1, n2)
                if nxt is FALSE:
                    continue
                out.append((g, nxt, p1 | p2))
        return self.normalise(out)

    def normalise(self, terms: list[_Term]) -> list[_Term]:
        """Merge terms with equal successor and promises; drop valuations a better term covers.

        Term ``t1`` is better than ``t2`` when its successor's conjuncts are a
        subset of ``t2``'s (a weaker obligation) and its promises a subset of
        ``t2``'s, one of them strictly: on the valuations of ``t1`` the edge of
        ``t2`` is then useless (any word accepted through it is accepted
        through ``t1``, which postpones nothing more), so they are removed
        from ``t2``'s guard.
        """
        merged: dict[tuple[Formula, frozenset[Formula]], int] = {}
        for g, nxt, prom in terms:
            key = (nxt, prom)
            merged[key] = merged.get(key, 0) | g
        if len(merged) == 1:
            (((nxt, prom), g),) = merged.items()
            return [(g, nxt, prom)]
        items = [(g, nxt, prom, self._conjuncts(nxt)) for (nxt, prom), g in merged.items()]
        out: list[_Term] = []
        for g, nxt, prom, conj in items:
            for g2, n2, p2, c2 in items:
                if n2 is nxt and p2 == prom:
                    continue
                if p2 <= prom and c2 <= conj:
                    g &= ~g2
            if g:
                out.append((g, nxt, prom))
        return out

    def _conjuncts(self, f: Formula) -> frozenset[Formula]:
        hit = self._conj_sets.get(f)
        if hit is None:
            hit = frozenset() if f is TRUE else frozenset(f.args) if isinstance(f, And) else frozenset((f,))
            self._conj_sets[f] = hit
        return hit

    def expand(self, f: Formula) -> list[_Term]:
        hit = self._cache.get(f)
        if hit is not None:
            return hit
        terms = self._expand(f)
        self._cache[f] = terms
        self.held_terms += len(terms)
        if self.held_terms > self.budget_terms:
            raise TranslationTooLarge(
                f"translate: the tableau exceeds {self.budget_terms} edges over {len(self.aps)} APs; simplify the "
                f"formula, or for a GR(1) spec translate "
                f"spec.translation_formula(), which conjoins the environment assumptions"
            )
        return terms

    def _expand(self, f: Formula) -> list[_Term]:
        none: frozenset[Formula] = frozenset()
        if f.is_boolean:
            g = self.mask(f)
            return [(g, TRUE, none)] if g else []
        if isinstance(f, And):
            terms: list[_Term] = [(self.full, TRUE, none)]
            # propositional conjuncts first: one guard, prunes the product early
            props = [a for a in f.args if a.is_boolean]
            if props:
                g = self.mask(And(*props))
                if not g:
                    return []
                terms = [(g, TRUE, none)]
            for a in f.args:
                if not a.is_boolean:
                    terms = self.product(terms, self.expand(a))
                    if not terms:
                        return []
            return terms
        if isinstance(f, Or):
            out: list[_Term] = []
            for a in f.args:
                out.extend(self.expand(a))
            return self.normalise(out)
        if isinstance(f, Next):
            return [(self.full, f.arg, none)]
        if isinstance(f, Finally):
            return self.normalise([*self.expand(f.arg), (self.full, f, frozenset({f}))])
        if isinstance(f, Globally):
            return self.product(self.expand(f.arg), [(self.full, f, none)])
        if isinstance(f, Until):
            later = self.product(self.expand(f.left), [(self.full, f, frozenset({f}))])
            return self.normalise([*self.expand(f.right), *later])
        if isinstance(f, WeakUntil):
            later = self.product(self.expand(f.left), [(self.full, f, none)])
            return self.normalise([*self.expand(f.right), *later])
        if isinstance(f, Release):
            stay = self.normalise([*self.expand(f.left), (self.full, f, none)])
            return self.product(self.expand(f.right), stay)
        if isinstance(f, StrongRelease):
            stay = self.normalise([*self.expand(f.left), (self.full, f, frozenset({f}))])
            return self.product(self.expand(f.right), stay)
        raise TypeError(f"translate: unexpected node {type(f).__name__} (input must be in NNF)")  # pragma: no cover


def _eventualities(f: Formula) -> list[Formula]:
    evs = [g for g in f.subformulas() if isinstance(g, (Until, StrongRelease, Finally))]
    return sorted(evs, key=Formula.sort_key)


def translate_native(
    formula: str | Formula,
    aps: Sequence[str] | None = None,
    *,
    simplify_formula: bool = True,
    reduce: bool = True,
    max_terms: int | None = None,
) -> Automaton:
    """Translate LTL to a transition-based generalized Büchi automaton (see module doc).

    Args:
        formula: LTL text (Spot syntax) or a :class:`Formula`.
        aps: AP order of the guards; must include every AP of the formula
            (default: the formula's APs, sorted).
        simplify_formula: apply :func:`steer_envs.ltl.simplify` first (else only NNF).
        reduce: trim useless states and merge bisimilar ones.
        max_terms: give up (:class:`TranslationTooLarge`) beyond this many
            tableau terms, an int >= 1 (default: a 256 MiB guard budget, at most
            :data:`MAX_TERMS`).

    Raises:
        LTLParseError: malformed text.
        TranslationTooLarge: a formula deeper than ``MAX_FORMULA_DEPTH``, whose
            NNF text exceeds ``MAX_FORMULA_TEXT``, or whose tableau exceeds the budget.
        TypeError / ValueError: bad ``aps`` (not a sequence of str names, or
            missing an AP of the formula), ``max_terms`` or flags.
    """
    f = parse(formula)
    check_depth(f, "translate", error=TranslationTooLarge)
    simplify_formula = boolean(simplify_formula, "simplify_formula", owner="translate")
    reduce = boolean(reduce, "reduce", owner="translate")
    if max_terms is not None:
        max_terms = integer(max_terms, "max_terms", low=1, owner="translate")
    aps = _translation_aps(f, aps)
    check_text_length(nnf(f), "translate", error=TranslationTooLarge)
    start = simplify(f) if simplify_formula else nnf(f)
    aut = _tableau(start, aps, max_terms, name=str(f))
    if reduce:
        aut = aut.trim().reduce()
    return aut


def _translation_aps(f: Formula, aps: Sequence[str] | None) -> tuple[str, ...]:
    """The AP order of the guards: ``aps`` checked to cover ``f`` (default: ``f``'s APs, sorted)."""
    atoms = f.atoms()
    if aps is None:
        aps = tuple(sorted(atoms))
    else:
        aps = check_aps(aps, "translate")
        missing = sorted(atoms - set(aps))
        if missing:
            raise ValueError(f"translate: `aps` must include every AP of the formula; missing {missing}")
    if len(aps) > MAX_APS:
        raise ValueError(f"translate: at most {MAX_APS} APs are supported, got {len(aps)}")
    return aps


def _tableau(start: Formula, aps: tuple[str, ...], max_terms: int | None, name: str) -> Automaton:
    """The unreduced automaton: breadth-first expansion of ``start`` (an NNF formula), one state per term."""
    evs = _eventualities(start)
    acc_index = {e: i for i, e in enumerate(evs)}
    all_marks = frozenset(range(len(evs)))
    expander = _Expander(aps, max_terms)

    states: dict[Formula, int] = {start: 0}
    order = [start]
    edges: list[Edge] = []
    queue = deque([start])
    while queue:
        phi = queue.popleft()
        src = states[phi]
        for guard, nxt, promises in expander.expand(phi):
            if nxt not in states:
                states[nxt] = len(order)
                order.append(nxt)
                queue.append(nxt)
            acc = all_marks - frozenset(acc_index[p] for p in promises)
            edges.append(Edge(src, states[nxt], guard, acc))
    return Automaton(
        aps=aps,
        num_states=len(order),
        initial=0,
        edges=tuple(edges),
        num_sets=len(evs),
        state_names=tuple(str(s) for s in order),
        name=name,
    )


def check_aps(aps: Any, who: str) -> tuple[str, ...]:
    """An AP order: a sequence (not a single string) of str names."""
    return name_tuple(aps, "`aps`", owner=who, what="AP names", ordered=False, empty=True)


def translate(
    formula: str | Formula,
    aps: Sequence[str] | None = None,
    *,
    backend: str = "native",
    simplify_formula: bool = True,
) -> Automaton:
    """LTL formula -> generalized Büchi automaton, through the chosen backend.

    Args:
        formula: LTL text (Spot syntax) or a :class:`Formula`.
        aps: AP order of the edge guards (default: the formula's APs, sorted).
        backend: ``"native"`` (this package's translator), ``"spot"`` (Spot's
            ``spot.translate``; raises ImportError when Spot's Python bindings
            are missing) or ``"auto"`` (Spot when importable, else native).
        simplify_formula: native backend only: simplify before translating.

    Both backends return an :class:`~steer_envs.ltl.automaton.Automaton` over
    ``aps`` accepting exactly the words that satisfy the formula.

    >>> aut = translate("G(a -> F b)")
    >>> aut
    Automaton(2 states, 4 edges, 1 acceptance sets, aps=('a', 'b'))
    >>> aut.accepts([{"a"}], [{"b"}]), aut.accepts([], [{"a"}])
    (True, False)
    """
    if not isinstance(backend, str) or backend not in BACKENDS:
        raise ValueError(f"translate: `backend` must be one of {BACKENDS}, got {describe(backend)}")
    if backend == "auto":
        from steer_envs.ltl.spot_backend import spot_available

        backend = "spot" if spot_available() else "native"
    if backend == "spot":
        from steer_envs.ltl.spot_backend import translate_spot

        return translate_spot(formula, aps)
    return translate_native(formula, aps, simplify_formula=simplify_formula)
