"""Task automata of the thesis specs and the sensor-driven mode replanner."""

from __future__ import annotations

import pytest

from steer_envs.core.task import TaskSpec
from steer_envs.ltl import evaluate, translate
from steer_envs.ltl import specs as S
from steer_envs.ltl.gr1 import GR1Spec
from steer_envs.ltl.replanner import ModeReplanner, TaskAutomaton, UnknownSensorReading, UnrealizableSpecError

SOUP_TASK = TaskSpec(name="soup", modes=("a", "b", "c", "d"), sensors=("r", "s", "t"))
COOKING_TASK = TaskSpec(name="cooking", modes=("w0",), sensors=S.COOKING_SENSORS)


def reading(bits: str, sensors: tuple[str, ...] = ("r", "s", "t")) -> dict[str, bool]:
    return {ap: bit == "1" for ap, bit in zip(sensors, bits, strict=True)}


# ------------------------------------------------------------ soup scooping
@pytest.mark.parametrize("convention", ["thesis", "public"])
def test_soup_scoop_mode_edges_are_the_thesis_figure(convention: str) -> None:
    aut = TaskAutomaton(SOUP_TASK, S.soup_scoop(convention))
    # thesis Fig. 3.3a: a->b->c->d plus the recovery edges b->a, c->a, c->b; nothing else
    assert aut.mode_edges() == {("a", "b"), ("b", "c"), ("c", "d"), ("b", "a"), ("c", "a"), ("c", "b")}
    assert len(aut.nodes) == 4 and [aut.nodes[i].mode for i in aut.initial] == ["a"]


def test_soup_scoop_table_matches_spots_automaton_of_the_public_code() -> None:
    # the public TLI automaton table: a:{000:a, 100:b}; b:{000:a,100:b,010:c}; c:{011:d,000:a,100:b,010:c}; d:{011:d}
    table = TaskAutomaton(SOUP_TASK, S.soup_scoop("public")).transition_table()
    assert table == {
        "a": {"000": "a", "100": "b"},
        "b": {"000": "a", "100": "b", "010": "c"},
        "c": {"011": "d", "000": "a", "100": "b", "010": "c"},
        "d": {"011": "d"},
    }
    thesis = TaskAutomaton(SOUP_TASK, S.soup_scoop("thesis")).transition_table()
    assert thesis["c"]["001"] == "d" and thesis["d"] == {"001": "d"}


def test_soup_scoop_replans_after_a_perturbation_from_c_into_a() -> None:
    rp = ModeReplanner(SOUP_TASK, S.soup_scoop("thesis"))
    assert rp.reset(reading("000")) == "a"
    assert rp.plan() == ["a", "b", "c", "d"] and rp.next_mode() == "b"
    assert rp.next_mode(reading("100")) == "c"
    assert rp.next_mode(reading("100")) == "c"  # a repeated reading is no transition
    assert rp.plan(reading("010")) == ["c", "d"]
    # perturbation: the soup spills, the spoon is back in the reaching mode
    assert rp.plan(reading("000")) == ["a", "b", "c", "d"]
    assert not rp.last_unexpected  # c -> a is a recovery edge of the spec
    assert rp.plan(reading("100")) == ["b", "c", "d"]
    # b -> d is not an edge: an unexpected jump, re-planned from where the system is
    assert rp.plan(reading("001")) == ["d"]
    assert rp.last_unexpected and rp.unexpected_transitions == 1
    assert rp.expected_transitions == 4 and not rp.stuck


def test_unknown_readings_keep_the_state() -> None:
    rp = ModeReplanner(SOUP_TASK, S.soup_scoop("thesis"))
    rp.reset(reading("000"))
    with pytest.raises(UnknownSensorReading, match=r"\['r', 's'\]"):
        rp.update(reading("110"))
    assert rp.current_mode == "a"
    with pytest.raises(ValueError, match="unknown sensor APs"):
        rp.update({"q": True})
    with pytest.raises(RuntimeError, match="reset"):
        ModeReplanner(SOUP_TASK, S.soup_scoop("thesis")).plan()


