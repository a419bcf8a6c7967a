"""TaskSpec: the discrete structure of a multistep task.

A task is a set of named *modes* (discrete task states), a set of boolean
*sensor atomic propositions* (APs) that the environment reports, the map from a
sensor reading to a mode, and the allowed mode transitions. From the allowed
transitions GLiDE (thesis §4.2) derives a *feasibility matrix*
``F[i, j] = -(number of modes skipped)``; LTL text (thesis ch. 3) can be attached
for the replanner.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import networkx as nx
import numpy as np

from steer_envs.core.regions import Boxes
from steer_envs.core.validation import boolean, describe, name_tuple

SensorKey = frozenset[str]


def _as_sensor_key(sensors: Mapping[str, bool] | Iterable[str], what: str = "sensors") -> SensorKey:
    """The set of true APs of a reading: a mapping AP -> bool (real bools only), AP names, or one name."""
    if isinstance(sensors, str):  # one AP name, not an iterable of characters
        return frozenset((sensors,))
    if isinstance(sensors, Mapping):
        return frozenset(_ap_name(name, what) for name, value in sensors.items() if boolean(value, f"{what}[{name!r}]"))
    try:
        names = list(sensors)
    except TypeError:
        raise TypeError(
            f"{what} must be a mapping AP -> bool or an iterable of true AP names, got {describe(sensors)}"
        ) from None
    return frozenset(_ap_name(name, what) for name in names)


def _ap_name(name: object, what: str) -> str:
    if not isinstance(name, str):
        raise TypeError(f"{what}: AP names must be str, got {describe(name)}")
    return name


def _names(value: Any, what: str) -> tuple[str, ...]:
    return name_tuple(value, f"`{what}`", owner="TaskSpec")


def _transition(pair: object) -> tuple[str, str]:
    if isinstance(pair, (str, bytes)) or not isinstance(pair, (tuple, list)) or len(pair) != 2:
        raise TypeError(f"TaskSpec: `transitions` must hold (from, to) pairs of mode names, got {describe(pair)}")
    a, b = pair
    if not (isinstance(a, str) and isinstance(b, str)):
        raise TypeError(f"TaskSpec: `transitions` must hold (from, to) pairs of mode names, got {describe(pair)}")
    return a, b


def _sensor_modes(raw: Any, modes: tuple[str, ...], sensors: tuple[str, ...]) -> dict[SensorKey, str]:
    """``TaskSpec.sensor_modes`` checked: keys as sets of known APs, values known modes (None: empty)."""
    if raw is None:
        raw = {}
    if not isinstance(raw, Mapping):
        raise TypeError(f"TaskSpec: `sensor_modes` must be a mapping, got {describe(raw)}")
    sensor_modes = {_as_sensor_key(k, "sensor_modes key"): v for k, v in dict(raw).items()}
    for key, mode in sensor_modes.items():
        if mode not in modes:
            raise ValueError(f"TaskSpec: `sensor_modes` maps to unknown mode {mode!r}")
        unknown = key - set(sensors)
        if unknown:
            raise ValueError(f"TaskSpec: `sensor_modes` uses unknown sensor APs {sorted(unknown)}")
    return sensor_modes


def _transitions(raw: Any, modes: tuple[str, ...]) -> frozenset[tuple[str, str]]:
    """``TaskSpec.transitions`` checked to name known modes, without self-loops (None: none)."""
    raw_transitions = () if raw is None else raw
    if isinstance(raw_transitions, (str, bytes)) or not isinstance(raw_transitions, Iterable):
        raise TypeError(f"TaskSpec: `transitions` must be a set of (from, to) pairs, got {describe(raw_transitions)}")
    transitions = frozenset(_transition(t) for t in raw_transitions)
    for a, b in transitions:
        if a not in modes or b not in modes:
            raise ValueError(f"TaskSpec: transition ({a!r}, {b!r}) names an unknown mode")
    return frozenset((a, b) for a, b in transitions if a != b)


def _goal(raw: Any, modes: tuple[str, ...]) -> tuple[str, ...]:
    """``TaskSpec.goal`` checked: one name, names of known modes, or (empty/None) the last mode."""
    if raw is None or (isinstance(raw, (tuple, list)) and not raw):
        goal: tuple[str, ...] = (modes[-1],)
    elif isinstance(raw, str):
        goal = (raw,)
    else:
        goal = _names(raw, "goal")
    for g in goal:
        if g not in modes:
            raise ValueError(f"TaskSpec: `goal` mode {g!r} is not one of {modes}")
    return goal


def _labels(raw: Any, modes: tuple[str, ...]) -> tuple[str, ...]:
    """``TaskSpec.labels`` checked: one distinct label a mode, none the name of another mode (empty: the names)."""
    labels = modes if raw is None or raw == () else _names(raw, "labels")
    if len(labels) != len(modes):
        raise ValueError(f"TaskSpec: `labels` must name each of the {len(modes)} modes, got {len(labels)} labels")
    if len(set(labels)) != len(labels):
        raise ValueError(f"TaskSpec: `labels` has duplicates: {labels}")
    for i, label in enumerate(labels):
        if label in modes and modes.index(label) != i:
            raise ValueError(f"TaskSpec: label {label!r} of mode {modes[i]!r} is the name of another mode")
    return labels


def _regions(
    raw: Any, forbidden: Any, mode_regions: Any, modes: tuple[str, ...]
) -> tuple[dict[str, Boxes], tuple[str, ...], dict[str, str]]:
    """``regions``, ``forbidden`` and ``mode_regions`` checked against each other and the modes."""
    regions = dict(raw or {})
    for name, region in regions.items():
        if not isinstance(name, str) or not isinstance(region, Boxes):
            raise TypeError(f"TaskSpec: `regions` must map names to Boxes, got {name!r}: {describe(region)}")
    bad = [r for r in _names(forbidden or (), "forbidden") if r not in regions]
    if bad:
        raise ValueError(f"TaskSpec: `forbidden` names unknown regions {bad} (regions: {sorted(regions)})")
    mapping = dict(mode_regions or {})
    for mode, region_name in mapping.items():
        if mode not in modes or region_name not in regions:
            raise ValueError(f"TaskSpec: `mode_regions` maps {mode!r} -> {region_name!r}: unknown mode or region")
    return regions, _names(forbidden or (), "forbidden"), mapping


@dataclass(frozen=True)
class TaskSpec:
    """Modes, sensor APs, the sensor -> mode labelling and allowed transitions.

    Args:
        name: human-readable task name.
        modes: ordered mode names; the index of a mode is its integer id
            (``info["mode"]`` in every env).
        sensors: ordered sensor AP names (keys of ``info["sensors"]``).
        sensor_modes: map from the *set of true APs* to a mode name. Sensor
            readings that are not listed map to no mode (``mode_of`` raises).
            May be empty for tasks whose modes are geometric (PolygonNav).
        transitions: allowed ``(from, to)`` pairs between distinct modes;
            self-loops are always allowed.
        initial: the mode a task starts in (default: the first mode).
        goal: the modes that complete the task (default: the last mode).
        ltl: optional LTL text (Spot syntax) of the task specification.
        ltl_variants: optional named alternative specifications (e.g. the
            cooking re-taskings ``phi_cb``, ``phi_bc``...).
        labels: optional descriptive name of each mode, in ``modes`` order (e.g.
            SoupScoop's ``reach``, ``scoop``, ``transport``, ``done`` for the thesis's
            ``a``-``d``). The mode names stay the ids (``info["mode_name"]``, LTL
            specs); everywhere a mode is looked up (:meth:`mode_index`,
            :meth:`is_allowed`, :meth:`shortest_plan`, ...) a label is accepted as an
            alias of its mode, and :meth:`label_of` gives it. Default: the mode names.
        regions: named :class:`~steer_envs.core.regions.Boxes` of the task's space (a maze's walls).
        forbidden: names of regions a plan must never enter.
        mode_regions: mode -> the region where that mode holds; a plan in the current mode
            must not enter the region of a mode it may not move to (:meth:`unsafe_regions`).

    Bad input (duplicate or unknown modes, unknown APs) raises ``ValueError``;
    names that are not non-empty strings raise ``TypeError``. A ``goal`` given
    as one string is that one mode. Sensor readings (``mode_of``) must hold
    real bools: ``"False"`` or NaN is a ``TypeError``, not a true AP.

    >>> task = TaskSpec(
    ...     name="scoop",
    ...     modes=("reach", "scoop", "carry"),
    ...     sensors=("in_soup", "soup_on_spoon"),
    ...     sensor_modes={frozenset(): "reach", frozenset({"in_soup"}): "scoop", frozenset({"soup_on_spoon"}): "carry"},
    ...     transitions=frozenset({("reach", "scoop"), ("scoop", "carry"), ("carry", "reach")}),
    ... )
    >>> task.mode_of({"in_soup": True, "soup_on_spoon": False}), task.goal, task.shortest_plan("reach")
    ('scoop', ('carry',), ['reach', 'scoop', 'carry'])
    >>> task.feasibility_matrix()
    array([[ 0.,  0., -1.],
           [-1.,  0.,  0.],
           [ 0., -1.,  0.]])
    >>> letters = TaskSpec.linear("soup", "abcd", labels=("reach", "scoop", "transport", "done"))
    >>> letters.mode_index("scoop"), letters.label_of("c"), letters.shortest_plan("reach")
    (1, 'transport', ['a', 'b', 'c', 'd'])
    """

    name: str
    modes: tuple[str, ...]
    sensors: tuple[str, ...] = ()
    sensor_modes: Mapping[SensorKey, str] = field(default_factory=dict, hash=False)
    transitions: frozenset[tuple[str, str]] = frozenset()
    initial: str | None = None
    goal: tuple[str, ...] = ()
    ltl: str | None = None
    ltl_variants: Mapping[str, str] = field(default_factory=dict, hash=False)
    labels: tuple[str, ...] = ()
    regions: Mapping[str, Boxes] = field(default_factory=dict, hash=False)
    forbidden: tuple[str, ...] = ()
    mode_regions: Mapping[str, str] = field(default_factory=dict, hash=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise TypeError(f"TaskSpec: `name` must be a str, got {describe(self.name)}")
        modes = _names(self.modes, "modes")
        if len(modes) == 0:
            raise ValueError("TaskSpec: `modes` must name at least one mode")
        if len(set(modes)) != len(modes):
            raise ValueError(f"TaskSpec: `modes` has duplicates: {modes}")
        sensors = _names((), "sensors") if self.sensors is None else _names(self.sensors, "sensors")
        if len(set(sensors)) != len(sensors):
            raise ValueError(f"TaskSpec: `sensors` has duplicates: {sensors}")
        object.__setattr__(self, "modes", modes)
        object.__setattr__(self, "sensors", sensors)
        object.__setattr__(self, "sensor_modes", _sensor_modes(self.sensor_modes, modes, sensors))
        object.__setattr__(self, "transitions", _transitions(self.transitions, modes))
        initial = modes[0] if self.initial is None else self.initial
        if initial not in modes:
            raise ValueError(f"TaskSpec: `initial` must be one of {modes}, got {initial!r}")
        object.__setattr__(self, "initial", initial)
        object.__setattr__(self, "goal", _goal(self.goal, modes))
        if self.ltl is not None and not isinstance(self.ltl, str):
            raise TypeError(f"TaskSpec: `ltl` must be LTL text (str) or None, got {describe(self.ltl)}")
        object.__setattr__(self, "ltl_variants", dict(self.ltl_variants))
        object.__setattr__(self, "labels", _labels(self.labels, modes))
        regions, forbidden, mode_regions = _regions(self.regions, self.forbidden, self.mode_regions, modes)
        object.__setattr__(self, "regions", regions)
        object.__setattr__(self, "forbidden", forbidden)
        object.__setattr__(self, "mode_regions", mode_regions)

    def unsafe_regions(self, mode: str | None = None) -> list[Boxes]:
        """The regions a plan must stay out of: the forbidden ones, and (given the current ``mode``) the
        regions of the modes ``mode`` may not move to (a disallowed transition).

        >>> from steer_envs.core.regions import Boxes
        >>> box = Boxes([[0.0]], [[1.0]])
        >>> task = TaskSpec("t", ("a", "b", "c"), transitions={("a", "b")}, regions={"b": box, "c": box, "wall": box},
        ...                 forbidden=("wall",), mode_regions={"b": "b", "c": "c"})
        >>> len(task.unsafe_regions()), len(task.unsafe_regions("a"))  # "a" may not go to "c"
        (1, 2)
        """
        out = [self.regions[name] for name in self.forbidden]
        if mode is None:
            return out
        current = self.modes[self.mode_index(mode)]
        for other, region in self.mode_regions.items():
            if other != current and not self.is_allowed(current, other):
                out.append(self.regions[region])
        return out

    # ------------------------------------------------------------------ modes
    @property
    def num_modes(self) -> int:
        return len(self.modes)

    def mode_index(self, mode: str | int) -> int:
        """Index of a mode given by name, label or index (validated)."""
        if isinstance(mode, (int, np.integer)) and not isinstance(mode, bool):
            if not 0 <= int(mode) < self.num_modes:
                raise ValueError(f"mode index must be in [0, {self.num_modes}), got {mode}")
            return int(mode)
        if mode in self.modes:
            return self.modes.index(mode)
        if isinstance(mode, str) and mode in self.labels:
            return self.labels.index(mode)
        aliases = "" if self.labels == self.modes else f" or a label of {self.labels}"
        raise ValueError(f"unknown mode {mode!r}; expected one of {self.modes}{aliases}")

    def label_of(self, mode: str | int) -> str:
        """The descriptive label of a mode given by name, label or index (see ``labels``)."""
        return self.labels[self.mode_index(mode)]

    def mode_of(self, sensors: Mapping[str, bool] | Iterable[str]) -> str:
        """The mode labelled by a sensor reading (thesis: sigma = L(alpha))."""
        key = _as_sensor_key(sensors)
        unknown = key - set(self.sensors)
        if unknown:
            raise ValueError(f"unknown sensor APs {sorted(unknown)}; expected a subset of {self.sensors}")
        try:
            return self.sensor_modes[key]
        except KeyError:
            raise ValueError(f"sensor reading {sorted(key)} labels no mode of task {self.name!r}") from None

    def sensors_of(self, mode: str | int) -> dict[str, bool]:
        """The (first) sensor reading that labels ``mode`` (name or index), as AP -> bool."""
        mode = self.modes[self.mode_index(mode)]
        for key, m in self.sensor_modes.items():
            if m == mode:
                return {ap: ap in key for ap in self.sensors}
        raise ValueError(f"no sensor reading labels mode {mode!r} in task {self.name!r}")

    # ------------------------------------------------------------ transitions
    def is_allowed(self, src: str | int, dst: str | int) -> bool:
        """True for self-loops and listed transitions."""
        a, b = self.modes[self.mode_index(src)], self.modes[self.mode_index(dst)]
        return a == b or (a, b) in self.transitions

    def graph(self) -> nx.DiGraph:
        """Directed graph of allowed transitions (nodes are mode names)."""
        g = nx.DiGraph()
        g.add_nodes_from(self.modes)
        g.add_edges_from(sorted(self.transitions))
        return g

    def allowed_matrix(self) -> np.ndarray:
        """Boolean ``(K, K)`` matrix: ``A[i, j]`` iff mode i may step to mode j."""
        k = self.num_modes
        allowed = np.eye(k, dtype=bool)
        for a, b in self.transitions:
            allowed[self.modes.index(a), self.modes.index(b)] = True
        return allowed

    def feasibility_matrix(self, convention: Literal["shortest_path", "forward"] = "shortest_path") -> np.ndarray:
        """GLiDE feasibility matrix ``F`` (thesis §4.2).

        ``"shortest_path"`` (thesis text): ``F[i, j] = 0`` for allowed moves and
        ``-(d(i, j) - 1)`` otherwise, with ``d`` the shortest path length in the
        transition graph (unreachable pairs count as ``K`` steps).
        ``"forward"`` (public GLiDE code, linear tasks only): ``F[i, j] =
        -(j - i - 1)`` for ``j > i + 1`` and 0 otherwise, i.e. every backward
        move is free.
        """
        k = self.num_modes
        if convention == "forward":
            i, j = np.indices((k, k))
            return np.where(j > i + 1, -(j - i - 1), 0).astype(np.float64)
        if convention != "shortest_path":
            raise ValueError(f"convention must be 'shortest_path' or 'forward', got {convention!r}")
        lengths = dict(nx.all_pairs_shortest_path_length(self.graph()))
        feas = np.zeros((k, k), dtype=np.float64)
        for i, a in enumerate(self.modes):
            for j, b in enumerate(self.modes):
                if self.is_allowed(a, b):
                    continue
                d = lengths.get(a, {}).get(b, k)
                feas[i, j] = -(d - 1)
        return feas

    def shortest_plan(self, src: str | int, dst: str | int | None = None) -> list[str]:
        """Shortest mode sequence from ``src`` to ``dst`` (default: nearest goal)."""
        a = self.modes[self.mode_index(src)]
        targets = self.goal if dst is None else (self.modes[self.mode_index(dst)],)
        g = self.graph()
        best: list[str] | None = None
        for t in targets:
            try:
                path = nx.shortest_path(g, a, t)
            except nx.NetworkXNoPath:
                continue
            if best is None or len(path) < len(best):
                best = path
        if best is None:
            raise ValueError(f"no allowed mode sequence from {a!r} to {targets}")
        return best

    @classmethod
    def linear(cls, name: str, modes: Iterable[str], *, back_edges: bool = False, **kwargs: Any) -> TaskSpec:
        """A chain ``m0 -> m1 -> ... -> mK`` (optionally with ``m(i+1) -> m(i)``); ``kwargs`` go to the constructor.

        >>> TaskSpec.linear("chain", ["a", "b", "c"]).is_allowed("a", "c")
        False
        """
        modes = tuple(modes)
        transitions = {(modes[i], modes[i + 1]) for i in range(len(modes) - 1)}
        if back_edges:
            transitions |= {(modes[i + 1], modes[i]) for i in range(len(modes) - 1)}
        return cls(name=name, modes=modes, transitions=frozenset(transitions), **kwargs)
