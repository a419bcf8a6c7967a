"""Task automaton over modes and the sensor-driven mode replanner (TLI, thesis §3.4-3.5).

From a :class:`~steer_envs.core.task.TaskSpec` (sensor APs, optionally the
sensor -> mode labelling) and a :class:`~steer_envs.ltl.gr1.GR1Spec`, the
:class:`TaskAutomaton` is built *directly* from the GR(1) structure instead of
through a general LTL -> Büchi translation (which the thesis used Spot for):

- **nodes** are the pairs (sensor reading, mode) that satisfy every safety
  *invariant* (the ``G(...)`` conjuncts without ``X``, e.g. ``G(a <-> !r & !s &
  !t)``) with exactly one mode AP true; when the spec's modes are the task's,
  a node must also agree with ``task.sensor_modes`` wherever the task labels
  the reading (so a spec may leave the sensor -> mode constraints to the task);
- **edges** ``n -> n'`` are the pairs allowed by every *transition constraint*
  (the ``G(...)`` conjuncts with ``X``), both environment and system;
- **initial nodes** satisfy ``env_init & sys_init``; **goals** are the ``G F p``
  conditions of ``sys_liveness``.

In this fragment that graph is the task automaton of the spec: every infinite
path from an initial node that visits each goal infinitely often satisfies the
GR(1) formula (tests check plans against :func:`~steer_envs.ltl.translate` and
the lasso semantics). Planning is cooperative, as in TLI: the environment
(sensors) is assumed to follow the plan unless a perturbation says otherwise.

:class:`ModeReplanner` tracks the automaton state from sensor readings. A
repeated reading is not a transition (a continuous motion stays in a mode for
many steps; specs such as ``w1 -> X y`` have no self-loops). A reading reached
by an automaton edge is an *expected* transition; any other reading is an
*unexpected* one (a perturbation or an invariance failure): the replanner
jumps to the node of that reading and re-plans from there. A plan is the
shortest lasso (prefix + cycle) from the current node whose cycle visits every
goal, written as the sequence of modes (``a b c d`` for soup scooping).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import cached_property

import networkx as nx
import numpy as np

from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import boolean, describe
from steer_envs.ltl.automaton import Automaton, Edge, backward_closure
from steer_envs.ltl.gr1 import GR1Spec, SafetyPart
from steer_envs.ltl.guards import MAX_APS, formula_mask
from steer_envs.ltl.syntax import FALSE, TRUE, And, Atom, Const, Formula, Next

__all__ = ["ModeReplanner", "Node", "TaskAutomaton", "UnknownSensorReading", "UnrealizableSpecError"]


class UnrealizableSpecError(ValueError):
    """The specification is contradictory or cannot be met; the message names the failing part."""


class UnknownSensorReading(ValueError):
    """A sensor reading that no mode of the task automaton is consistent with."""


@dataclass(frozen=True)
class Node:
    """A task-automaton state: a mode together with the sensor reading (set of true sensor APs)."""

    mode: str
    sensors: frozenset[str]

    def __str__(self) -> str:
        return f"{self.mode}[{','.join(sorted(self.sensors))}]"


def _substitute_current(f: Formula, true_aps: frozenset[str]) -> Formula:
    """Replace current-step APs by constants and ``X p`` by ``p``: a formula over the next step."""
    if isinstance(f, Atom):
        return TRUE if f.name in true_aps else FALSE
    if isinstance(f, Const):
        return f
    if isinstance(f, Next):
        return f.arg
    return type(f)(*(_substitute_current(a, true_aps) for a in f.args))


class TaskAutomaton:
    """The automaton of a GR(1) spec over modes (see the module docstring).

    Attributes:
        task: the task (sensor APs, labelling).
        spec: the specification.
        modes: the mode (system) APs.
        nodes: the states, in a deterministic order.
        edges: ``(i, j)`` node index pairs (``i == j`` for allowed stays).
        succ: successors of each node (every edge: what tracking accepts as expected).
        plan_succ: successors plans may use (no edge into a recovery mode).
        initial: indices of the initial nodes.
        goals: for each ``G F p`` of ``sys_liveness``, the indices of nodes satisfying ``p``.

    Raises:
        UnrealizableSpecError: a contradictory part, no initial state, or a
            liveness goal that cannot be met from an initial state.
        ValueError: APs the task does not define, or parts outside GR(1).
    """

    def __init__(self, task: TaskSpec, spec: GR1Spec) -> None:
        if not isinstance(task, TaskSpec):
            raise TypeError(f"task must be a TaskSpec, got {type(task).__name__}")
        if not isinstance(spec, GR1Spec):
            raise TypeError(f"spec must be a GR1Spec, got {type(spec).__name__}")
        self.task = task
        self.spec = spec
        self.modes: tuple[str, ...] = spec.modes if spec.modes is not None else task.modes
        self.sensors: tuple[str, ...] = task.sensors
        clash = set(self.modes) & set(self.sensors)
        if clash:
            raise ValueError(f"mode APs and sensor APs must differ; both name {sorted(clash)}")
        self.aps: tuple[str, ...] = (*self.sensors, *self.modes)
        if len(self.aps) > MAX_APS:
            raise ValueError(f"at most {MAX_APS} sensor + mode APs are supported, got {len(self.aps)}")
        for part in ("env_init", "env_safety", "env_liveness", "sys_init", "sys_safety", "sys_liveness"):
            unknown = sorted(spec.part(part).atoms() - set(self.aps))
            if unknown:
                raise ValueError(
                    f"GR1Spec.{part} uses APs {unknown} that are neither sensors {self.sensors} nor modes {self.modes}"
                )
        self._build()

    # ---------------------------------------------------------------- build
    def _mask(self, f: Formula) -> int:
        return formula_mask(f, self.aps)

    def _valuation(self, node: Node) -> int:
        v = 0
        for j, ap in enumerate(self.aps):
            if ap in node.sensors or ap == node.mode:
                v |= 1 << j
        return v

    def _build(self) -> None:
        env_safety, sys_safety = self.spec.safety("env_safety"), self.spec.safety("sys_safety")
        nodes = self._safe_nodes(env_safety, sys_safety)
        self.nodes: tuple[Node, ...] = tuple(nodes)
        self.index: dict[Node, int] = {node: i for i, node in enumerate(nodes)}
        vals = [self._valuation(node) for node in nodes]
        self._build_edges(And(*env_safety.transitions, *sys_safety.transitions), vals)
        self._build_initial(vals)
        self._build_goals(vals)
        self._vals = vals
        self._cycles = self._covering_cycles()
        for i in self.initial:
            if self.plan_nodes(i) is None:
                goal_text = " & ".join(f"G F {g}" for g in self.goal_formulas) or "true"
                raise UnrealizableSpecError(
                    f"unrealizable: from the initial state {self.nodes[i]} no mode sequence allowed by sys_safety "
                    f"(and env_safety) satisfies sys_liveness {goal_text!r}"
                )

    def _candidates(self, mask: int) -> list[Node]:
        """The (mode, sensor reading) nodes whose valuation ``mask`` allows (and the task's labels, if used)."""
        task, ns = self.task, len(self.sensors)
        use_labels = set(self.modes) == set(task.modes) and bool(task.sensor_modes)
        out = []
        for mi, mode in enumerate(self.modes):
            for alpha in range(1 << ns):
                v = alpha | (1 << (ns + mi))
                if not (mask >> v) & 1:
                    continue
                reading = frozenset(ap for j, ap in enumerate(self.sensors) if (alpha >> j) & 1)
                if use_labels and task.sensor_modes.get(reading, mode) != mode:
                    continue
                out.append(Node(mode, reading))
        return out

    def _safe_nodes(self, env_safety: SafetyPart, sys_safety: SafetyPart) -> list[Node]:
        """The nodes meeting both safety invariants; an error naming the contradictory part if none."""
        env_inv = self._mask(And(*env_safety.invariants))
        sys_inv = self._mask(And(*sys_safety.invariants))
        nodes = self._candidates(env_inv & sys_inv)
        if nodes:
            return nodes
        if not self._candidates(env_inv):
            raise UnrealizableSpecError(
                f"env_safety is contradictory: no sensor reading with one mode of {self.modes} satisfies its "
                f"invariants {[str(f) for f in env_safety.invariants]}"
            )
        if not self._candidates(sys_inv):
            raise UnrealizableSpecError(
                f"sys_safety is contradictory: no mode of {self.modes} satisfies its invariants "
                f"{[str(f) for f in sys_safety.invariants]}"
            )
        raise UnrealizableSpecError(
            "env_safety and sys_safety contradict each other: no (sensor reading, mode) satisfies both invariants"
        )

    def _build_edges(self, transition: Formula, vals: list[int]) -> None:
        """``edges``, ``succ`` and ``plan_succ`` (plans never lead into a recovery mode)."""
        nodes = self.nodes
        edges: set[tuple[int, int]] = set()
        for i, node in enumerate(nodes):
            allowed = self._mask(_substitute_current(transition, node.sensors | {node.mode}))
            for j, v in enumerate(vals):
                if (allowed >> v) & 1:
                    edges.add((i, j))
        self.edges: frozenset[tuple[int, int]] = frozenset(edges)
        self.succ: tuple[tuple[int, ...], ...] = tuple(
            tuple(sorted(j for (a, j) in edges if a == i)) for i in range(len(nodes))
        )
        # plans never lead into a recovery mode (entered only by perturbation)
        recovery = set(self.spec.recovery_modes)
        unknown = recovery - set(self.modes)
        if unknown:
            raise ValueError(f"GR1Spec.recovery_modes {sorted(unknown)} are not modes of the task {self.modes}")
        self.plan_succ: tuple[tuple[int, ...], ...] = tuple(
            tuple(j for j in self.succ[i] if j == i or nodes[j].mode not in recovery) for i in range(len(nodes))
        )

    def _build_initial(self, vals: list[int]) -> None:
        """``initial``: the nodes meeting ``env_init`` and ``sys_init``."""
        spec = self.spec
        env_init = self._mask(spec.initial_condition("env_init"))
        sys_init = self._mask(spec.initial_condition("sys_init"))
        init_env = [i for i, v in enumerate(vals) if (env_init >> v) & 1]
        if not init_env:
            raise UnrealizableSpecError(
                f"env_init {spec.env_init!r} is unsatisfiable together with the safety invariants (no sensor reading)"
            )
        self.initial: tuple[int, ...] = tuple(i for i in init_env if (sys_init >> vals[i]) & 1)
        if not self.initial:
            raise UnrealizableSpecError(
                f"sys_init {spec.sys_init!r} contradicts env_init {spec.env_init!r} under the safety invariants: "
                f"no initial mode"
            )

    def _build_goals(self, vals: list[int]) -> None:
        """``goal_formulas`` and ``goals`` (the nodes meeting each ``G F`` goal)."""
        self.goal_formulas: tuple[Formula, ...] = self.spec.liveness("sys_liveness")
        self.goals: tuple[frozenset[int], ...] = tuple(
            frozenset(i for i, v in enumerate(vals) if (self._mask(g) >> v) & 1) for g in self.goal_formulas
        )
        for g, members in zip(self.goal_formulas, self.goals, strict=True):
            if not members:
                raise UnrealizableSpecError(
                    f"sys_liveness goal 'G F {g}' is unsatisfiable: no mode of {self.modes} meets it under the "
                    f"safety invariants"
                )

    # --------------------------------------------------------------- lassos
    def _goal_mask(self, i: int) -> int:
        return sum(1 << k for k, members in enumerate(self.goals) if i in members)

    def _covering_cycles(self) -> dict[int, list[int]]:
        """For each node, the shortest cycle through it whose nodes meet every goal (if any)."""
        full = (1 << len(self.goals)) - 1
        cycles: dict[int, list[int]] = {}
        for s in range(len(self.nodes)):
            start = (s, self._goal_mask(s))
            parent: dict[tuple[int, int], tuple[int, int] | None] = {start: None}
            queue = deque([start])
            found: tuple[int, int] | None = None
            while queue and found is None:
                node, mask = queue.popleft()
                for nxt in self.plan_succ[node]:
                    state = (nxt, mask | self._goal_mask(nxt))
                    if nxt == s and state[1] == full:
                        parent_of_end = (node, mask)
                        found = parent_of_end
                        break
                    if state not in parent:
                        parent[state] = (node, mask)
                        queue.append(state)
            if found is None:
                continue
            path = [s]
            cur: tuple[int, int] | None = found
            while cur is not None:
                path.append(cur[0])
                cur = parent[cur]
            path.reverse()  # s ... s
            cycles[s] = path
        return cycles

    @cached_property
    def _live(self) -> frozenset[int]:
        """Nodes from which a goal-covering lasso exists."""
        pred: dict[int, list[int]] = {i: [] for i in range(len(self.nodes))}
        for a, succ in enumerate(self.plan_succ):
            for b in succ:
                pred[b].append(a)
        return frozenset(backward_closure(self._cycles, pred))

    def plan_nodes(self, start: int) -> list[int] | None:
        """Shortest lasso from node ``start`` as node indices: prefix, then the cycle closed (or None)."""
        if start in self._plan_cache:
            return self._plan_cache[start]
        dist: dict[int, int] = {start: 0}
        parent: dict[int, int | None] = {start: None}
        queue = deque([start])
        while queue:
            q = queue.popleft()
            for nxt in self.plan_succ[q]:
                if nxt not in dist:
                    dist[nxt] = dist[q] + 1
                    parent[nxt] = q
                    queue.append(nxt)
        best: tuple[int, int, int] | None = None
        for s, cycle in self._cycles.items():
            if s in dist:
                key = (dist[s] + len(cycle) - 1, dist[s], s)
                if best is None or key < best:
                    best = key
        result: list[int] | None = None
        if best is not None:
            s = best[2]
            prefix: list[int] = []
            node: int | None = s
            while node is not None:
                prefix.append(node)
                node = parent[node]
            prefix.reverse()  # start ... s
            result = prefix + self._cycles[s][1:]
        self._plan_cache[start] = result
        return result

    @cached_property
    def _plan_cache(self) -> dict[int, list[int] | None]:
        return {}

    def plan_modes(self, start: int) -> list[str] | None:
        """Modes of :meth:`plan_nodes` with consecutive repeats collapsed (``a b c d``)."""
        nodes = self.plan_nodes(start)
        if nodes is None:
            return None
        modes: list[str] = []
        for i in nodes:
            m = self.nodes[i].mode
            if not modes or modes[-1] != m:
                modes.append(m)
        return modes

    def is_live(self, i: int) -> bool:
        """Can the goals still be met from node ``i``?"""
        return i in self._live

    # --------------------------------------------------------------- views
    def nodes_of(self, sensors: Mapping[str, bool] | Iterable[str]) -> list[int]:
        """Indices of the nodes consistent with a sensor reading (AP -> bool, or the set of true APs)."""
        reading = _reading(sensors, self.sensors)
        return [i for i, node in enumerate(self.nodes) if node.sensors == reading]

    def mode_edges(self) -> frozenset[tuple[str, str]]:
        """Mode transitions ``(m1, m2)``, ``m1 != m2``, that some automaton edge makes."""
        return frozenset(
            (self.nodes[a].mode, self.nodes[b].mode) for a, b in self.edges if self.nodes[a].mode != self.nodes[b].mode
        )

    def mode_graph(self) -> nx.DiGraph:
        """The automaton projected on modes (thesis Fig. 3.3a)."""
        g = nx.DiGraph()
        g.add_nodes_from(self.modes)
        g.add_edges_from(sorted(self.mode_edges()))
        return g

    def transition_table(self) -> dict[str, dict[str, str]]:
        """``{mode: {sensor bits: next mode}}`` (bits in ``task.sensors`` order), like Spot's table in the TLI code."""
        table: dict[str, dict[str, str]] = {}
        for a, b in sorted(self.edges):
            src, dst = self.nodes[a], self.nodes[b]
            bits = "".join("1" if ap in dst.sensors else "0" for ap in self.sensors)
            table.setdefault(src.mode, {})[bits] = dst.mode
        return table

    def to_automaton(self) -> Automaton:
        """The task automaton as an explicit :class:`Automaton` over sensor + mode APs.

        State 0 is a fresh initial state; state ``i + 1`` is node ``i``; an
        edge into node ``j`` reads node ``j``'s valuation. Acceptance: one set
        per liveness goal, on the edges entering a node that meets it.
        """
        edges = []
        for i in self.initial:
            edges.append(Edge(0, i + 1, 1 << self._vals[i], self._marks(i)))
        for a, b in sorted(self.edges):
            edges.append(Edge(a + 1, b + 1, 1 << self._vals[b], self._marks(b)))
        return Automaton(
            aps=self.aps,
            num_states=len(self.nodes) + 1,
            initial=0,
            edges=tuple(edges),
            num_sets=len(self.goals),
            state_names=("init", *(str(node) for node in self.nodes)),
            name=self.spec.name or "task automaton",
        )

    def _marks(self, i: int) -> frozenset[int]:
        return frozenset(k for k, members in enumerate(self.goals) if i in members)

    def letter(self, i: int) -> frozenset[str]:
        """The set of true APs (sensors and the mode) at node ``i``."""
        node = self.nodes[i]
        return node.sensors | {node.mode}

    def __repr__(self) -> str:
        return (
            f"TaskAutomaton({self.spec.name or 'spec'!r}: {len(self.nodes)} nodes, {len(self.edges)} edges, "
            f"modes={self.modes})"
        )


def _reading(sensors: Mapping[str, bool] | Iterable[str], known: tuple[str, ...]) -> frozenset[str]:
    """The set of true APs of a reading. Values must be real bools: ``"False"``, ``1`` or NaN raise ``TypeError``."""
    keys: set[str] | frozenset[str]
    if isinstance(sensors, Mapping):
        for k in sensors:
            _ap_name(k)
        reading = frozenset(k for k, v in sensors.items() if boolean(v, f"sensors[{k!r}]"))
        keys = set(sensors)
    elif isinstance(sensors, str):
        reading = keys = frozenset((sensors,))
    else:
        if isinstance(sensors, (bytes, np.ndarray)) or not isinstance(sensors, Iterable):
            raise TypeError(
                f"sensors must be a mapping AP -> bool or an iterable of true AP names, got {describe(sensors)}"
            )
        reading = frozenset(_ap_name(x) for x in sensors)
        keys = set(reading)
    unknown = sorted(set(keys) - set(known))
    if unknown:
        raise ValueError(f"sensors: unknown sensor APs {unknown}; expected a subset of {known}")
    return reading


def _ap_name(name: object) -> str:
    if not isinstance(name, str):
        raise TypeError(f"sensors: AP names must be str, got {describe(name)}")
    return name


class ModeReplanner:
    """Tracks the task automaton from sensor readings and plans the next mode.

    Args:
        task: the task (its sensor APs are the environment APs).
        spec: the GR(1) specification.

    Use :meth:`reset` with the first reading of an episode, then :meth:`update`
    (or :meth:`next_mode` / :meth:`plan`, which update first) with every new
    reading. A reading is a mapping AP -> bool (real bools: ``"False"`` or NaN
    is a ``TypeError``, never a true AP) or an iterable of the true AP names.

    >>> from steer_envs.envs.soup_scoop import SOUP_TASK
    >>> from steer_envs.ltl import specs
    >>> replanner = ModeReplanner(SOUP_TASK, specs.soup_scoop("public"))
    >>> replanner.reset({"r": False, "s": False, "t": False}), replanner.plan()
    ('a', ['a', 'b', 'c', 'd'])
    >>> replanner.next_mode({"r": True, "s": False, "t": False})  # the spoon is in the soup: mode b, then c
    'c'
    >>> replanner.next_mode({"r": False, "s": False, "t": False})  # it left the soup unscooped: back to a
    'b'
    """

    def __init__(self, task: TaskSpec, spec: GR1Spec) -> None:
        self.automaton = TaskAutomaton(task, spec)
        self.task = task
        self.spec = spec
        self.modes = self.automaton.modes
        self.state: int | None = None
        #: counts of expected and unexpected (perturbation) transitions since reset
        self.expected_transitions = 0
        self.unexpected_transitions = 0
        #: was the latest transition unexpected?
        self.last_unexpected = False

    # ------------------------------------------------------------- tracking
    def _choose(self, candidates: list[int], previous: int | None) -> tuple[int, bool]:
        """Pick the node of a reading: an automaton successor if any (expected), else the nearest one."""
        aut = self.automaton
        if previous is not None:
            succ = [i for i in candidates if i in aut.succ[previous]]
            if succ:
                planned = aut.plan_nodes(previous) or []
                on_plan = [i for i in succ if i in planned[1:2]]
                return (on_plan or succ)[0], True
            # unexpected: prefer the candidate closest to where the automaton was, then live ones
            dist = nx.single_source_shortest_path_length(self._graph, previous)
            ranked = sorted(candidates, key=lambda i: (i not in dist, dist.get(i, 0), not aut.is_live(i), i))
            return ranked[0], False
        initial = [i for i in candidates if i in aut.initial]
        live = [i for i in candidates if aut.is_live(i)]
        return (initial or live or candidates)[0], True

    @cached_property
    def _graph(self) -> nx.DiGraph:
        g = nx.DiGraph()
        g.add_nodes_from(range(len(self.automaton.nodes)))
        g.add_edges_from(self.automaton.edges)
        return g

    def _locate(self, sensors: Mapping[str, bool] | Iterable[str]) -> list[int]:
        candidates = self.automaton.nodes_of(sensors)
        if not candidates:
            reading = sorted(_reading(sensors, self.automaton.sensors))
            raise UnknownSensorReading(
                f"sensor reading {reading} is consistent with no mode of spec {self.spec.name or '(unnamed)'!r} "
                f"(modes {self.modes})"
            )
        return candidates

    def reset(self, sensors: Mapping[str, bool] | Iterable[str]) -> str:
        """Start tracking from the first reading of an episode; returns the current mode.

        Prefers an initial node of the spec; a reading that no initial node has
        (an episode started elsewhere) starts from its node anyway.
        """
        candidates = self._locate(sensors)
        self.state, _ = self._choose(candidates, None)
        self.expected_transitions = self.unexpected_transitions = 0
        self.last_unexpected = False
        return self.current_mode

    def update(self, sensors: Mapping[str, bool] | Iterable[str]) -> str:
        """Advance the automaton on a new reading; returns the current mode.

        A reading equal to the current node's is no transition. Raises
        :class:`UnknownSensorReading` for a reading no mode is consistent with
        (the tracked state is then left unchanged).
        """
        if self.state is None:
            return self.reset(sensors)
        candidates = self._locate(sensors)
        if self.state in candidates:
            self.last_unexpected = False
            return self.current_mode
        self.state, expected = self._choose(candidates, self.state)
        self.last_unexpected = not expected
        if expected:
            self.expected_transitions += 1
        else:
            self.unexpected_transitions += 1
        return self.current_mode

    # -------------------------------------------------------------- queries
    @property
    def current_mode(self) -> str:
        """The mode of the tracked automaton state."""
        if self.state is None:
            raise RuntimeError("ModeReplanner: call reset(sensors) first")
        return self.automaton.nodes[self.state].mode

    @property
    def current_node(self) -> Node:
        if self.state is None:
            raise RuntimeError("ModeReplanner: call reset(sensors) first")
        return self.automaton.nodes[self.state]

    @property
    def stuck(self) -> bool:
        """True when no mode sequence from the current state can meet the liveness goals."""
        return self.state is not None and not self.automaton.is_live(self.state)

    def plan(self, sensors: Mapping[str, bool] | Iterable[str] | None = None) -> list[str]:
        """The planned mode sequence from the current mode (after updating on ``sensors`` if given).

        Shortest lasso whose cycle meets every ``G F`` goal, as modes, e.g.
        ``["a", "b", "c", "d"]``; ``[current]`` when stuck.
        """
        if sensors is not None:
            self.update(sensors)
        if self.state is None:
            raise RuntimeError("ModeReplanner: call reset(sensors) or pass `sensors`")
        return self.automaton.plan_modes(self.state) or [self.current_mode]

    def next_mode(self, sensors: Mapping[str, bool] | Iterable[str] | None = None) -> str:
        """The mode to pursue next (the current one when the plan is to stay)."""
        plan = self.plan(sensors)
        return plan[1] if len(plan) > 1 else plan[0]

    def next_mode_index(self, sensors: Mapping[str, bool] | Iterable[str] | None = None) -> int:
        """:meth:`next_mode` as an index into :attr:`modes`."""
        return self.modes.index(self.next_mode(sensors))