def test_plans_satisfy_the_gr1_formula() -> None:
    """Every node's plan, closed into a lasso, is a model of the spec (oracle and automaton agree)."""
    for spec, task in [
        (S.soup_scoop("thesis"), SOUP_TASK),
        (S.cooking("phi_cb"), COOKING_TASK),
        (S.cooking("phi_cc"), COOKING_TASK),
        (S.color_tracing("c"), S.COLOR_TRACING_TASK),
    ]:
        aut = TaskAutomaton(task, spec)
        checker = translate(spec.translation_formula(), aut.aps)
        for i in aut.initial:
            nodes = aut.plan_nodes(i)
            assert nodes is not None
            # the plan ends by closing its cycle: the loop starts at the last node's first occurrence
            start = nodes.index(nodes[-1])
            prefix = [aut.letter(j) for j in nodes[:start]]
            loop = [aut.letter(j) for j in nodes[start:-1]]
            assert evaluate(spec.formula(), prefix, loop), (spec.name, nodes)
            assert checker.accepts(prefix, loop), spec.name
        # and the explicit task automaton exports with one acceptance set per goal
        explicit = aut.to_automaton()
        assert explicit.num_sets == len(spec.liveness("sys_liveness")) and not explicit.is_empty()
        witness = explicit.accepting_lasso()
        assert witness is not None and evaluate(spec.formula(), *witness, aps=aut.aps)


# ------------------------------------------------------------------ cooking
@pytest.mark.parametrize(
    ("variant", "plan"),
    [
        ("phi_cb", ["w1", "y", "d1", "g", "d2"]),  # (c) white, yellow, dark, green, dark
        ("phi_bc", ["w1", "g", "d1", "y", "d2"]),  # (d) white, green, dark, yellow, dark
        ("phi_c", ["w", "y", "d"]),  # (e) chicken only
        ("phi_cc", ["w", "y", "d", "w"]),  # (f) chicken continuously: the plan loops
    ],
)
def test_cooking_retasking_plans(variant: str, plan: list[str]) -> None:
    rp = ModeReplanner(COOKING_TASK, S.cooking(variant))
    sensors = S.COOKING_SENSORS
    assert rp.reset(reading("00000", sensors)) in ("w", "w1")
    assert rp.plan() == plan


def test_cooking_recoveries_follow_each_automaton() -> None:
    sensors = S.COOKING_SENSORS
    cb = ModeReplanner(COOKING_TASK, S.cooking("phi_cb"))
    cb.reset(reading("00000", sensors))
    cb.update(reading("10000", sensors))  # chicken on the spoon: y
    assert cb.plan(reading("00000", sensors)) == ["w1", "y", "d1", "g", "d2"]  # spilled: back to w1
    cb.update(reading("10000", sensors))
    cb.update(reading("00110", sensors))  # chicken in the pot: d1
    assert cb.plan(reading("01010", sensors)) == ["g", "d2"]
    assert cb.plan(reading("00010", sensors)) == ["w2", "g", "d2"]  # broccoli spilled: w2, not w1
    only = ModeReplanner(COOKING_TASK, S.cooking("phi_c"))
    only.reset(reading("00000", sensors))
    assert only.plan(reading("01000", sensors)) == ["g", "w", "y", "d"]  # broccoli: drop it, get chicken
    again = ModeReplanner(COOKING_TASK, S.cooking("phi_cc"))
    again.reset(reading("00000", sensors))
    again.update(reading("10000", sensors))
    assert again.plan(reading("00110", sensors)) == ["d", "w", "y", "d"]  # in the pot: go again


# ------------------------------------------------------------- color tracing
def test_color_tracing_automata_structure() -> None:
    edges = {v: TaskAutomaton(S.COLOR_TRACING_TASK, S.color_tracing(v)).mode_edges() for v in "abc"}
    chain = {("yellow", "blue"), ("blue", "green"), ("green", "orange"), ("orange", "pink"), ("pink", "red")}
    exits = {("yellow", "dark1"), ("blue", "dark2"), ("green", "dark3"), ("orange", "dark4"), ("pink", "dark4")}
    assert edges["a"] == chain | exits | {(f"dark{k}", "yellow") for k in range(1, 5)}
    assert edges["b"] == chain | exits | {("dark1", "yellow"), ("dark2", "blue"), ("dark3", "blue"), ("dark4", "blue")}
    assert edges["c"] == chain | exits | {("dark1", "blue"), ("dark2", "pink"), ("dark3", "green"), ("dark4", "orange")}


