"""LTL -> Büchi translation checked against the lasso semantics.

CI runs :func:`test_automaton_accepts_exactly_the_models` with 500 random
formulas (depth <= 5, 3 APs, every operator) and 20 random lasso words each,
and requires zero mismatches.
"""

from __future__ import annotations

import random
import sys
import types

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from ltl_strategies import APS, formulas, lasso_words, random_formula

from steer_envs.ltl import (
    Automaton,
    Edge,
    Formula,
    evaluate,
    from_hoa,
    parse,
    spot_available,
    to_hoa,
    translate,
    translate_native,
    write_hoa,
)
from steer_envs.ltl.guards import ap_mask, cube_mask, formula_mask, full_mask, isop, remap_guard

_PROPERTY = settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@_PROPERTY
@given(formulas(5), st.lists(lasso_words(), min_size=20, max_size=20))
def test_automaton_accepts_exactly_the_models(f: Formula, words: list) -> None:
    aut = translate(f, APS)
    for prefix, loop in words:
        expected = evaluate(f, prefix, loop, aps=APS)
        assert aut.accepts(prefix, loop) is expected, (str(f), prefix, loop, to_hoa(aut))


@pytest.mark.slow
def test_deep_fuzz_every_automaton_form_agrees_with_the_semantics() -> None:
    """3000 formulas of depth 5 drawn without shrinking bias, 20 words each, four automaton forms."""
    rng = random.Random(2024)
    for _ in range(3000):
        f = random_formula(rng)
        aut = translate(f, APS)
        forms = [aut, aut.degeneralize(), aut.degeneralize(state_based=False), from_hoa(to_hoa(aut))]
        for _ in range(20):
            prefix = [rng.randrange(8) for _ in range(rng.randrange(5))]
            loop = [rng.randrange(8) for _ in range(1 + rng.randrange(4))]
            expected = evaluate(f, prefix, loop, aps=APS)
            for form in forms:
                assert form.accepts(prefix, loop) is expected, (str(f), prefix, loop)


@settings(max_examples=150, deadline=None)
@given(formulas(4), st.lists(lasso_words(), min_size=8, max_size=8))
def test_degeneralized_and_hoa_round_tripped_automata_agree(f: Formula, words: list) -> None:
    aut = translate(f, APS)
    variants = [
        aut.degeneralize(),
        aut.degeneralize(state_based=False),
        from_hoa(to_hoa(aut)),
        from_hoa(to_hoa(aut.degeneralize())),
        translate_native(f, APS, simplify_formula=False, reduce=False),
    ]
    for ba in variants[:2]:
        assert ba.num_sets == 1
    for prefix, loop in words:
        expected = evaluate(f, prefix, loop, aps=APS)
        for other in variants:
            assert other.accepts(prefix, loop) is expected, (str(f), prefix, loop)


@settings(max_examples=200, deadline=None)
@given(formulas(5))
def test_emptiness_witness_is_a_model(f: Formula) -> None:
    aut = translate(f, APS)
    lasso = aut.accepting_lasso()
    if lasso is None:
        assert aut.is_empty()
        # an unsatisfiable formula: its negation holds on every word we try
        assert evaluate(parse(f"!({f})"), [], [0], aps=APS)
    else:
        prefix, loop = lasso
        assert evaluate(f, prefix, loop, aps=APS)
        assert aut.accepts(prefix, loop)


@pytest.mark.parametrize(
    ("text", "states", "sets"),
    [("G F a", 1, 1), ("F G a", 2, 1), ("a U b", 2, 1), ("G a", 1, 0), ("true", 1, 0), ("X a", 3, 0)],
)
def test_small_automata(text: str, states: int, sets: int) -> None:
    aut = translate(text)
    assert (aut.num_states, aut.num_sets) == (states, sets)


def test_false_and_true() -> None:
    empty = translate("a & !a")
    assert empty.is_empty() and not empty.edges
    assert not empty.accepts([], [{"a"}])
    everything = translate("true")
    assert everything.accepts([], [set()]) and not everything.is_empty()


def test_translate_arguments() -> None:
    with pytest.raises(ValueError, match="missing"):
        translate("a & b", aps=("a",))
    with pytest.raises(ValueError, match="backend"):
        translate("a", backend="ltl3ba")
    with pytest.raises(ValueError, match="loop"):
        translate("a").accepts([{"a"}], [])
    aut = translate("G(a -> X b)", aps=("b", "z", "a"))
    assert aut.aps == ("b", "z", "a")
    assert aut.accepts([{"a"}], [{"b", "z"}]) and not aut.accepts([{"a"}], [{"z"}])
    # letters as mappings and ints are accepted too
    assert aut.accepts([{"a": True}], [0b001])
    assert aut.successors(0, {"a"}) == aut.successors(0, 0b100)


