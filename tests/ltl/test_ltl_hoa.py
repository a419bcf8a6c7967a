"""HOA v1 export and import (the subset Spot's translators produce)."""

from __future__ import annotations

import pytest

from steer_envs.ltl import evaluate, from_hoa, to_hoa, translate

# as printed by `ltl2tgba -H 'GFa'` (transition-based Büchi)
SPOT_GFA = """HOA: v1
name: "GFa"
States: 1
Start: 0
AP: 1 "a"
acc-name: Buchi
Acceptance: 1 Inf(0)
properties: trans-labels explicit-labels trans-acc complete
properties: deterministic stutter-invariant
--BODY--
State: 0
[0] 0 {0}
[!0] 0
--END--
"""

# as printed by `ltl2tgba -B -H 'a U b'` (state-based Büchi)
SPOT_AUB = """HOA: v1
name: "a U b"
States: 2
Start: 1
AP: 2 "a" "b"
acc-name: Buchi
Acceptance: 1 Inf(0)
properties: trans-labels explicit-labels state-acc deterministic
properties: stutter-invariant terminal
--BODY--
State: 0 {0}
[t] 0
State: 1
[1] 0
[0&!1] 1
--END--
"""

# generalized Büchi, aliases, comments and two start states
HAND_WRITTEN = """HOA: v1 /* G F a & G F b, or a forever */
States: 3
Start: 0
Start: 2
AP: 2 "a" "b"
Alias: @both 0 & 1
acc-name: generalized-Buchi 2
Acceptance: 2 Inf(1)&Inf(0)
tool: "hand"
--BODY--
State: 0 "gfa & gfb"
[@both] 0 {0 1}
[0 & !1] 0 {1}
[!0 & 1] 0 {0}
[!(0 | 1)] 0
State: 1 "unreachable"
[t] 1
State: 2 "G a"
[0] 2 {0 1}
--END--
"""


@pytest.mark.parametrize(
    ("text", "formula"),
    [(SPOT_GFA, "G F a"), (SPOT_AUB, "a U b"), (HAND_WRITTEN, "(G F a & G F b) | G a")],
)
def test_reads_spot_style_hoa(text: str, formula: str) -> None:
    aut = from_hoa(text)
    letters = [set(), {"a"}, {"b"}, {"a", "b"}]  # sets: extra APs are ignored by a one-AP automaton
    for prefix in ([], [1], [0, 2], [3]):
        for loop in ([0], [1], [2], [3], [1, 2], [0, 3]):
            p, v = [letters[i] for i in prefix], [letters[i] for i in loop]
            assert aut.accepts(p, v) is evaluate(formula, p, v), (prefix, loop)


def test_state_based_marks_and_names() -> None:
    aut = from_hoa(SPOT_AUB)
    assert aut.state_based and aut.initial == 1
    assert aut.accepting_states == frozenset({0})
    hand = from_hoa(HAND_WRITTEN)
    assert hand.num_states == 4 and hand.initial == 3  # a fresh start state merges the two starts
    assert hand.state_names[0] == "gfa & gfb"


def test_write_then_read_round_trip() -> None:
    aut = translate("G(a -> F b) & F c")
    text = to_hoa(aut)
    assert text.startswith("HOA: v1\n") and "--BODY--" in text and text.endswith("--END--\n")
    assert 'AP: 3 "a" "b" "c"' in text
    back = from_hoa(text)
    assert (back.num_states, back.num_sets, back.aps) == (aut.num_states, aut.num_sets, aut.aps)
    assert {(e.src, e.dst, e.guard, e.acc) for e in back.edges} == {(e.src, e.dst, e.guard, e.acc) for e in aut.edges}
    ba = aut.degeneralize()
    assert "state-acc" in to_hoa(ba) and from_hoa(to_hoa(ba)).accepting_states == ba.accepting_states


def test_all_and_none_acceptance() -> None:
    all_text = to_hoa(translate("G a"))
    assert "Acceptance: 0 t" in all_text
    assert from_hoa(all_text).accepts([], [{"a"}])
    never = SPOT_GFA.replace("Acceptance: 1 Inf(0)", "Acceptance: 1 f")
    assert from_hoa(never).is_empty()


@pytest.mark.parametrize(
    ("mutation", "message"),
    [
        (("Acceptance: 1 Inf(0)", "Acceptance: 1 Fin(0)"), "generalized Büchi"),
        (("Acceptance: 1 Inf(0)", "Acceptance: 2 Inf(0) | Inf(1)"), "generalized Büchi"),
        (("[0] 0 {0}", "0 {0}"), "implicit"),
        (("Start: 0", "Start: 0&0"), "alternating"),
        (("HOA: v1", "HOX: v1"), "HOA:"),
        (("--BODY--", ""), "BODY"),
        (("[0] 0 {0}", "[3] 0 {0}"), "AP 3"),
        (("[0] 0 {0}", "[@x] 0 {0}"), "alias"),
    ],
)
def test_unsupported_or_malformed(mutation: tuple[str, str], message: str) -> None:
    text = SPOT_GFA.replace(*mutation)
    with pytest.raises(ValueError, match=message):
        from_hoa(text)
    with pytest.raises(TypeError):
        from_hoa(b"HOA: v1")  # type: ignore[arg-type]
