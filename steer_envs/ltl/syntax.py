"""Immutable LTL formula trees (hash-consed) and their Spot-syntax printer.

Every node is *interned*: building the same formula twice returns the same
object, so equality is identity, hashing is O(1) and formulas can key caches
(the translator memoises expansions per subformula). Nodes are read-only.

``And``/``Or`` are n-ary and flatten nested conjunctions/disjunctions at
construction (``And(a, And(b, c)) is And(a, b, c)``), which is what makes
printing round-trip: ``parse(str(f)) is f`` for every formula ``f``.

The printer writes Spot's syntax (``G F X U R W M``, ``! & | -> <-> xor``,
``true false``) with every binary subformula of a binary operator
parenthesised, so the output is unambiguous to Spot, to ``steer_envs.ltl.parse``
and to a human reader. It uses an explicit stack, so any formula that can be
built prints, however deep. The recursive algorithms on formulas (NNF,
simplification, translation) accept formulas of depth at most
:data:`MAX_FORMULA_DEPTH` and raise :class:`FormulaTooDeep` (or their own
documented error, a ``ValueError`` too) beyond it, instead of a
``RecursionError``.
"""

from __future__ import annotations

import itertools
import re
import weakref
from collections.abc import Iterator
from typing import Any, ClassVar, Self

__all__ = [
    "BINARY_OPERATORS",
    "FALSE",
    "MAX_FORMULA_DEPTH",
    "MAX_FORMULA_TEXT",
    "TRUE",
    "UNARY_OPERATORS",
    "And",
    "Atom",
    "Const",
    "Equiv",
    "Finally",
    "Formula",
    "FormulaTooDeep",
    "Globally",
    "Implies",
    "Next",
    "Not",
    "Or",
    "Release",
    "StrongRelease",
    "Until",
    "WeakUntil",
    "Xor",
    "ap_needs_quotes",
    "check_depth",
    "check_text_length",
    "text_length",
]

_TABLE: weakref.WeakValueDictionary[tuple[Any, ...], Formula] = weakref.WeakValueDictionary()  # the unique table
_SERIAL = itertools.count()

# A bare atomic proposition, as Spot's scanner reads it where an operand is
# expected: it may not start with F, G or X (unary operators) unless a digit
# follows; identifiers equal to a keyword (true/false in any case, xor, the
# binary operators) must be quoted.
_BARE_AP = re.compile(r"(?:[a-zA-EH-WYZ_.][a-zA-Z0-9_.]*|[FGX][0-9][a-zA-Z0-9_.]*)\Z")
_KEYWORDS = frozenset({"xor", "U", "R", "V", "W", "M"})


#: deepest operator nesting the recursive formula algorithms (NNF, simplify, translate, guards) accept;
#: they use about three Python frames per level, so this stays well inside Python's default recursion limit.
MAX_FORMULA_DEPTH = 200


class FormulaTooDeep(ValueError):
    """A formula nests operators deeper than an algorithm's limit (see :data:`MAX_FORMULA_DEPTH`)."""


def check_depth(
    f: Formula, who: str, *, limit: int = MAX_FORMULA_DEPTH, error: type[ValueError] = FormulaTooDeep
) -> None:
    """Raise ``error`` naming ``who`` and the limit when ``f`` nests deeper than ``limit`` (O(size), no recursion).

    >>> f = Atom("a")
    >>> for _ in range(300):
    ...     f = Next(f)
    >>> check_depth(f, "nnf")
    Traceback (most recent call last):
    steer_envs.ltl.syntax.FormulaTooDeep: nnf: the formula nests 300 operators deep; at most MAX_FORMULA_DEPTH=200 ...
    """
    depth = f.depth
    if depth > limit:
        raise error(
            f"{who}: the formula nests {depth} operators deep; at most MAX_FORMULA_DEPTH={limit} are supported "
            f"(rewrite it flatter, e.g. X X a as one X with a counter AP)"
        )


#: longest text (characters) of a formula the algorithms that print subformulas (simplify's operand
#: order, translate's state names) accept: an n-deep ``<->`` chain has a small DAG but ~4**(n/2) characters.
MAX_FORMULA_TEXT = 1_000_000


