"""TaskSpec: validation, sensor labelling, transitions, feasibility matrices, plans."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from steer_envs.core import TaskSpec

CHAIN = ("reach", "grasp", "carry", "place")


def _bfs_lengths(modes: tuple[str, ...], edges: set[tuple[str, str]]) -> dict[tuple[str, str], int]:
    """Independent shortest path lengths by breadth-first search (no networkx)."""
    succ: dict[str, list[str]] = {m: [] for m in modes}
    for a, b in edges:
        succ[a].append(b)
    lengths: dict[tuple[str, str], int] = {}
    for src in modes:
        dist = {src: 0}
        queue = deque([src])
        while queue:
            node = queue.popleft()
            for nxt in succ[node]:
                if nxt not in dist:
                    dist[nxt] = dist[node] + 1
                    queue.append(nxt)
        lengths.update({(src, dst): d for dst, d in dist.items()})
    return lengths


def _expected_shortest_path_feasibility(modes: tuple[str, ...], edges: set[tuple[str, str]]) -> np.ndarray:
    k = len(modes)
    lengths = _bfs_lengths(modes, edges)
    feas = np.zeros((k, k))
    for i, a in enumerate(modes):
        for j, b in enumerate(modes):
            d = lengths.get((a, b), k)  # unreachable counts as K steps
            feas[i, j] = 0.0 if d <= 1 else -(d - 1)
    return feas


# ---------------------------------------------------------------- feasibility
def test_linear_chain_forward_convention() -> None:
    task = TaskSpec.linear("chain", CHAIN)
    expected = np.array(
        [
            [0, 0, -1, -2],
            [0, 0, 0, -1],
            [0, 0, 0, 0],
            [0, 0, 0, 0],
        ],
        dtype=float,
    )
    np.testing.assert_array_equal(task.feasibility_matrix("forward"), expected)


def test_linear_chain_shortest_path_convention() -> None:
    task = TaskSpec.linear("chain", CHAIN)
    expected = np.array(
        [
            [0, 0, -1, -2],
            [-3, 0, 0, -1],  # going back is unreachable: counts as K = 4 steps
            [-3, -3, 0, 0],
            [-3, -3, -3, 0],
        ],
        dtype=float,
    )
    feas = task.feasibility_matrix()
    np.testing.assert_array_equal(feas, expected)
    np.testing.assert_array_equal(feas, _expected_shortest_path_feasibility(CHAIN, set(task.transitions)))


def test_linear_chain_with_back_edges_is_symmetric() -> None:
    task = TaskSpec.linear("chain", CHAIN, back_edges=True)
    feas = task.feasibility_matrix("shortest_path")
    np.testing.assert_array_equal(feas, feas.T)
    np.testing.assert_array_equal(feas, _expected_shortest_path_feasibility(CHAIN, set(task.transitions)))
    assert feas[3, 0] == -2.0
    # the forward convention ignores the transition graph by design
    np.testing.assert_array_equal(
        task.feasibility_matrix("forward"), TaskSpec.linear("c", CHAIN).feasibility_matrix("forward")
    )


def test_feasibility_rejects_unknown_convention() -> None:
    with pytest.raises(ValueError, match="convention must be"):
        TaskSpec.linear("chain", CHAIN).feasibility_matrix("backward")  # type: ignore[arg-type]


@settings(max_examples=40, deadline=None)
@given(
    st.integers(1, 6).flatmap(
        lambda k: st.tuples(
            st.just(k),
            st.sets(st.tuples(st.integers(0, k - 1), st.integers(0, k - 1)), max_size=k * k),
        )
    )
)
def test_shortest_path_feasibility_matches_bfs_on_random_graphs(graph: tuple[int, set[tuple[int, int]]]) -> None:
    k, index_edges = graph
    modes = tuple(f"m{i}" for i in range(k))
    edges = {(modes[a], modes[b]) for a, b in index_edges}
    task = TaskSpec(name="random", modes=modes, transitions=frozenset(edges))
    np.testing.assert_array_equal(task.feasibility_matrix(), _expected_shortest_path_feasibility(modes, edges))
    allowed = task.allowed_matrix()
    assert np.all((task.feasibility_matrix() == 0) >= allowed)  # allowed moves are free


# ------------------------------------------------------------ transitions
def test_allowed_matrix_and_is_allowed() -> None:
    task = TaskSpec.linear("chain", CHAIN)
    expected = np.eye(4, dtype=bool) | np.eye(4, k=1, dtype=bool)
    allowed = task.allowed_matrix()
    assert allowed.dtype == bool
    np.testing.assert_array_equal(allowed, expected)
    assert task.is_allowed("reach", "grasp") and task.is_allowed(2, 2)
    assert not task.is_allowed("grasp", "reach") and not task.is_allowed(0, 2)
    assert set(task.graph().edges) == {("reach", "grasp"), ("grasp", "carry"), ("carry", "place")}


def test_self_loops_are_implicit_and_dropped_from_transitions() -> None:
    task = TaskSpec(name="t", modes=("a", "b"), transitions=frozenset({("a", "a"), ("a", "b")}))
    assert task.transitions == frozenset({("a", "b")})
    assert task.is_allowed("a", "a") and task.is_allowed("b", "b")


def test_shortest_plan() -> None:
    task = TaskSpec.linear("chain", CHAIN)
    assert task.shortest_plan("reach") == list(CHAIN)
    assert task.shortest_plan(1, "carry") == ["grasp", "carry"]
    assert task.shortest_plan("carry", "carry") == ["carry"]
    with pytest.raises(ValueError, match="no allowed mode sequence"):
        task.shortest_plan("place", "reach")
    # several goals: the nearest one wins
    branching = TaskSpec(
        name="kitchen",
        modes=("start", "door", "microwave", "sink"),
        transitions=frozenset({("start", "door"), ("door", "microwave"), ("start", "sink")}),
        goal=("microwave", "sink"),
    )
    assert branching.shortest_plan("start") == ["start", "sink"]
    assert branching.shortest_plan("door") == ["door", "microwave"]


# ------------------------------------------------------------------- sensors
@pytest.fixture
def sensed() -> TaskSpec:
    return TaskSpec.linear(
        "pick",
        ("reach", "carry", "done"),
        sensors=("grasp", "on_target"),
        sensor_modes={
            frozenset(): "reach",
            frozenset({"grasp"}): "carry",
            frozenset({"on_target"}): "done",
        },
    )


def test_mode_of_accepts_dicts_and_iterables(sensed: TaskSpec) -> None:
    assert sensed.mode_of({"grasp": False, "on_target": False}) == "reach"
    assert sensed.mode_of({"grasp": True, "on_target": False}) == "carry"
    assert sensed.mode_of({"grasp": np.bool_(True)}) == "carry"
    assert sensed.mode_of(["on_target"]) == "done"
    assert sensed.mode_of([]) == "reach"
    # a single AP name is one AP, not an iterable of characters
    assert sensed.mode_of("grasp") == "carry"


def test_mode_of_errors(sensed: TaskSpec) -> None:
    with pytest.raises(ValueError, match=r"unknown sensor APs \['lid'\]"):
        sensed.mode_of({"lid": True})
    with pytest.raises(ValueError, match="labels no mode of task 'pick'"):
        sensed.mode_of({"grasp": True, "on_target": True})


def test_sensors_of(sensed: TaskSpec) -> None:
    assert sensed.sensors_of("carry") == {"grasp": True, "on_target": False}
    assert sensed.sensors_of(0) == {"grasp": False, "on_target": False}  # by index
    for mode in sensed.modes:
        assert sensed.mode_of(sensed.sensors_of(mode)) == mode
    with pytest.raises(ValueError, match="unknown mode 'fly'"):
        sensed.sensors_of("fly")
    bare = TaskSpec.linear("bare", ("a", "b"))
    with pytest.raises(ValueError, match="no sensor reading labels mode 'a'"):
        bare.sensors_of("a")


def test_mode_index(sensed: TaskSpec) -> None:
    assert sensed.mode_index("done") == 2 and sensed.mode_index(np.int64(1)) == 1
    assert sensed.num_modes == 3
    with pytest.raises(ValueError, match=r"mode index must be in \[0, 3\)"):
        sensed.mode_index(3)
    with pytest.raises(ValueError, match="unknown mode"):
        sensed.mode_index(True)  # a bool is not an index


# ---------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"modes": ()}, "at least one mode"),
        ({"modes": ("a", "a")}, "`modes` has duplicates"),
        ({"sensors": ("s", "s")}, "`sensors` has duplicates"),
        ({"sensor_modes": {frozenset(): "zzz"}}, "unknown mode 'zzz'"),
        ({"sensor_modes": {frozenset({"x"}): "a"}}, r"unknown sensor APs \['x'\]"),
        ({"transitions": frozenset({("a", "zzz")})}, "names an unknown mode"),
        ({"initial": "zzz"}, "`initial` must be one of"),
        ({"goal": ("zzz",)}, "`goal` mode 'zzz'"),
    ],
)
def test_constructor_validation(kwargs: dict, match: str) -> None:
    base: dict = {"name": "t", "modes": ("a", "b"), "sensors": ("s",)}
    base.update(kwargs)
    with pytest.raises(ValueError, match=match):
        TaskSpec(**base)


def test_defaults_equality_and_hash() -> None:
    task = TaskSpec.linear("chain", CHAIN, ltl="F place", ltl_variants={"alt": "F carry"})
    assert task.initial == "reach" and task.goal == ("place",)
    twin = TaskSpec.linear("chain", CHAIN, ltl="F place", ltl_variants={"alt": "F carry"})
    assert task == twin and hash(task) == hash(twin)
    assert task != TaskSpec.linear("chain", CHAIN, back_edges=True)
    assert len({task, twin}) == 1
