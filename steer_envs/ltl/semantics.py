"""Reference semantics: LTL on ultimately periodic words ``u v^omega``.

An ultimately periodic (lasso) word has finitely many distinct suffixes, one
per position of ``u v``; position ``len(u v) - 1`` is followed by position
``len(u)``. Every LTL operator is then a finite computation over those
positions: ``X`` reads the successor, ``U``/``M``/``F`` are *least* and
``R``/``W``/``G`` *greatest* fixpoints of their one-step unfoldings
(``a U b = b | (a & X(a U b))``), iterated to stability around the loop.

This is exact and independent of any automaton, which is why the property
tests use it as the oracle for the translator.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from steer_envs.core.validation import BoundExceeded, boolean, describe
from steer_envs.ltl import syntax as s
from steer_envs.ltl.parser import parse
from steer_envs.ltl.syntax import Formula

__all__ = ["LassoWord", "Letter", "evaluate", "evaluate_positions"]

#: one letter: the set of true APs, a mapping AP -> bool, or (with ``aps``) an int bitmask
Letter = frozenset[str] | set[str] | Mapping[str, bool] | int | Iterable[str]


def _letter(letter: object, aps: Sequence[str] | None, what: str) -> frozenset[str]:
    """A letter as its set of true APs; mapping values must be real bools (``"False"``/NaN are errors)."""
    kinds = "a set of true APs, a mapping AP -> bool or an int"
    if isinstance(letter, (bool, np.bool_)):
        raise TypeError(f"{what}: a letter must be {kinds}, got {describe(letter)}")
    if isinstance(letter, numbers.Integral):
        value = int(letter)
        if aps is None:
            raise ValueError(f"{what}: int letters need `aps` (the AP order of the bits)")
        if not 0 <= value < (1 << len(aps)):
            raise ValueError(f"{what}: int letter {value} out of range for {len(aps)} APs")
        return frozenset(ap for j, ap in enumerate(aps) if (value >> j) & 1)
    if isinstance(letter, Mapping):
        return frozenset(_ap(k, what) for k, v in letter.items() if boolean(v, f"{what} letter[{k!r}]"))
    if isinstance(letter, str):
        return frozenset((letter,))
    if not isinstance(letter, Iterable) or isinstance(letter, (bytes, np.ndarray)):
        raise TypeError(f"{what}: a letter must be {kinds}, got {describe(letter)}")
    return frozenset(_ap(x, what) for x in letter)


def _ap(name: object, what: str) -> str:
    if not isinstance(name, str):
        raise TypeError(f"{what}: AP names in a letter must be str, got {describe(name)}")
    return name


@dataclass(frozen=True)
class LassoWord:
    """The infinite word ``prefix loop loop loop ...`` (letters: sets of true APs)."""

    prefix: tuple[frozenset[str], ...]
    loop: tuple[frozenset[str], ...]

    @classmethod
    def of(cls, prefix: Iterable[Letter], loop: Iterable[Letter], aps: Sequence[str] | None = None) -> LassoWord:
        """Build a word from letters in any accepted form (see :data:`Letter`; mapping values are real bools)."""
        if aps is not None:
            if isinstance(aps, str):
                raise TypeError(f"LassoWord.of: `aps` must be a sequence of AP names, not one string ({aps!r})")
            aps = tuple(_ap(a, "aps") for a in aps)
        for name, part in (("prefix", prefix), ("loop", loop)):
            if isinstance(part, (str, bytes)) or not isinstance(part, Iterable):
                raise TypeError(f"LassoWord.of: `{name}` must be a sequence of letters, got {describe(part)}")
        p = tuple(_letter(x, aps, "prefix") for x in prefix)
        v = tuple(_letter(x, aps, "loop") for x in loop)
        if not v:
            raise ValueError("loop: the periodic part of a lasso word must have at least one letter")
        return cls(p, v)

    def __len__(self) -> int:
        return len(self.prefix) + len(self.loop)

    def letters(self) -> tuple[frozenset[str], ...]:
        """Letters of positions ``0 .. len - 1``."""
        return self.prefix + self.loop

    def successor(self, i: int) -> int:
        """Position after ``i`` (the last position loops back to ``len(prefix)``)."""
        return i + 1 if i + 1 < len(self) else len(self.prefix)


def evaluate_positions(formula: str | Formula, word: LassoWord) -> tuple[bool, ...]:
    """Truth value of ``formula`` at each position ``0 .. len(word) - 1`` of the lasso.

    >>> evaluate_positions("X b", LassoWord.of([{"a"}, {"b"}], [set()]))
    (True, False, False)
    """
    f = parse(formula)
    if not isinstance(word, LassoWord):
        raise TypeError(f"word must be a LassoWord, got {type(word).__name__}")
    letters = word.letters()
    succ = [word.successor(i) for i in range(len(letters))]
    values: dict[Formula, list[bool]] = {}
    for g in f.subformulas():
        values[g] = _node_values(g, values, letters, succ)
    return tuple(values[f])


_TEMPORAL = (s.Finally, s.Globally, s.Until, s.WeakUntil, s.Release, s.StrongRelease)


def _node_values(
    g: Formula, values: Mapping[Formula, list[bool]], letters: Sequence[frozenset[str]], succ: Sequence[int]
) -> list[bool]:
    """Truth values of ``g`` at every position, given those of its subformulas in ``values``."""
    n = len(letters)
    a = values[g.args[0]] if g.args else []
    b = values[g.args[1]] if len(g.args) > 1 else []
    if isinstance(g, _TEMPORAL):
        return _temporal_values(g, a, b, succ)
    if isinstance(g, s.Const):
        return [g.value] * n
    if isinstance(g, s.Atom):
        return [g.name in letters[i] for i in range(n)]
    if isinstance(g, s.Not):
        return [not x for x in a]
    if isinstance(g, s.And):
        return [all(values[c][i] for c in g.args) for i in range(n)]
    if isinstance(g, s.Or):
        return [any(values[c][i] for c in g.args) for i in range(n)]
    if isinstance(g, s.Implies):
        return [(not x) or y for x, y in zip(a, b, strict=True)]
    if isinstance(g, s.Equiv):
        return [x == y for x, y in zip(a, b, strict=True)]
    if isinstance(g, s.Xor):
        return [x != y for x, y in zip(a, b, strict=True)]
    if isinstance(g, s.Next):
        return [a[succ[i]] for i in range(n)]
    raise TypeError(f"unknown formula node {type(g).__name__}")  # pragma: no cover - closed hierarchy


def _temporal_values(g: Formula, a: list[bool], b: list[bool], succ: Sequence[int]) -> list[bool]:
    """Truth values of a fixpoint operator (``F G U W R M``) over its operands' values ``a`` and ``b``."""
    if isinstance(g, s.Finally):
        return _fixpoint(succ, False, lambda i, nxt: a[i] or nxt)
    if isinstance(g, s.Globally):
        return _fixpoint(succ, True, lambda i, nxt: a[i] and nxt)
    if isinstance(g, s.Until):
        return _fixpoint(succ, False, lambda i, nxt: b[i] or (a[i] and nxt))
    if isinstance(g, s.WeakUntil):
        return _fixpoint(succ, True, lambda i, nxt: b[i] or (a[i] and nxt))
    if isinstance(g, s.Release):
        return _fixpoint(succ, True, lambda i, nxt: b[i] and (a[i] or nxt))
    if isinstance(g, s.StrongRelease):
        return _fixpoint(succ, False, lambda i, nxt: b[i] and (a[i] or nxt))
    raise TypeError(f"unknown formula node {type(g).__name__}")  # pragma: no cover - closed hierarchy


