"""Transition DSs: one LPV-DS per demonstrated mode *transition*, recombined by edited automata (TLI re-tasking).

Thesis appendix "Generalization Results": two demonstrations add chicken and
broccoli to the pot in different orders; LTL-DS learns one LPV-DS per *mode
transition* (a mode can lead to several next modes here) and the skills are
recombined, without retraining, by the edited automata ``phi_cb``, ``phi_bc``,
``phi_c`` and ``phi_cc`` (:func:`steer_envs.ltl.specs.cooking`).

* **Skills** (:func:`fit_skills`): each demonstration is cut where the spoon's
  region letter changes (:func:`spoon_letters`: ``w`` empty spoon, ``y``
  holding chicken, ``g`` holding broccoli, ``d`` in the pot; read from the
  sensors). Every segment is keyed by its transition (``("w", "y")``, ...); the
  segments of one key train one LPV-DS whose attractor is the mean first state
  after them (the guard, pushed ``overshoot`` further along the crossing direction).
* **Policy** (:class:`TransitionDSPolicy`): a
  :class:`~steer_envs.ltl.replanner.ModeReplanner` tracks the automaton from the
  sensors; the next mode is the first step of the shortest goal-covering lasso
  that uses only transitions with a learned skill (or stays in a mode); the
  skill of ``(current letter, next letter)`` gives the velocity, zero when the
  plan is to stay (an absorbing goal).
  With ``modulation`` (the default, LTL-DS proper) a mode change that is
  neither the planned one nor a push is an invariance failure of the active
  skill: a cut through the last in-mode state is added to that skill (the
  thesis's QCQP, :func:`~steer_envs.baselines.lpv_ds.cuts.resolve_cuts`) and
  its flow is modulated by its cuts from then on (cuts persist across episodes).

>>> import numpy as np
>>> spoon_letters(np.array([[True, False, False], [False, False, True]]), ("hc", "hb", "p"))
['y', 'd']
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import networkx as nx
import numpy as np

from steer_envs.baselines.lpv_ds.cuts import ATTRACTOR_MARGIN, CutSet, FailureRecord, resolve_cuts
from steer_envs.baselines.lpv_ds.lpvds import LPVDS
from steer_envs.baselines.lpv_ds.modulation import hold_beyond_cuts, modulate
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import boolean, integer, real_scalar
from steer_envs.data.tli_demos import cooking_demonstrations
from steer_envs.envs.cooking import SENSORS
from steer_envs.ltl.gr1 import GR1Spec
from steer_envs.ltl.replanner import ModeReplanner, UnknownSensorReading

__all__ = [
    "Skill",
    "TransitionDSPolicy",
    "fit_skills",
    "learned_skills",
    "skills_fingerprint",
    "spoon_letters",
]

#: LPV-DS stability margin of the skills (the library default lets far flows crawl)
DS_EPS = 1.0
#: attractors sit this far past the mean guard crossing (> dt * max_speed = 0.1)
OVERSHOOT = 0.25
#: most cuts one skill learns
MAX_CUTS = 8


def spoon_letters(sensors: np.ndarray, sensor_names: Sequence[str]) -> list[str]:
    """The spoon's region letter per reading: ``y`` (holds chicken), ``g`` (broccoli), ``d`` (pot), else ``w``."""
    col = {ap: i for i, ap in enumerate(sensor_names)}
    s = np.asarray(sensors, dtype=bool).reshape(-1, len(sensor_names))
    out = np.where(s[:, col["hc"]], "y", np.where(s[:, col["hb"]], "g", np.where(s[:, col["p"]], "d", "w")))
    return [str(v) for v in out]


@dataclass(frozen=True)
class Skill:
    """One learned transition skill: an LPV-DS from region ``source`` into region ``target``."""

    source: str
    target: str
    policy: LPVDS
    attractor: np.ndarray
    n_points: int


def fit_skills(
    demos: Sequence[Any],
    sensor_names: Sequence[str],
    dt: float,
    *,
    ds_eps: float = DS_EPS,
    overshoot: float = OVERSHOOT,
    random_state: int = 0,
) -> dict[tuple[str, str], Skill]:
    """One LPV-DS per demonstrated region transition (see the module docstring)."""
    if not demos:
        raise ValueError("fit_skills: demos must be a non-empty sequence")
    dt = real_scalar(dt, "dt", low=0.0, low_inclusive=False, owner="fit_skills")
    overshoot = real_scalar(overshoot, "overshoot", low=0.0, owner="fit_skills")
    pieces: dict[tuple[str, str], list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]] = {}
    for demo in demos:
        x = np.asarray(demo.states, dtype=np.float64)
        letters = spoon_letters(demo.sensors, sensor_names)
        start = 0
        for t in range(1, len(x)):
            if letters[t] != letters[t - 1]:
                seg = x[start:t]
                vel = (x[start + 1 : t + 1] - seg) / dt  # the motion actually made (speed-clipped)
                pieces.setdefault((letters[t - 1], letters[t]), []).append((seg, vel, x[t - 1], x[t]))
                start = t
    skills: dict[tuple[str, str], Skill] = {}
    for key, segs in sorted(pieces.items()):
        after = np.stack([s[3] for s in segs])
        direction = (after - np.stack([s[2] for s in segs])).mean(axis=0)
        attractor = after.mean(axis=0)
        if overshoot > 0 and np.linalg.norm(direction) > 1e-9:
            attractor = attractor + overshoot * direction / np.linalg.norm(direction)
        xs = [np.vstack([s[0], attractor]) for s in segs]  # each segment ends at the attractor (thesis: shifted)
        vs = [np.vstack([s[1], np.zeros(2)]) for s in segs]
        ds = LPVDS(eps=ds_eps, random_state=random_state).fit(xs, vs, attractor=attractor)
        skills[key] = Skill(key[0], key[1], ds, attractor, int(sum(len(s[0]) for s in segs)))
    return skills


