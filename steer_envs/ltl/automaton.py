"""Explicit (transition-based, generalized) Büchi automata over AP valuations.

An :class:`Automaton` has numbered states, one initial state, and edges
``src -> dst`` labelled by a guard (a truth table over ``aps``, see
:mod:`steer_envs.ltl.guards`) and a set of acceptance marks. A run is accepting
when, for every acceptance set ``0 .. num_sets - 1``, it takes edges carrying
that mark infinitely often (generalized Büchi; ``num_sets == 0`` accepts every
infinite run). A *state-based* automaton (``state_based=True``, e.g. the
output of :meth:`Automaton.degeneralize`) carries the marks of each state on
all of its outgoing edges, which is the same condition.

Lasso words are checked exactly: the product of the automaton with the
word's position cycle is finite, and the word is accepted iff some reachable
strongly connected component of the product has an internal edge of every
acceptance set (Tarjan's algorithm).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from typing import TYPE_CHECKING, Any

from steer_envs.core.validation import BoundExceeded, boolean, describe, integer
from steer_envs.ltl.guards import MAX_APS, GuardLetter, full_mask, guard_to_str, remap_guard, valuation_of

if TYPE_CHECKING:
    import networkx as nx

__all__ = ["MAX_STATES", "Automaton", "Edge", "backward_closure"]

#: most states an automaton may have (HOA input declares its count; each state costs memory up front)
MAX_STATES = 10_000_000


@dataclass(frozen=True)
class Edge:
    """One transition: ``src -> dst`` on the valuations in ``guard``, carrying marks ``acc``."""

    src: int
    dst: int
    guard: int
    acc: frozenset[int] = frozenset()

    @property
    def acc_bits(self) -> int:
        return sum(1 << i for i in self.acc)


@dataclass(frozen=True, eq=False)
class Automaton:
    """A (transition-based) generalized Büchi automaton with explicit states.

    Args:
        aps: atomic propositions; valuation bit ``j`` is ``aps[j]``.
        num_states: states are ``0 .. num_states - 1``.
        initial: the initial state.
        edges: the transitions (guards are never empty).
        num_sets: number of generalized Büchi acceptance sets.
        state_based: acceptance marks belong to states (every outgoing edge of
            a state carries the state's marks); affects HOA output only.
        state_names: optional description of each state (e.g. its LTL obligation).
        name: optional automaton name (HOA ``name:``).
    """

    aps: tuple[str, ...]
    num_states: int
    initial: int
    edges: tuple[Edge, ...]
    num_sets: int = 0
    state_based: bool = False
    state_names: tuple[str, ...] = ()
    name: str = ""

    def __post_init__(self) -> None:
        if isinstance(self.aps, (str, bytes)):
            raise TypeError(f"Automaton: `aps` must be a sequence of AP names, not one string ({describe(self.aps)})")
        aps = tuple(str(a) for a in self.aps)
        if len(set(aps)) != len(aps):
            raise ValueError(f"Automaton: `aps` has duplicates: {aps}")
        if len(aps) > MAX_APS:
            raise ValueError(f"Automaton: at most {MAX_APS} APs are supported, got {len(aps)}")
        object.__setattr__(self, "aps", aps)
        if integer(self.num_states, "num_states", owner="Automaton") < 1:
            raise ValueError(f"Automaton: `num_states` must be >= 1, got {self.num_states}")
        if self.num_states > MAX_STATES:
            raise ValueError(f"Automaton: `num_states` may be at most MAX_STATES={MAX_STATES}, got {self.num_states}")
        if not 0 <= integer(self.initial, "initial", owner="Automaton") < self.num_states:
            raise ValueError(f"Automaton: `initial` must be in [0, {self.num_states}), got {self.initial}")
        if integer(self.num_sets, "num_sets", owner="Automaton") < 0:
            raise ValueError(f"Automaton: `num_sets` must be >= 0, got {self.num_sets}")
        boolean(self.state_based, "state_based", owner="Automaton")
        if not isinstance(self.name, str):
            raise TypeError(f"Automaton: `name` must be a str, got {describe(self.name)}")
        full = full_mask(len(aps))
        edges = tuple(self.edges)
        for e in edges:
            if not isinstance(e, Edge):
                raise TypeError(f"Automaton: `edges` must hold Edge objects, got {describe(e)}")
            for label in ("src", "dst", "guard"):
                integer(getattr(e, label), f"edge.{label}", owner="Automaton")
            if not (0 <= e.src < self.num_states and 0 <= e.dst < self.num_states):
                raise ValueError(f"Automaton: edge {e.src}->{e.dst} names a state outside [0, {self.num_states})")
            if not 0 < e.guard <= full:
                raise ValueError(f"Automaton: edge {e.src}->{e.dst} has an empty or out-of-range guard")
            if any(not 0 <= i < self.num_sets for i in e.acc):
                raise ValueError(f"Automaton: edge {e.src}->{e.dst} has marks {sorted(e.acc)} >= num_sets")
        object.__setattr__(self, "edges", edges)
        names = tuple(self.state_names)
        if names and len(names) != self.num_states:
            raise ValueError(f"Automaton: {len(names)} state names for {self.num_states} states")
        object.__setattr__(self, "state_names", names)

    # ------------------------------------------------------------- structure
    @cached_property
    def _out(self) -> tuple[tuple[tuple[int, int, int], ...], ...]:
        out: list[list[tuple[int, int, int]]] = [[] for _ in range(self.num_states)]
        for e in self.edges:
            out[e.src].append((e.dst, e.guard, e.acc_bits))
        return tuple(tuple(x) for x in out)

    @property
    def all_sets(self) -> int:
        """Bitmask of every acceptance set."""
        return (1 << self.num_sets) - 1

    def out_edges(self, state: int) -> list[Edge]:
        """Edges leaving ``state``."""
        return [e for e in self.edges if e.src == state]

    def valuation(self, letter: GuardLetter) -> int:
        """The valuation int of a letter (set of true APs, mapping AP -> bool, or int)."""
        return valuation_of(letter, self.aps)

    def successors(self, state: int, letter: GuardLetter) -> list[int]:
        """States reachable from ``state`` (an int in ``[0, num_states)``) in one step reading ``letter``."""
        state = integer(state, "state", low=0, high=self.num_states - 1, owner="Automaton.successors")
        v = self.valuation(letter)
        return sorted({dst for dst, guard, _ in self._out[state] if (guard >> v) & 1})

    @property
    def accepting_states(self) -> frozenset[int]:
        """For state-based automata: states whose outgoing edges carry every mark."""
        return frozenset(e.src for e in self.edges if e.acc_bits == self.all_sets)

    def guard_str(self, edge: Edge) -> str:
        """The guard of ``edge`` as a formula over the AP names."""
        return guard_to_str(edge.guard, self.aps)

    def __repr__(self) -> str:
        kind = "state-based " if self.state_based else ""
        return (
            f"Automaton({self.num_states} states, {len(self.edges)} edges, {kind}{self.num_sets} acceptance sets, "
            f"aps={self.aps})"
        )

    # ------------------------------------------------------------ acceptance
    def accepts(self, prefix: Iterable[GuardLetter], loop: Iterable[GuardLetter]) -> bool:
        """Is the lasso word ``prefix loop^omega`` accepted?

        Exact: searches the product with the word's positions for a reachable
        strongly connected component whose internal edges carry every mark.
        Letters are sets of true APs, mappings AP -> bool (real bools only) or
        valuation ints.
        """
        for label, part in (("prefix", prefix), ("loop", loop)):
            if isinstance(part, (str, bytes)) or not isinstance(part, Iterable):
                raise TypeError(f"accepts: `{label}` must be a sequence of letters, got {describe(part)}")
        word = [self.valuation(x) for x in prefix]
        k = len(word)
        word += [self.valuation(x) for x in loop]
        n = len(word)
        if n == k:
            raise ValueError("accepts: `loop` must have at least one letter")
        out = self._out
        all_sets = self.all_sets

        def successors(node: int) -> list[tuple[int, int]]:
            q, i = divmod(node, n)
            v = word[i]
            j = i + 1 if i + 1 < n else k
            return [(dst * n + j, acc) for dst, guard, acc in out[q] if (guard >> v) & 1]

        return _has_accepting_scc(self.initial * n, successors, all_sets)

    def is_empty(self) -> bool:
        """True when the automaton accepts no word at all."""
        return self.accepting_lasso() is None

    def accepting_lasso(self) -> tuple[list[int], list[int]] | None:
        """A short accepted lasso word ``(prefix, loop)`` of valuation ints, or None if empty."""
        sccs = _accepting_sccs(self)
        if not sccs:
            return None
        good = set().union(*sccs)
        # shortest path (BFS) from the initial state into any accepting SCC
        parent: dict[int, tuple[int, int] | None] = {self.initial: None}
        queue = deque([self.initial])
        target = None
        while queue:
            q = queue.popleft()
            if q in good:
                target = q
                break
            for dst, guard, _ in self._out[q]:
                if dst not in parent:
                    parent[dst] = (q, guard)
                    queue.append(dst)
        if target is None:  # pragma: no cover - accepting SCCs are reachable by construction
            return None
        prefix: list[int] = []
        node = target
        while (edge := parent[node]) is not None:
            src, guard = edge
            prefix.append(_lowest_bit(guard))
            node = src
        prefix.reverse()
        scc = next(s for s in sccs if target in s)
        loop = _covering_cycle(self, target, scc)
        return prefix, loop

    # -------------------------------------------------------- transformations
    def trim(self) -> Automaton:
        """Drop states that are unreachable or from which no word is accepted."""
        reach = _reachable(self, self.initial)
        sccs = _accepting_sccs(self)
        good: set[int] = set().union(*sccs) if sccs else set()
        # states that can reach an accepting SCC (backward closure)
        pred: dict[int, set[int]] = {q: set() for q in range(self.num_states)}
        for e in self.edges:
            pred[e.dst].add(e.src)
        live = backward_closure(good, pred)
        keep = sorted(q for q in reach if q in live)
        if self.initial not in keep:
            keep = [self.initial, *keep]
        return self._restrict(keep)

    def _restrict(self, keep: Sequence[int]) -> Automaton:
        order = [self.initial] + [q for q in keep if q != self.initial]
        index = {q: i for i, q in enumerate(order)}
        edges = tuple(
            Edge(index[e.src], index[e.dst], e.guard, e.acc) for e in self.edges if e.src in index and e.dst in index
        )
        names = tuple(self.state_names[q] for q in order) if self.state_names else ()
        return replace(self, num_states=len(order), initial=0, edges=edges, state_names=names)

    def merge_edges(self) -> Automaton:
        """Combine parallel edges with equal marks (OR of guards); drop edges dominated by a sibling.

        An edge ``s -g1-> d`` with marks ``A1`` makes the valuations of ``g1``
        useless on a sibling ``s -g2-> d`` whose marks ``A2`` are a subset of
        ``A1`` (same target, fewer marks), so those are removed from ``g2``.
        """
        groups: dict[tuple[int, int], dict[frozenset[int], int]] = {}
        for e in self.edges:
            by_acc = groups.setdefault((e.src, e.dst), {})
            by_acc[e.acc] = by_acc.get(e.acc, 0) | e.guard
        edges: list[Edge] = []
        for (src, dst), by_acc in groups.items():
            for acc, guard in by_acc.items():
                for acc2, g2 in by_acc.items():
                    if acc < acc2:
                        guard &= ~g2
                if guard:
                    edges.append(Edge(src, dst, guard, acc))
        edges.sort(key=lambda e: (e.src, e.dst, sorted(e.acc), e.guard))
        return replace(self, edges=tuple(edges))

    def reduce(self) -> Automaton:
        """Quotient by (direct) bisimulation: states with the same outgoing behaviour are merged."""
        aut = self.merge_edges()
        block = [0] * aut.num_states
        for _ in range(aut.num_states + 1):  # each round splits a block or stops: at most num_states rounds
            sigs: dict[tuple[Any, ...], int] = {}
            new_block = []
            for q in range(aut.num_states):
                moves: dict[tuple[int, frozenset[int]], int] = {}
                for e in aut.out_edges(q):
                    key = (block[e.dst], e.acc)
                    moves[key] = moves.get(key, 0) | e.guard
                sig = (block[q], tuple(sorted((d, tuple(sorted(a)), g) for (d, a), g in moves.items())))
                new_block.append(sigs.setdefault(sig, len(sigs)))
            if len(sigs) == len(set(block)):
                block = new_block
                break
            block = new_block
        else:  # pragma: no cover - partition refinement stabilises within num_states rounds
            raise BoundExceeded(
                f"Automaton.reduce: no stable partition after num_states + 1 = {aut.num_states + 1} rounds"
            )
        if len(set(block)) == aut.num_states:
            return aut
        rep: dict[int, int] = {}
        for q in range(aut.num_states):
            rep.setdefault(block[q], q)
        keep = sorted(rep.values())
        index = {q: i for i, q in enumerate(keep)}
        edges = {
            Edge(index[rep[block[e.src]]], index[rep[block[e.dst]]], e.guard, e.acc)
            for e in aut.edges
            if rep[block[e.src]] == e.src
        }
        names = tuple(aut.state_names[q] for q in keep) if aut.state_names else ()
        merged = replace(
            aut, num_states=len(keep), initial=index[rep[block[aut.initial]]], edges=tuple(edges), state_names=names
        )
        return merged.merge_edges()

    def degeneralize(self, *, state_based: bool = True) -> Automaton:
        """An equivalent Büchi automaton (one acceptance set).

        Classic counter construction: state ``(q, i)`` waits for mark ``i``;
        edges advance the counter through the marks they carry, in order. With
        ``state_based=True`` the states ``(q, num_sets)`` (a full round just
        completed) are the accepting states; otherwise the edge completing a
        round carries the single mark.
        """
        k = self.num_sets
        out = self._out
        if k == 0:
            edges = tuple(Edge(e.src, e.dst, e.guard, frozenset({0})) for e in self.edges)
            return replace(self, edges=edges, num_sets=1, state_based=state_based)
        index: dict[tuple[int, int], int] = {(self.initial, 0): 0}
        queue = deque([(self.initial, 0)])
        raw: list[tuple[int, int, int, bool]] = []
        while queue:
            q, lvl = queue.popleft()
            for dst, guard, acc in out[q]:
                j = 0 if lvl == k else lvl
                while j < k and (acc >> j) & 1:
                    j += 1
                completed = j == k
                if not state_based and completed:
                    j = 0
                target = (dst, j)
                if target not in index:
                    index[target] = len(index)
                    queue.append(target)
                raw.append((index[(q, lvl)], index[target], guard, completed))
        if state_based:
            accepting = {i for (q, lvl), i in index.items() if lvl == k}
            edges = tuple(Edge(s, d, g, frozenset({0}) if s in accepting else frozenset()) for s, d, g, _ in raw)
        else:
            edges = tuple(Edge(s, d, g, frozenset({0}) if c else frozenset()) for s, d, g, c in raw)
        names: tuple[str, ...] = ()
        if self.state_names:
            by_index = sorted(index.items(), key=lambda kv: kv[1])
            names = tuple(f"{self.state_names[q]} [{lvl}]" for (q, lvl), _ in by_index)
        aut = Automaton(self.aps, len(index), 0, edges, 1, state_based, names, self.name)
        return aut.merge_edges()

    def with_aps(self, aps: Sequence[str]) -> Automaton:
        """The same automaton with guards over ``aps`` (a superset of ``self.aps``, any order)."""
        aps = tuple(aps)
        if aps == self.aps:
            return self
        edges = tuple(Edge(e.src, e.dst, remap_guard(e.guard, self.aps, aps), e.acc) for e in self.edges)
        return replace(self, aps=aps, edges=edges)

    # ---------------------------------------------------------------- export
    def to_networkx(self) -> nx.MultiDiGraph:
        """A ``networkx.MultiDiGraph``: node attrs ``name``/``initial``, edge attrs ``guard``/``label``/``acc``."""
        import networkx as nx

        g = nx.MultiDiGraph()
        for q in range(self.num_states):
            g.add_node(q, name=self.state_names[q] if self.state_names else str(q), initial=q == self.initial)
        for e in self.edges:
            g.add_edge(e.src, e.dst, guard=e.guard, label=self.guard_str(e), acc=e.acc)
        return g


# ------------------------------------------------------------------ helpers
def backward_closure(targets: Iterable[int], pred: Mapping[int, Iterable[int]]) -> set[int]:
    """The states that can reach one of ``targets`` (themselves included), given each state's predecessors.

    >>> sorted(backward_closure({2}, {0: [], 1: [0], 2: [1]}))
    [0, 1, 2]
    """
    live = set(targets)
    stack = list(live)
    while stack:
        q = stack.pop()
        for p in pred[q]:
            if p not in live:
                live.add(p)
                stack.append(p)
    return live


def _lowest_bit(x: int) -> int:
    return (x & -x).bit_length() - 1


def _reachable(aut: Automaton, start: int) -> set[int]:
    seen = {start}
    stack = [start]
    while stack:
        q = stack.pop()
        for dst, _, _ in aut._out[q]:
            if dst not in seen:
                seen.add(dst)
                stack.append(dst)
    return seen


def _tarjan(start: int, successors: Any) -> Iterable[list[int]]:
    """Strongly connected components reachable from ``start`` (iterative Tarjan)."""
    index: dict[int, int] = {}
    low: dict[int, int] = {}
    on_stack: set[int] = set()
    stack: list[int] = []
    counter = 0
    work: list[tuple[int, Iterable[int]]] = []

    def push(node: int) -> None:
        nonlocal counter
        index[node] = low[node] = counter
        counter += 1
        stack.append(node)
        on_stack.add(node)
        work.append((node, iter(successors(node))))

    push(start)
    while work:
        node, it = work[-1]
        advanced = False
        for nxt in it:
            if nxt not in index:
                push(nxt)
                advanced = True
                break
            if nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if advanced:
            continue
        work.pop()
        if work:
            parent = work[-1][0]
            low[parent] = min(low[parent], low[node])
        if low[node] == index[node]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == node:
                    break
            yield comp


def _has_accepting_scc(start: int, successors: Any, all_sets: int) -> bool:
    """Generalized Büchi non-emptiness from ``start``; ``successors(node) -> [(node, acc_bits)]``."""
    cache: dict[int, list[tuple[int, int]]] = {}

    def succ(node: int) -> list[tuple[int, int]]:
        s = cache.get(node)
        if s is None:
            s = cache[node] = successors(node)
        return s

    for comp in _tarjan(start, lambda node: [d for d, _ in succ(node)]):
        members = set(comp)
        marks = 0
        internal = False
        for node in comp:
            for dst, acc in succ(node):
                if dst in members:
                    internal = True
                    marks |= acc
        if internal and marks & all_sets == all_sets:
            return True
    return False


def _accepting_sccs(aut: Automaton) -> list[set[int]]:
    """Reachable SCCs of the automaton whose internal edges carry every mark."""
    out = aut._out
    result = []
    for comp in _tarjan(aut.initial, lambda q: [d for d, _, _ in out[q]]):
        members = set(comp)
        marks = 0
        internal = False
        for q in comp:
            for dst, _, acc in out[q]:
                if dst in members:
                    internal = True
                    marks |= acc
        if internal and marks & aut.all_sets == aut.all_sets:
            result.append(members)
    return result


def _covering_cycle(aut: Automaton, start: int, scc: set[int]) -> list[int]:
    """Letters of a cycle from ``start`` inside ``scc`` that takes an edge of every acceptance set."""
    out = aut._out

    def path(src: int, goal: Any) -> list[tuple[int, int, int, int]]:
        # BFS inside the SCC to the first edge satisfying goal(src, dst, acc)
        parent: dict[int, tuple[int, int, int, int] | None] = {src: None}
        queue = deque([src])
        while queue:
            q = queue.popleft()
            for dst, guard, acc in out[q]:
                if dst not in scc:
                    continue
                if goal(q, dst, acc):
                    steps = [(q, dst, guard, acc)]
                    node = q
                    while (step := parent[node]) is not None:
                        steps.append(step)
                        node = step[0]
                    steps.reverse()
                    return steps
                if dst not in parent:
                    parent[dst] = (q, dst, guard, acc)
                    queue.append(dst)
        raise AssertionError("no covering path inside an accepting SCC")  # pragma: no cover

    letters: list[int] = []
    node = start
    missing = aut.all_sets
    while missing:
        steps = path(node, lambda q, d, acc, m=missing: acc & m)
        for _, dst, guard, acc in steps:
            letters.append(_lowest_bit(guard))
            missing &= ~acc
            node = dst
    if node != start or not letters:
        steps = path(node, lambda q, d, acc: d == start)
        for _, dst, guard, _ in steps:
            letters.append(_lowest_bit(guard))
            node = dst
    return letters