def text_length(f: Formula) -> int:
    """Length of ``str(f)`` computed on the DAG, without building the text (O(size), no recursion).

    >>> f = And(Atom("a"), Not(Atom("b")))
    >>> text_length(f) == len(str(f))
    True
    """
    lengths: dict[Formula, int] = {}
    for g in f.subformulas():
        if isinstance(g, Const):
            n = 4 if g.value else 5
        elif isinstance(g, Atom):
            n = len(_quote(g.name))
        else:
            n = sum(lengths[a] + (2 if _parenthesised(a) else 0) for a in g.args)
            n += len(g.symbol) if isinstance(g, _Unary) else (len(g.args) - 1) * (len(g.symbol) + 2)
        lengths[g] = n
    return lengths[f]


def check_text_length(
    f: Formula, who: str, *, limit: int = MAX_FORMULA_TEXT, error: type[ValueError] = FormulaTooDeep
) -> None:
    """Raise ``error`` naming ``who`` and the limit when ``str(f)`` would exceed ``limit`` characters."""
    n = text_length(f)
    if n > limit:
        raise error(
            f"{who}: the formula's text would be {n} characters; at most MAX_FORMULA_TEXT={limit} are supported "
            f"(nested <->/xor grow exponentially in negation normal form)"
        )


def ap_needs_quotes(name: str) -> bool:
    """True when ``name`` must be written ``"name"`` to parse back as one AP."""
    return _BARE_AP.match(name) is None or name in _KEYWORDS or name.lower() in ("true", "false")


def _quote(name: str) -> str:
    if not ap_needs_quotes(name):
        return name
    return '"' + name.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _check(arg: object, what: str) -> Formula:
    if not isinstance(arg, Formula):
        raise TypeError(f"{what}: operands must be Formula objects, got {type(arg).__name__} ({arg!r})")
    return arg


class Formula:
    """Base class of every LTL formula node (interned, immutable).

    Attributes:
        args: operand subformulas (empty for constants and atoms).
    Subclasses add readable accessors: ``Atom.name``, ``Const.value``,
    ``arg`` for unary operators, ``left``/``right`` for binary ones.
    """

    __slots__ = ("__weakref__", "_args", "_boolean", "_hash", "_name", "_serial", "_str")

    #: operator symbol in Spot syntax (subclasses override)
    symbol: ClassVar[str] = ""
    #: binding strength: 1 (-> <->), 2 (|), 3 (xor), 4 (&), 5 (U R W M), 6 (unary, atoms)
    precedence: ClassVar[int] = 6
    #: False for temporal operators (X F G U R W M)
    propositional: ClassVar[bool] = True

    _args: tuple[Formula, ...]
    _name: Any
    _hash: int
    _serial: int
    _str: str | None
    _boolean: bool

    @classmethod
    def _make(cls, args: tuple[Formula, ...], name: Any = None) -> Self:
        # Children are interned, so their ids identify them; the entry lives only
        # as long as the node, which keeps its children (and their ids) alive.
        key = (cls, name, *map(id, args))
        try:
            found = _TABLE[key]
        except KeyError:
            found = None
        if isinstance(found, cls):  # `cls` is part of the key: a hit is always of class `cls`
            node = found
        else:
            node = object.__new__(cls)
            object.__setattr__(node, "_args", args)
            object.__setattr__(node, "_name", name)
            object.__setattr__(node, "_hash", hash(key))
            object.__setattr__(node, "_serial", next(_SERIAL))
            object.__setattr__(node, "_str", None)
            boolean = cls.propositional and all(a._boolean for a in args)
            object.__setattr__(node, "_boolean", boolean)
            _TABLE[key] = node
        return node

    # ------------------------------------------------------------ immutability
    def __setattr__(self, key: str, value: object) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable")

    def __delattr__(self, key: str) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable")

    def __eq__(self, other: object) -> bool:
        return self is other

    def __hash__(self) -> int:
        return self._hash

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild, (type(self), self._name, self._args))

    def __copy__(self) -> Formula:
        return self

    def __deepcopy__(self, memo: dict[int, Any]) -> Formula:
        return self

    # ---------------------------------------------------------------- queries
    @property
    def args(self) -> tuple[Formula, ...]:
        """Operand subformulas (in order)."""
        return self._args

    @property
    def is_boolean(self) -> bool:
        """True when the formula has no temporal operator (a propositional guard)."""
        return self._boolean

    def atoms(self) -> frozenset[str]:
        """Names of the atomic propositions occurring in the formula."""
        return frozenset(f._name for f in self.subformulas() if isinstance(f, Atom))

    def subformulas(self) -> Iterator[Formula]:
        """Every distinct subformula (including ``self``), children before parents."""
        seen: set[Formula] = set()
        stack: list[tuple[Formula, bool]] = [(self, False)]
        while stack:
            node, expanded = stack.pop()
            if expanded:
                yield node
                continue
            if node in seen:
                continue
            seen.add(node)
            stack.append((node, True))
            stack.extend((child, False) for child in reversed(node._args) if child not in seen)

    @property
    def size(self) -> int:
        """Number of distinct subformulas (DAG size)."""
        return sum(1 for _ in self.subformulas())

    @property
    def depth(self) -> int:
        """Operator nesting depth (atoms and constants have depth 0)."""
        depth: dict[Formula, int] = {}
        for f in self.subformulas():
            depth[f] = 1 + max((depth[a] for a in f._args), default=-1)
        return depth[self]

    # ---------------------------------------------------------- construction
    def __and__(self, other: Formula) -> Formula:
        return And(self, other)

    def __or__(self, other: Formula) -> Formula:
        return Or(self, other)

    def __invert__(self) -> Formula:
        return Not(self)

    def __rshift__(self, other: Formula) -> Formula:
        return Implies(self, other)

    # --------------------------------------------------------------- printing
    def __str__(self) -> str:
        text = self._str
        if text is None:
            text = _to_str(self)
            object.__setattr__(self, "_str", text)
        return text

    def __repr__(self) -> str:
        return f"parse({str(self)!r})"

    def sort_key(self) -> tuple[int, str]:
        """A deterministic total order (size-ish, then text) used to canonicalise n-ary operands."""
        return (len(str(self)), str(self))