@functools.lru_cache(maxsize=4)
def learned_skills(seed: int, ds_eps: float = DS_EPS, overshoot: float = OVERSHOOT) -> dict[tuple[str, str], Skill]:
    """The Cooking skills of experiment ``seed``, learned once and shared by every automaton (cached; do not modify).

    Fitted on :func:`~steer_envs.data.tli_demos.cooking_demonstrations` with Cooking-v0's ``dt`` (0.01).
    """
    return fit_skills(
        cooking_demonstrations(seed), SENSORS, 0.01, ds_eps=ds_eps, overshoot=overshoot, random_state=seed
    )


def skills_fingerprint(skills: Mapping[tuple[str, str], Skill]) -> str:
    """A short hash of the skills' parameters: equal fingerprints mean the very same DS set."""
    h = hashlib.sha256()
    for key in sorted(skills):
        ds = skills[key].policy
        h.update(repr(key).encode())
        for arr in (ds.attractor, ds.A, ds.b, ds.means):
            h.update(np.ascontiguousarray(arr, dtype=np.float64).tobytes())
    return h.hexdigest()[:12]


def _clip(v: np.ndarray, max_speed: float) -> np.ndarray:
    speed = float(np.linalg.norm(v))
    return v if speed <= max_speed else v * (max_speed / speed)


