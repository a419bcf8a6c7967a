"""HOA v1 (Hanoi Omega-Automata format) writer and reader.

The writer emits what Spot's ``autfilt`` reads: explicit edge labels over AP
indices, transition- or state-based marks and a generalized Büchi
``Acceptance:`` line. The reader accepts the subset Spot's ``translate`` and
``ltl2tgba`` produce for LTL: generalized Büchi acceptance (``t``, ``f``, or a
conjunction of ``Inf(i)``), explicit labels (``[0&!1 | 2]``, aliases
``@name``), state- or transition-based marks, one or several (non-alternating)
start states. Anything else raises ``ValueError`` saying what is unsupported
or malformed (also for truncated or garbled input: never an ``IndexError``);
labels may nest at most :data:`MAX_LABEL_DEPTH` deep, aliases may not refer
to themselves, and an automaton has at most
:data:`~steer_envs.ltl.automaton.MAX_STATES` states.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

from steer_envs.io import atomic_write_text
from steer_envs.ltl.automaton import MAX_STATES, Automaton, Edge
from steer_envs.ltl.guards import MAX_APS, ap_mask, cubes_to_str, full_mask, isop

__all__ = ["MAX_LABEL_DEPTH", "from_hoa", "to_hoa", "write_hoa"]

#: deepest nesting of ``!`` / ``(`` / alias references in one HOA edge label
MAX_LABEL_DEPTH = 100


def _hoa_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def to_hoa(aut: Automaton) -> str:
    """Serialise ``aut`` in HOA v1.

    >>> from steer_envs.ltl.buchi import translate
    >>> text = to_hoa(translate("F a"))
    >>> text.splitlines()[:3]
    ['HOA: v1', 'name: "Fa"', 'States: 2']
    >>> from_hoa(text).accepts([], [{"a"}])
    True
    """
    k = aut.num_sets
    lines = ["HOA: v1"]
    if aut.name:
        lines.append(f"name: {_hoa_string(aut.name)}")
    lines.append(f"States: {aut.num_states}")
    lines.append(f"Start: {aut.initial}")
    lines.append(f"AP: {len(aut.aps)}" + "".join(" " + _hoa_string(ap) for ap in aut.aps))
    if k == 0:
        lines.append("acc-name: all")
        lines.append("Acceptance: 0 t")
    else:
        lines.append("acc-name: Buchi" if k == 1 else f"acc-name: generalized-Buchi {k}")
        lines.append(f"Acceptance: {k} " + "&".join(f"Inf({i})" for i in range(k)))
    lines.append("properties: trans-labels explicit-labels " + ("state-acc" if aut.state_based else "trans-acc"))
    lines.append("--BODY--")
    indices = [str(j) for j in range(len(aut.aps))]
    by_state: dict[int, list[Edge]] = {q: [] for q in range(aut.num_states)}
    for e in aut.edges:
        by_state[e.src].append(e)
    for q in range(aut.num_states):
        head = f"State: {q}"
        if aut.state_names:
            head += " " + _hoa_string(aut.state_names[q])
        marks_of_state: frozenset[int] = frozenset()
        if aut.state_based and by_state[q]:
            marks_of_state = by_state[q][0].acc
            if any(e.acc != marks_of_state for e in by_state[q]):
                raise ValueError(f"to_hoa: state-based automaton has different marks on the edges of state {q}")
            if marks_of_state:
                head += " {" + " ".join(str(i) for i in sorted(marks_of_state)) + "}"
        lines.append(head)
        for e in by_state[q]:
            cubes = isop(e.guard, len(aut.aps))
            label = "t" if cubes == [()] else cubes_to_str(cubes, indices, and_="&", or_=" | ")
            line = f"[{label}] {e.dst}"
            if not aut.state_based and e.acc:
                line += " {" + " ".join(str(i) for i in sorted(e.acc)) + "}"
            lines.append(line)
    lines.append("--END--")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ reader
_TOKEN = re.compile(
    r"""
    (?P<ws>\s+|/\*.*?\*/)
  | (?P<string>"(?:[^"\\]|\\.)*")
  | (?P<header>[A-Za-z@][A-Za-z0-9_-]*:)
  | (?P<marker>--BODY--|--END--|--ABORT--)
  | (?P<int>\d+)
  | (?P<ident>@?[A-Za-z_][A-Za-z0-9_-]*)
  | (?P<punct>[!&|()\[\]{}])
    """,
    re.VERBOSE | re.DOTALL,
)


@dataclass
class _Tok:
    kind: str
    text: str
    pos: int


def write_hoa(aut: Automaton, path: str | os.PathLike[str]) -> None:
    """Write :func:`to_hoa` of ``aut`` to ``path`` atomically (temp file in the target's folder, ``fsync``, rename).

    >>> import os, tempfile
    >>> from steer_envs.ltl.buchi import translate
    >>> path = os.path.join(tempfile.mkdtemp(), "fa.hoa")
    >>> write_hoa(translate("F a"), path)
    >>> from_hoa(open(path).read()).accepts([], [{"a"}])
    True
    """
    atomic_write_text(path, to_hoa(aut))


def _lex(text: str) -> list[_Tok]:
    toks: list[_Tok] = []
    i = 0
    while i < len(text):
        m = _TOKEN.match(text, i)
        if m is None:
            raise ValueError(f"from_hoa: unexpected character {text[i]!r} at offset {i}")
        kind = m.lastgroup or ""
        if kind != "ws":
            toks.append(_Tok(kind, m.group(), i))
        i = m.end()
    return toks


def _unquote(s: str) -> str:
    return re.sub(r"\\(.)", r"\1", s[1:-1])


class _LabelParser:
    """Boolean label expressions over AP indices: ``t f int ! & | ( ) @alias`` (nesting bounded)."""

    def __init__(
        self,
        toks: list[_Tok],
        n: int,
        aliases: dict[str, list[_Tok]],
        depth: int = 0,
        using: frozenset[str] = frozenset(),
    ) -> None:
        self.toks, self.i, self.n, self.aliases = toks, 0, n, aliases
        self.depth, self.using = depth, using

    def peek(self) -> str:
        return self.toks[self.i].text if self.i < len(self.toks) else ""

    def parse(self) -> int:
        value = self.disj()
        if self.i != len(self.toks):
            raise ValueError(f"from_hoa: unexpected {self.peek()!r} in a label")
        return value

    def _enter(self) -> None:
        self.depth += 1
        if self.depth > MAX_LABEL_DEPTH:
            raise ValueError(f"from_hoa: a label nests deeper than MAX_LABEL_DEPTH={MAX_LABEL_DEPTH}")

    def disj(self) -> int:
        v = self.conj()
        while self.peek() == "|":
            self.i += 1
            v |= self.conj()
        return v

    def conj(self) -> int:
        v = self.atom()
        while self.peek() == "&":
            self.i += 1
            v &= self.atom()
        return v

    def atom(self) -> int:
        if self.i >= len(self.toks):
            raise ValueError("from_hoa: label ends unexpectedly")
        tok = self.toks[self.i]
        self.i += 1
        full = full_mask(self.n)
        if tok.text == "!":
            self._enter()
            v = full & ~self.atom()
            self.depth -= 1
            return v
        if tok.text == "(":
            self._enter()
            v = self.disj()
            if self.peek() != ")":
                raise ValueError("from_hoa: missing ')' in a label")
            self.i += 1
            self.depth -= 1
            return v
        if tok.text == "t":
            return full
        if tok.text == "f":
            return 0
        if tok.kind == "int":
            j = int(tok.text)
            if j >= self.n:
                raise ValueError(f"from_hoa: label uses AP {j} but only {self.n} APs are declared")
            return ap_mask(j, self.n)
        if tok.text.startswith("@"):
            if tok.text not in self.aliases:
                raise ValueError(f"from_hoa: undefined alias {tok.text}")
            if tok.text in self.using:
                raise ValueError(f"from_hoa: alias {tok.text} refers to itself")
            self._enter()
            inner = _LabelParser(self.aliases[tok.text], self.n, self.aliases, self.depth, self.using | {tok.text})
            v = inner.parse()
            self.depth -= 1
            return v
        raise ValueError(f"from_hoa: unexpected {tok.text!r} in a label")


def _int(tok: _Tok | None, what: str) -> int:
    """A non-negative int token, or a ``ValueError`` saying what was expected."""
    if tok is None:
        raise ValueError(f"from_hoa: {what} is missing (input ends early)")
    if tok.kind != "int":
        raise ValueError(f"from_hoa: {what} must be a non-negative int, got {tok.text!r}")
    return int(tok.text)


def _at(toks: list[_Tok], i: int) -> _Tok | None:
    return toks[i] if 0 <= i < len(toks) else None


def _parse_acceptance(toks: list[_Tok]) -> list[int] | None:
    """The ``Inf`` sets of a generalized Büchi condition (``None`` for ``f``)."""
    if len(toks) < 2 or toks[0].kind != "int":
        raise ValueError("from_hoa: malformed Acceptance: header")
    body = [t.text for t in toks[1:]]
    while body and body[0] == "(" and body[-1] == ")":
        body = body[1:-1]
    if body == ["t"]:
        return []
    if body == ["f"]:
        return None
    sets: list[int] = []
    i = 0
    while i < len(body):
        if body[i : i + 2] != ["Inf", "("] or i + 3 >= len(body) or body[i + 3] != ")":
            raise ValueError(
                "from_hoa: only generalized Büchi acceptance (t, f, or Inf(i)&Inf(j)&...) is supported, got "
                + " ".join(body)
            )
        if not body[i + 2].isdigit():
            raise ValueError(f"from_hoa: Inf() needs a set number, got {body[i + 2]!r}")
        sets.append(int(body[i + 2]))
        i += 4
        if i < len(body):
            if body[i] != "&":
                raise ValueError(
                    "from_hoa: only generalized Büchi acceptance (conjunctions of Inf(i)) is supported, got "
                    + " ".join(body)
                )
            i += 1
    return sets


def _closing(toks: list[_Tok], start: int, closer: str, what: str) -> int:
    at = next((k for k in range(start, len(toks)) if toks[k].text == closer), None)
    if at is None:
        raise ValueError(f"from_hoa: unterminated {what} (no {closer!r})")
    return at


@dataclass
class _Header:
    """What the HOA header lines declare."""

    num_states: int | None = None
    starts: list[int] = field(default_factory=list)
    aps: tuple[str, ...] = ()
    sets: list[int] | None = field(default_factory=list)
    name: str = ""
    aliases: dict[str, list[_Tok]] = field(default_factory=dict)


def _header_lines(toks: list[_Tok], body_at: int) -> list[tuple[str, list[_Tok]]]:
    """The ``(key, arguments)`` of every header line before ``--BODY--``."""
    headers: list[tuple[str, list[_Tok]]] = []
    for tok in toks[:body_at]:
        if tok.kind == "header":
            headers.append((tok.text[:-1], []))
        elif not headers:
            raise ValueError(f"from_hoa: unexpected {tok.text!r} before the first header")
        else:
            headers[-1][1].append(tok)
    return headers


def _read_aps(args: list[_Tok]) -> tuple[str, ...]:
    """The names of an ``AP:`` header."""
    count = _int(_at(args, 0), "AP: count")
    if count > MAX_APS:
        raise ValueError(f"from_hoa: AP: declares {count} APs; at most {MAX_APS} are supported")
    if any(t.kind != "string" for t in args[1:]):
        raise ValueError("from_hoa: AP: names must be double-quoted strings")
    aps = tuple(_unquote(t.text) for t in args[1:])
    if len(aps) != count:
        raise ValueError(f"from_hoa: AP: declares {count} APs but lists {len(aps)}")
    return aps


def _read_header(headers: list[tuple[str, list[_Tok]]]) -> _Header:
    """Interpret the header lines that matter for a generalized Büchi automaton."""
    head = _Header()
    for key, args in headers:
        if key == "States":
            head.num_states = _int(_at(args, 0), "States:")
            if head.num_states > MAX_STATES:
                raise ValueError(f"from_hoa: States: {head.num_states} exceeds MAX_STATES={MAX_STATES}")
        elif key == "Start":
            if any(t.text == "&" for t in args):
                raise ValueError("from_hoa: alternating automata (conjunctive Start) are not supported")
            head.starts.append(_int(_at(args, 0), "Start:"))
        elif key == "AP":
            head.aps = _read_aps(args)
        elif key == "Acceptance":
            head.sets = _parse_acceptance(args)
        elif key == "name":
            head.name = _unquote(args[0].text) if args and args[0].kind == "string" else ""
        elif key == "Alias":
            if not args or not args[0].text.startswith("@"):
                raise ValueError("from_hoa: Alias: needs an @name and a label")
            head.aliases[args[0].text] = args[1:]
    if not head.starts:
        raise ValueError("from_hoa: no Start: state")
    return head


class _BodyReader:
    """Reads the states and labelled edges between ``--BODY--`` and ``--END--``."""

    def __init__(self, body: list[_Tok], head: _Header) -> None:
        self.body, self.head = body, head
        self.remap = {} if head.sets is None else {s: i for i, s in enumerate(head.sets)}
        self.edges: list[Edge] = []
        self.names: dict[int, str] = {}
        self.state: int | None = None
        self.state_marks: frozenset[int] = frozenset()
        self.state_based = False

    def marks(self, tok_list: list[_Tok]) -> frozenset[int]:
        """The acceptance sets named in ``{...}``, renumbered to ``0..num_sets-1``."""
        return frozenset(self.remap[int(t.text)] for t in tok_list if t.kind == "int" and int(t.text) in self.remap)

    def read(self) -> None:
        """Read the whole body into ``edges``, ``names`` and ``state_based``."""
        body = self.body
        i = 0
        while i < len(body):
            tok = body[i]
            if tok.text in ("--END--", "--ABORT--"):
                if tok.text == "--ABORT--":
                    raise ValueError("from_hoa: the producer aborted the automaton (--ABORT--)")
                break
            if tok.text == "State:":
                i = self._state(i + 1)
                continue
            if self.state is None:
                raise ValueError(f"from_hoa: edge before any State: ({tok.text!r})")
            if tok.text != "[":
                raise ValueError("from_hoa: implicit (unlabelled) edges are not supported")
            i = self._edge(i, self.state)

    def _state(self, i: int) -> int:
        """Read a ``State:`` line from just after the keyword; the index after it."""
        body = self.body
        nxt = _at(body, i)
        if nxt is not None and nxt.text == "[":
            raise ValueError("from_hoa: state labels are not supported (use edge labels)")
        self.state = _int(nxt, "State:")
        i += 1
        if i < len(body) and body[i].kind == "string":
            self.names[self.state] = _unquote(body[i].text)
            i += 1
        self.state_marks = frozenset()
        if i < len(body) and body[i].text == "{":
            j = _closing(body, i, "}", "state marks")
            self.state_marks = self.marks(body[i + 1 : j])
            self.state_based = True
            i = j + 1
        return i

    def _edge(self, i: int, state: int) -> int:
        """Read one ``[label] dst {marks}`` edge starting at ``[``; the index after it."""
        body = self.body
        close = _closing(body, i, "]", "edge label")
        guard = _LabelParser(body[i + 1 : close], len(self.head.aps), self.head.aliases).parse()
        i = close + 1
        dst = _int(_at(body, i), "an edge's destination state")
        i += 1
        if i < len(body) and body[i].text == "&":
            raise ValueError("from_hoa: alternating automata (conjunctive destinations) are not supported")
        acc = self.state_marks
        if i < len(body) and body[i].text == "{":
            k = _closing(body, i, "}", "edge marks")
            acc = acc | self.marks(body[i + 1 : k])
            i = k + 1
        if guard:
            self.edges.append(Edge(state, dst, guard, acc))
        return i


def _assemble(head: _Header, reader: _BodyReader) -> Automaton:
    """The :class:`Automaton`; several start states get one fresh initial state copying their edges."""
    starts, edges, names = head.starts, reader.edges, reader.names
    total = (
        head.num_states
        if head.num_states is not None
        else 1 + max([*starts, *(e.dst for e in edges), *(e.src for e in edges)])
    )
    if total > MAX_STATES:
        raise ValueError(f"from_hoa: the automaton names state {total - 1}; at most MAX_STATES={MAX_STATES} states")
    state_names = tuple(names.get(q, "") for q in range(total)) if names else ()
    if len(starts) > 1:  # a fresh initial state copying the edges of every start state
        fresh = total
        edges += [Edge(fresh, e.dst, e.guard, e.acc) for e in list(edges) if e.src in starts]
        total += 1
        if state_names:
            state_names = (*state_names, "start")
        initial = fresh
    else:
        initial = starts[0]
    return Automaton(
        aps=head.aps,
        num_states=total,
        initial=initial,
        edges=tuple(edges),
        num_sets=1 if head.sets is None else len(head.sets),
        state_based=reader.state_based,
        state_names=state_names,
        name=head.name,
    )


def from_hoa(text: str) -> Automaton:
    """Parse one HOA v1 automaton (see the module doc for the supported subset)."""
    if not isinstance(text, str):
        raise TypeError(f"from_hoa: `text` must be a str, got {type(text).__name__}")
    toks = _lex(text)
    if not toks or toks[0].text != "HOA:":
        raise ValueError("from_hoa: input does not start with 'HOA:'")
    try:
        body_at = next(i for i, t in enumerate(toks) if t.text == "--BODY--")
    except StopIteration:
        raise ValueError("from_hoa: missing --BODY--") from None
    head = _read_header(_header_lines(toks, body_at))
    reader = _BodyReader(toks[body_at + 1 :], head)
    reader.read()
    return _assemble(head, reader)