def _rebuild(cls: type[Formula], name: Any, args: tuple[Formula, ...]) -> Formula:
    if cls is Const:
        return Const(bool(name))
    if cls is Atom:
        return Atom(name)
    return cls(*args)


class Const(Formula):
    """``true`` or ``false``."""

    __slots__ = ()

    def __new__(cls, value: bool) -> Const:
        if not isinstance(value, bool):
            raise TypeError(f"Const: value must be a bool, got {type(value).__name__}")
        return cls._make((), value)

    @property
    def value(self) -> bool:
        return bool(self._name)


class Atom(Formula):
    """An atomic proposition (a sensor AP or a mode symbol)."""

    __slots__ = ()

    def __new__(cls, name: str) -> Atom:
        if not isinstance(name, str) or not name:
            raise ValueError(f"Atom: name must be a non-empty string, got {name!r}")
        return cls._make((), name)

    @property
    def name(self) -> str:
        return str(self._name)


TRUE: Const = Const(True)
FALSE: Const = Const(False)


class _Unary(Formula):
    __slots__ = ()

    def __new__(cls, arg: Formula) -> Self:
        return cls._make((_check(arg, cls.__name__),))

    @property
    def arg(self) -> Formula:
        return self._args[0]


class Not(_Unary):
    """``!a``."""

    __slots__ = ()
    symbol = "!"


class Next(_Unary):
    """``X a``: ``a`` holds at the next position."""

    __slots__ = ()
    propositional = False
    symbol = "X"


class Finally(_Unary):
    """``F a``: ``a`` holds now or later."""

    __slots__ = ()
    propositional = False
    symbol = "F"


class Globally(_Unary):
    """``G a``: ``a`` holds now and forever."""

    __slots__ = ()
    propositional = False
    symbol = "G"


class _Binary(Formula):
    __slots__ = ()

    def __new__(cls, left: Formula, right: Formula) -> Self:
        return cls._make((_check(left, cls.__name__), _check(right, cls.__name__)))

    @property
    def left(self) -> Formula:
        return self._args[0]

    @property
    def right(self) -> Formula:
        return self._args[1]