def _fixpoint(succ: Sequence[int], init: bool, step: Callable[[int, bool], bool]) -> list[bool]:
    """The fixpoint of ``val[i] = step(i, val[succ[i]])`` reached by backward sweeps from ``init``."""
    n = len(succ)
    val = [init] * n
    for _ in range(n + 1):  # monotone: every sweep but the last flips a value for good, so <= n + 1 sweeps
        changed = False
        for i in range(n - 1, -1, -1):
            new = step(i, val[succ[i]])
            if new != val[i]:
                val[i] = new
                changed = True
        if not changed:
            return val
    raise BoundExceeded(f"evaluate: no fixpoint after len(word) + 1 = {n + 1} sweeps")  # pragma: no cover


def evaluate(
    formula: str | Formula,
    prefix: Iterable[Letter] | LassoWord,
    loop: Iterable[Letter] | None = None,
    *,
    aps: Sequence[str] | None = None,
) -> bool:
    """Does the word ``prefix loop^omega`` satisfy ``formula`` (at position 0)?

    ``prefix`` may also be a ready :class:`LassoWord` (then omit ``loop``).
    Letters are sets of true APs, mappings AP -> bool, or ints with ``aps``.

    >>> evaluate("a U b", [{"a"}, {"a"}], [{"b"}])
    True
    >>> evaluate("G F a", [], [0b1, 0b0], aps=["a"])
    True
    """
    if isinstance(prefix, LassoWord):
        if loop is not None:
            raise ValueError("evaluate: pass either a LassoWord or `prefix` and `loop`, not both")
        word = prefix
    else:
        if loop is None:
            raise ValueError("evaluate: `loop` (the periodic part of the word) is required")
        word = LassoWord.of(prefix, loop, aps)
    return evaluate_positions(formula, word)[0]
