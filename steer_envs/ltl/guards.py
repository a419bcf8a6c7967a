"""Boolean edge guards as truth tables over a fixed AP order.

A *valuation* of APs ``aps = (p0, p1, ...)`` is an int whose bit ``j`` is the
value of ``aps[j]``. A *guard* is a Python int used as a truth table: bit
``v`` is set iff valuation ``v`` satisfies the guard. Conjunction, disjunction
and complement are then single big-int operations, emptiness is ``== 0`` and
equal guards are equal ints: an exact, canonical representation (what BDDs
give Spot) for the small AP sets of task specifications (up to
:data:`MAX_APS`).

:func:`isop` turns a guard back into a compact sum of products (Minato-Morreale
irredundant cover) for printing and for HOA labels.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable, Mapping, Sequence
from functools import lru_cache

import numpy as np

from steer_envs.core.validation import boolean, describe
from steer_envs.ltl.syntax import (
    And,
    Atom,
    Const,
    Equiv,
    Formula,
    Implies,
    Not,
    Or,
    Xor,
)

__all__ = [
    "MAX_APS",
    "ap_mask",
    "cube_mask",
    "cubes_to_str",
    "formula_mask",
    "full_mask",
    "guard_to_str",
    "isop",
    "remap_guard",
    "valuation_of",
]

#: largest AP set a guard may range over (a truth table has 2**n bits)
MAX_APS = 20

Cube = tuple[tuple[int, bool], ...]  # ((ap index, polarity), ...), sorted by index


def _check_n(n: int) -> None:
    if isinstance(n, bool) or not isinstance(n, int):
        raise TypeError(f"the number of APs must be an int, got {describe(n)}")
    if not 0 <= n <= MAX_APS:
        raise ValueError(f"guards range over at most {MAX_APS} atomic propositions, got {n}")


@lru_cache(maxsize=64)
def full_mask(n: int) -> int:
    """The guard ``true`` over ``n`` APs (all ``2**n`` valuations)."""
    _check_n(n)
    return (1 << (1 << n)) - 1


@lru_cache(maxsize=1024)
def ap_mask(j: int, n: int) -> int:
    """The guard ``aps[j]`` over ``n`` APs."""
    _check_n(n)
    if not 0 <= j < n:
        raise ValueError(f"AP index must be in [0, {n}), got {j}")
    half = 1 << j  # block of 2**j valuations with bit j clear, then 2**j with it set
    unit = ((1 << half) - 1) << half
    period = half << 1
    repeats = (1 << (1 << n)) - 1
    return unit * (repeats // ((1 << period) - 1))


def cube_mask(cube: Cube, n: int) -> int:
    """The guard of a conjunction of literals."""
    m = full_mask(n)
    for j, pol in cube:
        m &= ap_mask(j, n) if pol else ~ap_mask(j, n)
    return m & full_mask(n)


#: a letter: the set (any iterable) of true APs, a mapping AP -> bool, or a valuation int
GuardLetter = Mapping[str, bool] | Iterable[str] | int


def valuation_of(letter: GuardLetter, aps: Sequence[str]) -> int:
    """The valuation (int) of a letter: set of true APs, mapping AP -> bool, or an int already.

    Mapping values must be real bools (Python or numpy): ``"False"``, ``1`` or
    NaN raise ``TypeError`` instead of reading as true. AP names must be str.
    """
    return _valuation(letter, aps, "letter")


def _valuation(letter: object, aps: Sequence[str], what: str) -> int:
    kinds = "a set of true APs, a mapping AP -> bool or an int"
    if isinstance(letter, (bool, np.bool_)):
        raise TypeError(f"{what} must be {kinds}, got {describe(letter)}")
    if isinstance(letter, numbers.Integral):
        value = int(letter)
        if not 0 <= value < (1 << len(aps)):
            raise ValueError(f"valuation {value} out of range for {len(aps)} APs")
        return value
    if isinstance(letter, Mapping):
        true = {_ap_name(k, what) for k, v in letter.items() if boolean(v, f"{what}[{k!r}]")}
    elif isinstance(letter, str):
        true = {letter}
    elif isinstance(letter, Iterable) and not isinstance(letter, (bytes, np.ndarray)):
        true = {_ap_name(x, what) for x in letter}
    else:
        raise TypeError(f"{what} must be {kinds}, got {describe(letter)}")
    v = 0
    for j, ap in enumerate(aps):
        if ap in true:
            v |= 1 << j
    return v


def _ap_name(name: object, what: str) -> str:
    if not isinstance(name, str):
        raise TypeError(f"{what}: AP names must be str, got {describe(name)}")
    return name


def formula_mask(f: Formula, aps: Sequence[str], cache: dict[Formula, int] | None = None) -> int:
    """The guard of a propositional formula over ``aps`` (APs not in ``aps`` raise).

    Evaluated with an explicit stack (children first), so any depth works;
    ``cache`` memoises guards of subformulas across calls.
    """
    if not isinstance(f, Formula):
        raise TypeError(f"formula_mask: `f` must be a Formula, got {describe(f)}")
    n = len(aps)
    index = {ap: j for j, ap in enumerate(aps)}
    full = full_mask(n)
    memo = {} if cache is None else cache
    hit = memo.get(f)
    if hit is not None:
        return hit
    stack: list[tuple[Formula, bool]] = [(f, False)]
    while stack:
        g, ready = stack.pop()
        if g in memo:
            continue
        if not ready and g.args:
            stack.append((g, True))
            stack.extend((a, False) for a in reversed(g.args) if a not in memo)
            continue
        if isinstance(g, Const):
            m = full if g.value else 0
        elif isinstance(g, Atom):
            if g.name not in index:
                raise ValueError(f"atomic proposition {g.name!r} is not one of the automaton APs {tuple(aps)}")
            m = ap_mask(index[g.name], n)
        elif isinstance(g, Not):
            m = full & ~memo[g.arg]
        elif isinstance(g, And):
            m = full
            for a in g.args:
                m &= memo[a]
        elif isinstance(g, Or):
            m = 0
            for a in g.args:
                m |= memo[a]
        elif isinstance(g, Implies):
            m = (full & ~memo[g.left]) | memo[g.right]
        elif isinstance(g, Equiv):
            m = full & ~(memo[g.left] ^ memo[g.right])
        elif isinstance(g, Xor):
            m = memo[g.left] ^ memo[g.right]
        else:
            raise TypeError(f"formula_mask: {str(g)!r} is temporal, expected a propositional formula")
        memo[g] = m
    return memo[f]


# ---------------------------------------------------------------- ISOP
def _cof0(f: int, j: int, n: int) -> int:
    low = f & ~ap_mask(j, n) & full_mask(n)
    return low | (low << (1 << j))


def _cof1(f: int, j: int, n: int) -> int:
    high = f & ap_mask(j, n)
    return high | (high >> (1 << j))


def isop(guard: int, n: int) -> list[Cube]:
    """An irredundant sum-of-products cover of ``guard`` (Minato-Morreale ISOP).

    Returns a list of cubes; ``[]`` is ``false`` and ``[()]`` is ``true``.
    """
    full = full_mask(n)
    if not 0 <= guard <= full:
        raise ValueError(f"guard is not a truth table over {n} APs")
    cubes, _ = _isop(guard, guard, n, n)
    return sorted(cubes, key=lambda c: (len(c), c))


def _isop(lower: int, upper: int, top: int, n: int) -> tuple[list[Cube], int]:
    full = full_mask(n)
    if lower == 0:
        return [], 0
    if upper == full:
        return [()], full
    j = top - 1
    while j >= 0 and _cof0(lower, j, n) == _cof1(lower, j, n) and _cof0(upper, j, n) == _cof1(upper, j, n):
        j -= 1
    if j < 0:  # pragma: no cover - lower != 0 and upper != full imply a support variable
        raise AssertionError("ISOP: no splitting variable")
    l0, l1 = _cof0(lower, j, n), _cof1(lower, j, n)
    u0, u1 = _cof0(upper, j, n), _cof1(upper, j, n)
    c0, f0 = _isop(l0 & ~u1 & full, u0, j, n)
    c1, f1 = _isop(l1 & ~u0 & full, u1, j, n)
    rest = ((l0 & ~f0) | (l1 & ~f1)) & full
    c2, f2 = _isop(rest, u0 & u1, j, n)
    mj = ap_mask(j, n)
    cover = (f0 & ~mj) | (f1 & mj) | f2
    cubes = [(*c, (j, False)) for c in c0] + [(*c, (j, True)) for c in c1] + c2
    return [tuple(sorted(c)) for c in cubes], cover & full


def cubes_to_str(cubes: Sequence[Cube], names: Sequence[str], *, and_: str = " & ", or_: str = " | ") -> str:
    """Print a cover with AP ``names`` (``true``/``false`` for the constants)."""
    if not cubes:
        return "false"
    terms = []
    for cube in cubes:
        if not cube:
            return "true"
        terms.append(and_.join(("" if pol else "!") + names[j] for j, pol in cube))
    if len(terms) == 1:
        return terms[0]
    return or_.join(f"({t})" if len(c) > 1 else t for t, c in zip(terms, cubes, strict=True))


def guard_to_str(guard: int, aps: Sequence[str]) -> str:
    """A readable Spot-syntax formula for a guard over ``aps``."""
    from steer_envs.ltl.syntax import ap_needs_quotes

    names = [f'"{ap}"' if ap_needs_quotes(ap) else ap for ap in aps]
    return cubes_to_str(isop(guard, len(aps)), names)


def remap_guard(guard: int, old_aps: Sequence[str], new_aps: Sequence[str]) -> int:
    """The same guard over a different AP order/superset (``old_aps`` must be a subset of ``new_aps``)."""
    missing = [ap for ap in old_aps if ap not in new_aps]
    if missing:
        raise ValueError(f"remap_guard: APs {missing} are not in the new AP list {tuple(new_aps)}")
    if tuple(old_aps) == tuple(new_aps):
        return guard
    n_new = len(new_aps)
    pos = {ap: j for j, ap in enumerate(new_aps)}
    out = 0
    for cube in isop(guard, len(old_aps)):
        out |= cube_mask(tuple(sorted((pos[old_aps[j]], pol) for j, pol in cube)), n_new)
    return out
