"""Parser for LTL formulas in Spot's syntax.

Accepted (as in Spot's ``parsetl``):

- constants ``true``/``false`` (any case), ``1``/``0``;
- atomic propositions: identifiers ``[a-zA-Z_.][a-zA-Z0-9_.]*`` that do not
  start with ``F``, ``G`` or ``X`` (unless a digit follows: ``X1`` is an AP, ``Xa``
  is ``X a``), or any text in double quotes (``"my ap"``, ``\\"`` escapes);
- unary ``!``/``~`` (not), ``X`` (next), ``F``/``<>`` (finally), ``G``/``[]``
  (globally);
- binary, from loosest to tightest: ``->``/``=>``/``-->`` and
  ``<->``/``<=>``/``<-->`` (right-associative), ``|``/``||``/``\\/``/``+``,
  ``xor``/``^``, ``&``/``&&``/``/\\``, and ``U R W M`` (``V`` = ``R``,
  right-associative); unary operators bind tighter than every binary one.

Like Spot, where an operand has just been read the letters ``U R V W M``
start a binary operator, so ``a Ub`` is ``a U b`` (but ``aUb`` is one AP).
PSL/SERE syntax (``{...}``, ``[*]``) is not supported.

A syntax error raises :class:`LTLParseError` (a ``ValueError``) naming the
1-based column and what was expected there. The parser keeps its own stack
instead of recursing, so deeply nested text parses up to
:data:`MAX_PARSE_DEPTH` open grammar rules (thousands of parentheses) and
beyond that raises :class:`LTLParseError` naming the limit, never a
``RecursionError``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Generator
from dataclasses import dataclass

from steer_envs.ltl import syntax as s
from steer_envs.ltl.syntax import Formula

__all__ = ["MAX_PARSE_DEPTH", "LTLParseError", "parse"]

_OPERAND = "a formula (atomic proposition, true/false, '(', or a unary operator ! X F G)"


#: characters of context shown either side of the error column in a long formula's message
_CONTEXT = 60


class LTLParseError(ValueError):
    """A syntax error in an LTL formula.

    Attributes:
        text: the formula text.
        column: 1-based column of the offending token.
        expected: what the parser expected there.
    """

    def __init__(self, text: str, column: int, expected: str, found: str) -> None:
        self.text = text
        self.column = column
        self.expected = expected
        self.found = found
        shown, at = text, column - 1
        if len(text) > 2 * _CONTEXT:  # long text: a window around the column
            lo = max(0, at - _CONTEXT)
            hi = min(len(text), at + _CONTEXT)
            shown = ("..." if lo else "") + text[lo:hi] + ("..." if hi < len(text) else "")
            at = at - lo + (3 if lo else 0)
        caret = " " * at + "^"
        super().__init__(f"LTL syntax error at column {column}: expected {expected}, got {found}\n  {shown}\n  {caret}")


@dataclass(frozen=True)
class _Token:
    kind: str  # ap const not unary binop and or xor implies equiv lparen rparen end
    value: str
    column: int  # 1-based

    def describe(self) -> str:
        if self.kind == "end":
            return "end of input"
        if self.kind == "ap":
            return f"atomic proposition {self.value!r}"
        return repr(self.value)


_SYMBOLS: tuple[tuple[str, str, str], ...] = (
    # (text, kind, canonical value) -- longest first
    ("<-->", "equiv", "<->"),
    ("-->", "implies", "->"),
    ("<->", "equiv", "<->"),
    ("<=>", "equiv", "<->"),
    ("->", "implies", "->"),
    ("=>", "implies", "->"),
    ("&&", "and", "&"),
    ("||", "or", "|"),
    ("/\\", "and", "&"),
    ("\\/", "or", "|"),
    ("[]", "unary", "G"),
    ("<>", "unary", "F"),
    ("&", "and", "&"),
    ("|", "or", "|"),
    ("+", "or", "|"),
    ("^", "xor", "xor"),
    ("!", "not", "!"),
    ("~", "not", "!"),
    ("(", "lparen", "("),
    (")", "rparen", ")"),
)
_WORD_CHARS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_.")
_BINOPS = {"U": "U", "R": "R", "V": "R", "W": "W", "M": "M"}


#: token kinds after which the scanner expects a binary operator, not an operand
_ENDS_OPERAND = frozenset({"ap", "const", "rparen"})


def _tokenize(text: str) -> list[_Token]:
    tokens: list[_Token] = []
    i, n = 0, len(text)
    expect_operand = True  # Spot's INITIAL vs not_prop scanner condition
    while i < n:
        if text[i].isspace():
            i += 1
            continue
        tok, i = _next_token(text, i, expect_operand)
        tokens.append(tok)
        expect_operand = tok.kind not in _ENDS_OPERAND
    tokens.append(_Token("end", "", n + 1))
    return tokens


def _next_token(text: str, i: int, expect_operand: bool) -> tuple[_Token, int]:
    """The token starting at ``text[i]`` (not a space) and the index after it."""
    ch = text[i]
    col = i + 1
    if ch == '"':
        return _quoted(text, i)
    for sym, kind, value in _SYMBOLS:
        if text.startswith(sym, i):
            return _Token(kind, value, col), i + len(sym)
    if ch in _WORD_CHARS:
        return _word(text, i, expect_operand)
    if ch in "{}[]*;:":
        raise LTLParseError(text, col, "an LTL operator (PSL/SERE syntax is not supported)", repr(ch))
    raise LTLParseError(text, col, _OPERAND if expect_operand else "a binary operator", repr(ch))


def _quoted(text: str, i: int) -> tuple[_Token, int]:
    """A double-quoted atomic proposition starting at ``text[i] == '"'`` (backslash escapes)."""
    n, col = len(text), i + 1
    j = i + 1
    chars: list[str] = []
    while j < n and text[j] != '"':
        if text[j] == "\\" and j + 1 < n:
            j += 1
        chars.append(text[j])
        j += 1
    if j >= n:
        raise LTLParseError(text, col, "a closing '\"' for the quoted atomic proposition", "end of input")
    if not chars:
        raise LTLParseError(text, col, "a non-empty quoted atomic proposition", '""')
    return _Token("ap", "".join(chars), col), j + 1


def _word(text: str, i: int, expect_operand: bool) -> tuple[_Token, int]:
    """A unary ``F G X``, a binary letter operator, ``xor``, a constant or an atomic proposition."""
    n, col, ch = len(text), i + 1, text[i]
    if ch in "FGX" and not (i + 1 < n and text[i + 1].isdigit()):
        return _Token("unary", ch, col), i + 1
    if not expect_operand and ch in _BINOPS:
        return _Token("binop", _BINOPS[ch], col), i + 1
    j = i
    while j < n and text[j] in _WORD_CHARS:
        j += 1
    word = text[i:j]
    if word == "xor":
        return _Token("xor", "xor", col), j
    if word in _BINOPS:
        return _Token("binop", _BINOPS[word], col), j
    if word.lower() in ("true", "false") or word in ("1", "0"):
        return _Token("const", "true" if word.lower() in ("true", "1") else "false", col), j
    if word[0].isdigit():
        raise LTLParseError(text, col, 'an atomic proposition not starting with a digit (quote it: "...")', repr(word))
    return _Token("ap", word, col), j


#: the parser's explicit stack holds at most this many open grammar rules (about 7 per open
#: parenthesis, 1 per unary operator or right-nested binary one) before it refuses the text.
MAX_PARSE_DEPTH = 100_000

# A grammar rule is a generator: it yields the rule it needs parsed next (a bound method returning
# a new generator) and is sent that rule's result; its return value is its own result. ``_run``
# drives the rules with an explicit stack, so nesting depth is bounded by MAX_PARSE_DEPTH, not by
# Python's recursion limit.
_Rule = Generator[Callable[[], "_Rule"], Formula, Formula]


class _Parser:
    def __init__(self, text: str) -> None:
        self.text = text
        self.tokens = _tokenize(text)
        self.pos = 0

    @property
    def tok(self) -> _Token:
        return self.tokens[self.pos]

    def fail(self, expected: str) -> LTLParseError:
        return LTLParseError(self.text, self.tok.column, expected, self.tok.describe())

    def parse(self) -> Formula:
        if self.tok.kind == "end":
            raise self.fail(_OPERAND)
        f = self._run(self.implication)
        if self.tok.kind != "end":
            if self.tok.kind == "rparen":
                raise self.fail("a binary operator or end of input (unbalanced ')')")
            raise self.fail("a binary operator or end of input")
        return f

    def _run(self, start: Callable[[], _Rule]) -> Formula:
        stack: list[_Rule] = [start()]
        value: Formula | None = None
        while True:
            try:
                rule = stack[-1].send(value)  # type: ignore[arg-type]  # None primes a fresh rule
            except StopIteration as done:
                stack.pop()
                value = done.value
                if not stack:
                    return value
                continue
            if len(stack) >= MAX_PARSE_DEPTH:
                raise self.fail(f"less nesting (the formula nests deeper than MAX_PARSE_DEPTH={MAX_PARSE_DEPTH})")
            stack.append(rule())
            value = None

    def implication(self) -> _Rule:
        left = yield self.disjunction
        tok = self.tok
        if tok.kind in ("implies", "equiv"):
            self.pos += 1
            right = yield self.implication
            return s.Implies(left, right) if tok.kind == "implies" else s.Equiv(left, right)
        return left

    def disjunction(self) -> _Rule:
        return s.Or(*(yield from self._operands("or", self.exclusive)))

    def exclusive(self) -> _Rule:
        return functools.reduce(s.Xor, (yield from self._operands("xor", self.conjunction)))  # left-associative

    def conjunction(self) -> _Rule:
        return s.And(*(yield from self._operands("and", self.temporal)))

    def _operands(
        self, op: str, operand: Callable[[], _Rule]
    ) -> Generator[Callable[[], _Rule], Formula, list[Formula]]:
        """The operands of ``operand (op operand)*``, in order."""
        args = [(yield operand)]
        while self.tok.kind == op:
            self.pos += 1
            args.append((yield operand))
        return args

    def temporal(self) -> _Rule:
        left = yield self.unary
        tok = self.tok
        if tok.kind == "binop":
            self.pos += 1
            right = yield self.temporal
            cls = {"U": s.Until, "R": s.Release, "W": s.WeakUntil, "M": s.StrongRelease}[tok.value]
            return cls(left, right)
        return left

    def unary(self) -> _Rule:
        tok = self.tok
        if tok.kind == "not":
            self.pos += 1
            return s.Not((yield self.unary))
        if tok.kind == "unary":
            self.pos += 1
            cls = {"X": s.Next, "F": s.Finally, "G": s.Globally}[tok.value]
            return cls((yield self.unary))
        if tok.kind == "ap":  # the common leaves, without a rule of their own
            self.pos += 1
            return s.Atom(tok.value)
        return (yield self.primary)

    def primary(self) -> _Rule:
        tok = self.tok
        if tok.kind == "ap":
            self.pos += 1
            return s.Atom(tok.value)
        if tok.kind == "const":
            self.pos += 1
            return s.TRUE if tok.value == "true" else s.FALSE
        if tok.kind == "lparen":
            self.pos += 1
            if self.tok.kind == "rparen":
                raise self.fail(_OPERAND + " inside '()'")
            inner = yield self.implication
            if self.tok.kind != "rparen":
                raise self.fail(f"')' to close the '(' at column {tok.column}")
            self.pos += 1
            return inner
        raise self.fail(_OPERAND)


def parse(text: str | Formula) -> Formula:
    """Parse LTL ``text`` (Spot syntax) into an immutable :class:`Formula`.

    A :class:`Formula` is returned unchanged, so APIs can accept either.
    Malformed text raises :class:`LTLParseError` (a ``ValueError``) pointing at the column.

    >>> f = parse("G(a -> F b)")
    >>> f, sorted(f.atoms())
    (parse('G(a -> Fb)'), ['a', 'b'])
    >>> parse("G (a &")
    Traceback (most recent call last):
    ...
    steer_envs.ltl.parser.LTLParseError: LTL syntax error at column 7: expected a formula ...
    """
    if isinstance(text, Formula):
        return text
    if not isinstance(text, str):
        raise TypeError(f"parse: `text` must be a str (LTL in Spot syntax) or a Formula, got {type(text).__name__}")
    return _Parser(text).parse()