class Implies(_Binary):
    """``a -> b``."""

    __slots__ = ()
    symbol = "->"
    precedence = 1


class Equiv(_Binary):
    """``a <-> b``."""

    __slots__ = ()
    symbol = "<->"
    precedence = 1


class Xor(_Binary):
    """``a xor b``."""

    __slots__ = ()
    symbol = "xor"
    precedence = 3


class Until(_Binary):
    """``a U b``: ``b`` eventually holds and ``a`` holds until then (strong)."""

    __slots__ = ()
    propositional = False
    symbol = "U"
    precedence = 5


class Release(_Binary):
    """``a R b``: ``b`` holds until and including when ``a`` holds (or forever)."""

    __slots__ = ()
    propositional = False
    symbol = "R"
    precedence = 5


class WeakUntil(_Binary):
    """``a W b``: ``a U b`` or ``G a``."""

    __slots__ = ()
    propositional = False
    symbol = "W"
    precedence = 5


class StrongRelease(_Binary):
    """``a M b``: ``a R b`` and ``F a``."""

    __slots__ = ()
    propositional = False
    symbol = "M"
    precedence = 5


class _NAry(Formula):
    __slots__ = ()
    _unit: ClassVar[bool]

    # And()/Or() of no or one operand is its unit or that operand, not an _NAry node. Python allows
    # __new__ to return another type and mypy types the call as the annotation says, but it flags the
    # annotation itself: hence the one [misc] ignore.
    def __new__(cls, *args: Formula) -> Formula:  # type: ignore[misc]
        flat: list[Formula] = []
        for arg in args:
            _check(arg, cls.__name__)
            if type(arg) is cls:
                flat.extend(arg._args)
            else:
                flat.append(arg)
        if not flat:
            return Const(cls._unit)
        if len(flat) == 1:
            return flat[0]
        return cls._make(tuple(flat))


class And(_NAry):
    """``a & b & ...`` (flattened; ``And()`` is ``true``, ``And(a)`` is ``a``)."""

    __slots__ = ()
    symbol = "&"
    precedence = 4
    _unit = True


class Or(_NAry):
    """``a | b | ...`` (flattened; ``Or()`` is ``false``, ``Or(a)`` is ``a``)."""

    __slots__ = ()
    symbol = "|"
    precedence = 2
    _unit = False


#: every unary operator class, and every operator class that takes two operands (``And`` / ``Or`` take any number)
UNARY_OPERATORS: tuple[type[Formula], ...] = (Not, Next, Finally, Globally)
BINARY_OPERATORS: tuple[type[Formula], ...] = (And, Or, Implies, Equiv, Xor, Until, Release, WeakUntil, StrongRelease)


# ------------------------------------------------------------------ printing
def _parenthesised(f: Formula) -> bool:
    """A child of an operator is parenthesised unless it binds tightest (unary operators, atoms, constants)."""
    return f.precedence != 6


def _to_str(root: Formula) -> str:
    """Spot-syntax text of ``root``, built with an explicit stack (no recursion, any depth).

    Subformulas whose text is already cached are reused; the others are
    written out without being cached (caching every subformula of a deep
    chain would hold quadratically many characters).
    """
    out: list[str] = []
    stack: list[Formula | str] = [root]
    while stack:
        item = stack.pop()
        if isinstance(item, str):
            out.append(item)
            continue
        f = item
        cached = f._str if f is not root else None
        if cached is not None:
            out.append(cached)
        elif isinstance(f, Const):
            out.append("true" if f.value else "false")
        elif isinstance(f, Atom):
            out.append(_quote(f.name))
        elif isinstance(f, _Unary | _NAry | _Binary):
            parts: list[Formula | str] = []
            if isinstance(f, _Unary):
                parts.append(f.symbol)
                operands: tuple[Formula, ...] = (f.arg,)
            else:
                operands = f.args
            for i, a in enumerate(operands):
                if i:
                    parts.append(f" {f.symbol} ")
                if _parenthesised(a):
                    parts.extend(("(", a, ")"))
                else:
                    parts.append(a)
            stack.extend(reversed(parts))
        else:  # pragma: no cover - closed hierarchy
            raise TypeError(f"cannot print {type(f).__name__}")
    return "".join(out)