def test_oversized_tableaux_fail_cleanly() -> None:
    from steer_envs.ltl import TranslationTooLarge

    big = " & ".join(f"G(m{i} -> X(m{(i + 1) % 5} | m{(i + 2) % 5}))" for i in range(5))
    with pytest.raises(TranslationTooLarge, match="translation_formula"):
        translate_native(big, max_terms=50)
    assert translate_native(big).num_states > 1


def test_automaton_validation_and_views(tmp_path: object) -> None:
    with pytest.raises(ValueError, match="empty or out-of-range guard"):
        Automaton(("a",), 1, 0, (Edge(0, 0, 0),))
    with pytest.raises(ValueError, match="num_sets"):
        Automaton(("a",), 1, 0, (Edge(0, 0, 1, frozenset({1})),), num_sets=1)
    with pytest.raises(ValueError, match="initial"):
        Automaton(("a",), 1, 3, ())
    aut = translate("G(a -> F b)")
    g = aut.to_networkx()
    assert g.number_of_nodes() == aut.num_states and g.number_of_edges() == len(aut.edges)
    for _, _, data in g.edges(data=True):  # labels are formulas denoting the guards
        assert formula_mask(parse(data["label"]), aut.aps) == data["guard"]
    path = tmp_path / "aut.hoa"  # type: ignore[operator]
    write_hoa(aut, path)
    assert from_hoa(path.read_text()).num_states == aut.num_states
    assert "Automaton(" in repr(aut)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 4), st.data())
def test_guard_isop_covers_exactly(n: int, data: st.DataObject) -> None:
    guard = data.draw(st.integers(0, full_mask(n)))
    cover = 0
    for cube in isop(guard, n):
        cover |= cube_mask(cube, n)
    assert cover == guard
    # remapping to a reordered superset keeps the meaning
    old = tuple(f"v{j}" for j in range(n))
    new = ("extra", *reversed(old))
    mapped = remap_guard(guard, old, new)
    for v in range(1 << n):
        w = sum(1 << new.index(old[j]) for j in range(n) if (v >> j) & 1)
        assert ((mapped >> w) & 1) == ((guard >> v) & 1) == ((mapped >> (w | 1)) & 1)


def test_formula_mask() -> None:
    aps = ("a", "b")
    assert formula_mask(parse("a & !b"), aps) == ap_mask(0, 2) & ~ap_mask(1, 2) & full_mask(2)
    with pytest.raises(TypeError, match="temporal"):
        formula_mask(parse("X a"), aps)
    with pytest.raises(ValueError, match="not one of"):
        formula_mask(parse("c"), aps)


# ------------------------------------------------------------------ Spot
@pytest.mark.skipif(not spot_available(), reason="Spot's Python bindings are not installed")
@settings(max_examples=50, deadline=None)
@given(formulas(4), st.lists(lasso_words(), min_size=10, max_size=10))
def test_spot_backend_agrees_with_semantics(f: Formula, words: list) -> None:  # pragma: no cover - needs Spot
    aut = translate(f, APS, backend="spot")
    for prefix, loop in words:
        assert aut.accepts(prefix, loop) is evaluate(f, prefix, loop, aps=APS)


def test_spot_backend_glue_with_a_stub_module(monkeypatch: pytest.MonkeyPatch) -> None:
    """The Spot path (translate -> HOA -> Automaton -> requested APs) without Spot itself."""
    calls = []

    class _StubAutomaton:
        def __init__(self, text: str) -> None:
            self.text = text

        def to_str(self, fmt: str) -> str:
            assert fmt == "hoa"
            # like Spot: only the APs that matter, in Spot's own order
            return to_hoa(translate_native(self.text, sorted(parse(self.text).atoms(), reverse=True)))

    def stub_translate(text: str, *options: str) -> _StubAutomaton:
        calls.append((text, options))
        return _StubAutomaton(text)

    monkeypatch.setitem(sys.modules, "spot", types.SimpleNamespace(translate=stub_translate))
    assert spot_available()
    aut = translate("G(p0 -> F p2)", APS, backend="spot")
    assert calls and parse(calls[0][0]) is parse("G(p0 -> F p2)")
    assert aut.aps == APS
    assert aut.accepts([0b001], [0b100]) and not aut.accepts([], [0b001])
    assert translate("p0", backend="auto").aps == ("p0",)


def test_spot_backend_missing_raises_import_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "spot", None)  # makes `import spot` fail
    assert not spot_available()
    with pytest.raises(ImportError, match="conda"):
        translate("a", backend="spot")
    assert translate("G a", backend="auto").num_states == 1  # falls back to native