class TransitionDSPolicy:
    """LTL-DS with one DS per mode transition: automaton mode from the sensors, the planned transition's skill.

    Args:
        task: the env's task (its sensors are the automaton's environment APs).
        spec: the edited GR(1) spec (its modes' first letters name the spoon's region).
        skills: ``(source letter, target letter) -> Skill``.
        max_speed: the env's speed limit.
        modulation: learn cuts from invariance failures and modulate the skills by them.
        max_cuts: most cuts per skill (each re-solve is quadratic in the skill's failures).

    Attributes:
        replans: automaton-unexpected transitions since :meth:`reset` (pushes included).
        invalid: unexpected transitions not caused by a push.
        failures: invariance failures since :meth:`reset` (not planned, not a push).
        stuck_steps: steps with no plan over the learned skills (zero velocity).
        cut_sets: ``skill key -> CutSet`` of the learned cuts (kept across episodes).
    """

    def __init__(
        self,
        task: TaskSpec,
        spec: GR1Spec,
        skills: Mapping[tuple[str, str], Skill],
        *,
        max_speed: float,
        modulation: bool = True,
        max_cuts: int = MAX_CUTS,
    ) -> None:
        if not isinstance(skills, Mapping) or not skills:
            raise TypeError("TransitionDSPolicy: skills must be a non-empty mapping (source, target) -> Skill")
        self.replanner = ModeReplanner(task, spec)
        self.automaton = self.replanner.automaton
        self.skills = dict(skills)
        self.max_speed = real_scalar(max_speed, "max_speed", low=0.0, low_inclusive=False, owner="TransitionDSPolicy")
        aut = self.automaton
        self._letter = [node.mode[0] for node in aut.nodes]
        graph = nx.DiGraph()
        graph.add_nodes_from(range(len(aut.nodes)))
        for i, succ in enumerate(aut.plan_succ):
            for j in succ:
                a, b = self._letter[i], self._letter[j]
                if a == b or (a, b) in self.skills:
                    graph.add_edge(i, j)
        self._graph = graph
        self._goal = frozenset().union(*aut.goals) if aut.goals else frozenset()
        self._next_cache: dict[int, int | None] = {}
        self.modulation = boolean(modulation, "modulation", owner="TransitionDSPolicy")
        self.max_cuts = integer(max_cuts, "max_cuts", low=0, owner="TransitionDSPolicy")
        self.cut_sets = {k: CutSet(sk.attractor) for k, sk in self.skills.items()}
        self._records: dict[tuple[str, str], list[FailureRecord]] = {k: [] for k in self.skills}
        self.replans = self.invalid = self.failures = self.stuck_steps = 0
        self.mode_path: list[str] = []
        self._x: np.ndarray | None = None
        self._entry: np.ndarray | None = None
        self._active: tuple[str, str] | None = None
        self._target: str | None = None

    def _next_node(self, start: int) -> int | None:
        """First step of the shortest goal lasso from ``start`` over skill-backed edges (None: no plan)."""
        if start in self._next_cache:
            return self._next_cache[start]
        dist = nx.single_source_shortest_path(self._graph, start)
        best: tuple[int, int] | None = None
        choice: int | None = None
        for s in self._goal:
            if s not in dist:
                continue
            if self._graph.has_edge(s, s):
                cycle = 1
            else:
                back = [
                    len(nx.shortest_path(self._graph, t, s))
                    for t in self._graph.successors(s)
                    if nx.has_path(self._graph, t, s)
                ]
                if not back:
                    continue
                cycle = min(back)
            key = (len(dist[s]) - 1 + cycle, s)
            if best is None or key < best:
                best = key
                path = dist[s]
                if len(path) > 1:
                    choice = path[1]
                elif self._graph.has_edge(s, s):
                    choice = s
                else:  # at the goal: the first step of its cycle
                    choice = min(
                        (t for t in self._graph.successors(s) if nx.has_path(self._graph, t, s)),
                        key=lambda t: (len(nx.shortest_path(self._graph, t, s)), t),
                    )
        self._next_cache[start] = choice
        return choice

    @property
    def mode(self) -> str:
        """The tracked automaton mode."""
        return self.replanner.current_mode

    def next_mode(self) -> str | None:
        """The mode the policy drives toward (None when no skill-backed plan exists)."""
        assert self.replanner.state is not None
        nxt = self._next_node(self.replanner.state)
        return None if nxt is None else self.automaton.nodes[nxt].mode

    @property
    def num_cuts(self) -> int:
        """Cuts over all skills."""
        return sum(len(c) for c in self.cut_sets.values())

    def reset(self, obs: np.ndarray, info: Mapping[str, Any]) -> None:
        """Start an episode from its first reading (cuts are kept)."""
        self.replanner.reset(info["sensors"])
        self.replans = self.invalid = self.failures = self.stuck_steps = 0
        self.mode_path = [self.mode]
        self._x = np.asarray(obs, dtype=np.float64).reshape(2).copy()
        self._entry = self._x.copy()
        self._active, self._target = None, None

    def observe(self, obs: np.ndarray, info: Mapping[str, Any]) -> None:
        """Track a reading; ``info["perturbed"]`` marks a push; an invariance failure may add a cut."""
        x = np.asarray(obs, dtype=np.float64).reshape(2).copy()
        pushed = boolean(info.get("perturbed", False), "info['perturbed']", owner="TransitionDSPolicy")
        before_mode = self.mode
        try:
            changed = self.replanner.update(info["sensors"]) != before_mode
        except UnknownSensorReading:
            changed = False  # a reading no mode explains (an empty spoon in the pot before any food): keep the mode
        if changed:
            if self.replanner.last_unexpected:
                self.replans += 1
                self.invalid += not pushed
            if not pushed and self._active is not None and self.mode != self._target:
                self.failures += 1
                self._learn(self._active, x)
            self.mode_path.append(self.mode)
            self._entry = x.copy()
        self._x = x

    def _learn(self, key: tuple[str, str], failure: np.ndarray) -> None:
        assert self._x is not None and self._entry is not None
        records = [*self._records[key], FailureRecord(self._x.copy(), failure, self._entry.copy())]
        if not self.modulation or len(records) > self.max_cuts:
            return
        try:
            cuts = resolve_cuts(records, self.skills[key].attractor, ATTRACTOR_MARGIN)
        except ValueError:
            return  # no cut separates this failure (kept out of the records)
        self._records[key] = records
        self.cut_sets[key].set_cuts(cuts)

    def act(self, obs: np.ndarray, info: Mapping[str, Any]) -> np.ndarray:
        """The velocity (float32 ``(2,)``) of the planned transition's skill, modulated by its cuts."""
        self.observe(obs, info)
        assert self.replanner.state is not None and self._x is not None
        nxt = self._next_node(self.replanner.state)
        self._active, self._target = None, None
        if nxt is None:
            self.stuck_steps += 1
            return np.zeros(2, dtype=np.float32)
        a, b = self._letter[self.replanner.state], self._letter[nxt]
        self._target = self.automaton.nodes[nxt].mode
        if a == b:
            return np.zeros(2, dtype=np.float32)  # the plan stays in this mode (an absorbing goal)
        self._active = (a, b)
        x = self._x[None]
        v = _clip(np.asarray(self.skills[(a, b)].policy(x), dtype=np.float64)[0], self.max_speed)[None]
        cuts = self.cut_sets[(a, b)]
        if self.modulation and len(cuts):
            v = hold_beyond_cuts(x, modulate(x, v, cuts, self.max_speed), cuts)
        return v[0].astype(np.float32)