@pytest.mark.parametrize(
    ("variant", "tiles", "plan"),
    [
        ("a", ["y", "b", "g"], ["dark3", "yellow", "blue", "green", "orange", "pink", "red"]),
        ("b", ["y", "b", "g"], ["dark3", "blue", "green", "orange", "pink", "red"]),
        ("b", ["y"], ["dark1", "yellow", "blue", "green", "orange", "pink", "red"]),
        ("c", ["y"], ["dark1", "blue", "green", "orange", "pink", "red"]),
        ("c", ["y", "b"], ["dark2", "pink", "red"]),
    ],
)
def test_color_tracing_dark_modes_are_told_apart_by_the_automaton(variant: str, tiles: list, plan: list) -> None:
    """The dark region looks the same from every tile; the tracked state says which D mode it is."""
    rp = ModeReplanner(S.COLOR_TRACING_TASK, S.color_tracing(variant))
    rp.reset({"y"})
    for tile in tiles[1:]:
        rp.update({tile})
    assert rp.plan({"k"}) == plan
    assert not rp.last_unexpected
    # plans never lead *into* the dark region, although the spec allows those edges
    aut = rp.automaton
    for i, node in enumerate(aut.nodes):
        assert not any(m.startswith("dark") for m in aut.plan_modes(i)[1:]), node


def test_color_tracing_nominal_plan_avoids_recovery_modes() -> None:
    rp = ModeReplanner(S.COLOR_TRACING_TASK, S.color_tracing("c"))
    rp.reset({"y"})
    assert rp.plan() == ["yellow", "blue", "green", "orange", "pink", "red"]  # not blue -> dark2 -> pink


# ------------------------------------------------------------- bad specs
def _spec(**parts: str) -> GR1Spec:
    base = S.soup_scoop("thesis")
    return GR1Spec(
        env_init=parts.get("env_init", base.env_init),
        env_safety=parts.get("env_safety", base.env_safety),
        sys_init=parts.get("sys_init", base.sys_init),
        sys_safety=parts.get("sys_safety", base.sys_safety),
        sys_liveness=parts.get("sys_liveness", base.sys_liveness),
    )


@pytest.mark.parametrize(
    ("parts", "message"),
    [
        ({"env_safety": "G(a & !a)"}, "env_safety is contradictory"),
        ({"env_safety": "G(a <-> r)", "sys_safety": "G(!a & !b & !c & !d)"}, "sys_safety is contradictory"),
        ({"env_safety": "G(a <-> r)", "sys_safety": "G(a & !r)"}, "contradict each other"),
        ({"env_init": "r & s"}, "env_init"),
        ({"sys_init": "b"}, "sys_init"),
        ({"sys_safety": "G((a -> X a) & (b -> X b) & (c -> X c) & (d -> X d))"}, "unrealizable"),
        ({"sys_liveness": "G F (a & b)"}, "sys_liveness goal"),
    ],
)
def test_contradictory_or_unrealizable_specs_say_which_part_fails(parts: dict, message: str) -> None:
    with pytest.raises(UnrealizableSpecError, match=message):
        TaskAutomaton(SOUP_TASK, _spec(**parts))


@pytest.mark.parametrize(
    ("parts", "message"),
    [
        ({"sys_safety": "G(a -> X b"}, r"GR1Spec.sys_safety: LTL syntax error at column 11"),
        ({"sys_safety": "a -> X b"}, "conjunction of G"),
        ({"sys_safety": "G(a -> X X b)"}, "X may only apply"),
        ({"sys_safety": "G(a -> F b)"}, "only propositional"),
        ({"sys_liveness": "F d"}, "G F p"),
        ({"env_init": "X r"}, "propositional"),
    ],
)
def test_specs_outside_gr1_are_rejected(parts: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        _spec(**parts)


def test_unknown_aps_and_bad_arguments() -> None:
    with pytest.raises(ValueError, match=r"APs \['q'\]"):
        TaskAutomaton(SOUP_TASK, _spec(sys_liveness="G F q"))
    with pytest.raises(TypeError, match="TaskSpec"):
        TaskAutomaton("soup", S.soup_scoop())  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="differ"):
        TaskAutomaton(TaskSpec(name="x", modes=("a",), sensors=("a",)), GR1Spec())
    with pytest.raises(ValueError, match="recovery_modes"):
        GR1Spec(modes=("a",), recovery_modes=("b",))


def test_spec_formulas_and_retasking() -> None:
    spec = S.cooking("phi_cb")
    assert spec.retask(S.cooking("phi_bc").sys_safety, name="phi_bc") == S.cooking("phi_bc")
    assert str(spec.formula()).startswith("(!hc & !hb & !p & !ch & !br &")
    assert spec.atoms() == set(S.COOKING_SENSORS) | {"w1", "w2", "y", "g", "d1", "d2"}
