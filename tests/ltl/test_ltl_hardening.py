"""Deep and hostile input to the LTL package: clean, documented errors, never a RecursionError or a hang.

* parse / str use explicit stacks: thousands of nested parentheses parse and
  print, and ``parse(str(f)) is f`` also for deep formulas; beyond
  MAX_PARSE_DEPTH the error is an LTLParseError naming the limit;
* nnf / simplify / translate refuse formulas deeper than MAX_FORMULA_DEPTH with
  FormulaTooDeep / TranslationTooLarge (ValueErrors) naming the limit;
* sensor readings and letters hold real bools ("False" and NaN are errors);
* HOA input that is truncated or garbled raises ValueError.
"""

from __future__ import annotations

import math
import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from ltl_strategies import random_formula

from steer_envs.envs.soup_scoop import SOUP_TASK
from steer_envs.ltl import (
    MAX_FORMULA_DEPTH,
    Atom,
    Finally,
    FormulaTooDeep,
    GR1Spec,
    LTLParseError,
    ModeReplanner,
    Next,
    TranslationTooLarge,
    Until,
    Xor,
    evaluate,
    from_hoa,
    nnf,
    parse,
    simplify,
    specs,
    to_hoa,
    translate,
)
from steer_envs.ltl import parser as ltl_parser
from steer_envs.ltl.guards import formula_mask, valuation_of
from steer_envs.ltl.syntax import text_length


def _nested(depth: int) -> object:
    f = Atom("a")
    for i in range(depth):
        f = (Next, Finally, lambda g, i=i: Until(Atom(f"p{i % 3}"), g))[i % 3](f)
    return f


# ---------------------------------------------------------------- parse, print
@pytest.mark.parametrize("n", [141, 1000, 5000])
def test_deeply_nested_parentheses_parse(n: int) -> None:
    assert parse("(" * n + "a" + ")" * n) is Atom("a")
    assert parse("!" * n + "a").depth == n
    assert parse("X " * n + "a").depth == n


def test_parse_beyond_its_stack_limit_is_a_parse_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ltl_parser, "MAX_PARSE_DEPTH", 50)
    with pytest.raises(LTLParseError, match="MAX_PARSE_DEPTH=50") as info:
        parse("(" * 100 + "a" + ")" * 100)
    assert isinstance(info.value, ValueError) and info.value.column <= 100


def test_long_error_messages_show_a_window() -> None:
    with pytest.raises(LTLParseError) as info:
        parse("a & " * 5000 + ")")
    assert info.value.column == 20001 and len(str(info.value)) < 600


def test_printing_and_round_trips_work_at_any_depth() -> None:
    chain = Atom("a")
    for i in range(3000):
        chain = Xor(chain, Atom(f"b{i % 4}"))
    text = str(chain)
    assert text.count("xor") == 3000 and parse(text) is chain
    deep = _nested(2000)
    assert parse(str(deep)) is deep and text_length(deep) == len(str(deep))


# --------------------------------------------------------- depth-limited algorithms
@pytest.mark.parametrize("depth", [250, 1200])
def test_translate_of_deep_x_f_u_is_a_translation_error(depth: int) -> None:
    deep = _nested(depth)
    with pytest.raises(TranslationTooLarge, match=f"MAX_FORMULA_DEPTH={MAX_FORMULA_DEPTH}"):
        translate(deep)
    with pytest.raises(TranslationTooLarge, match="MAX_FORMULA_DEPTH"):
        translate(str(deep))
    with pytest.raises(FormulaTooDeep, match="MAX_FORMULA_DEPTH"):
        nnf(deep)
    with pytest.raises(FormulaTooDeep, match="MAX_FORMULA_DEPTH"):
        simplify(deep)
    assert isinstance(evaluate(deep, [], [{"a", "p0"}]), bool)  # the lasso semantics is iterative: any depth


def test_formulas_at_the_depth_limit_translate() -> None:
    f = Atom("a")
    for _ in range(MAX_FORMULA_DEPTH):
        f = Next(f)
    aut = translate(f)
    assert aut.accepts([set()] * MAX_FORMULA_DEPTH, [{"a"}])
    assert not aut.accepts([set()] * MAX_FORMULA_DEPTH, [set()])


def test_exponential_nnf_text_is_refused_not_built() -> None:
    text = "p0"
    for i in range(40):  # 40 nested <->: a small DAG, ~4**20 characters in NNF
        text = f"(p{i % 3} <-> {text})"
    with pytest.raises(FormulaTooDeep, match="MAX_FORMULA_TEXT"):
        simplify(text)
    with pytest.raises(TranslationTooLarge, match="MAX_FORMULA_TEXT"):
        translate(text)


def test_gr1_parts_too_deep_name_the_part() -> None:
    deep = " & ".join(["G(m0 -> X m0)"] * 2)
    GR1Spec(sys_safety=deep)  # fine
    with pytest.raises(FormulaTooDeep, match=r"GR1Spec\.sys_init"):
        GR1Spec(sys_init="!" * (MAX_FORMULA_DEPTH + 1) + "m0")
    with pytest.raises(TypeError, match="modes"):
        GR1Spec(modes="abc")  # type: ignore[arg-type]


def test_formula_mask_is_iterative() -> None:
    f = Atom("a")
    for i in range(5000):
        f = Xor(f, Atom(f"b{i % 3}"))
    assert formula_mask(f, ("a", "b0", "b1", "b2")) > 0


# ------------------------------------------------------------- sensor readings
@pytest.mark.parametrize("bad", ["False", "True", math.nan, 1, 0, None])
def test_sensor_readings_must_be_real_bools(bad: object) -> None:
    replanner = ModeReplanner(SOUP_TASK, specs.soup_scoop("public"))
    good = {"r": False, "s": False, "t": False}
    replanner.reset(good)
    with pytest.raises(TypeError, match="'r'"):
        replanner.update({**good, "r": bad})
    with pytest.raises(TypeError, match="'r'"):
        replanner.reset({**good, "r": bad})
    with pytest.raises(TypeError, match="'a'"):
        evaluate("a", [{"a": bad}], [set()])
    with pytest.raises(TypeError, match="'a'"):
        valuation_of({"a": bad}, ("a",))
    with pytest.raises(TypeError, match="'a'"):
        translate("F a").accepts([{"a": bad}], [set()])
    assert replanner.update({**good, "r": np.bool_(True)}) == "b"


def test_readings_as_name_sets_hold_strings() -> None:
    replanner = ModeReplanner(SOUP_TASK, specs.soup_scoop("public"))
    with pytest.raises(TypeError, match="AP names must be str"):
        replanner.reset([1, 2])
    with pytest.raises(TypeError, match="sensors"):
        replanner.reset(42)  # type: ignore[arg-type]
    assert valuation_of(np.int64(1), ("a",)) == 1
    with pytest.raises(TypeError):
        valuation_of(np.bool_(True), ("a",))


# ---------------------------------------------------------------------- HOA
GOOD_HOA = to_hoa(translate("G(a -> F b)"))


@pytest.mark.parametrize(
    "text",
    [
        "HOA: v1\nStates:",
        "HOA: v1\nStart:\n--BODY--\n--END--",
        "HOA: v1\nStates: x\nStart: 0\n--BODY--\n--END--",
        "HOA: v1\nStates: 99999999999\nStart: 0\nAP: 0\n--BODY--\n--END--",
        "HOA: v1\nStart: 0\nAP: 1 a\n--BODY--\n--END--",
        'HOA: v1\nStart: 0\nAP: 1 "a"\n--BODY--\nState: 0\n[0] \n--END--',
        'HOA: v1\nStart: 0\nAP: 1 "a"\n--BODY--\nState: 0\n[0 1\n',
        'HOA: v1\nStart: 0\nAP: 1 "a"\n--BODY--\nState:',
        'HOA: v1\nStart: 0\nAP: 1 "a"\nAlias: @x @x\n--BODY--\nState: 0\n[@x] 0\n--END--',
        'HOA: v1\nStart: 0\nAP: 1 "a"\n--BODY--\nState: 0\n[' + "!" * 500 + "0] 0\n--END--",
        'HOA: v1\nStart: 0\nAP: 1 "a"\n--BODY--\nState: 0\n[' + "(" * 500 + "0" + ")" * 500 + "] 0\n--END--",
        "HOA: v1\nStart: 0\nAcceptance: 1 Inf(x)\n--BODY--\n--END--",
        'HOA: v1\nStart: 0\nAP: 99 "a"\n--BODY--\n--END--',
    ],
)
def test_malformed_hoa_raises_value_error(text: str) -> None:
    with pytest.raises(ValueError, match="from_hoa"):
        from_hoa(text)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, len(GOOD_HOA)), st.integers(0, len(GOOD_HOA)), st.text(max_size=4))
def test_property_truncated_or_garbled_hoa_is_a_value_error(cut: int, at: int, junk: str) -> None:
    for text in (GOOD_HOA[:cut], GOOD_HOA[:at] + junk + GOOD_HOA[at:]):
        try:
            from_hoa(text)
        except ValueError:
            pass


# -------------------------------------------------------------- random text
_ALPHABET = '()!&|^~<>-=[]XFGURWMV aptrue01"\\x'


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet=_ALPHABET, max_size=40))
def test_property_parse_returns_a_formula_or_a_parse_error(text: str) -> None:
    try:
        f = parse(text)
    except LTLParseError:
        return
    assert parse(str(f)) is f


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(MAX_FORMULA_DEPTH - 5, MAX_FORMULA_DEPTH + 400))
def test_property_deep_random_chains_translate_or_refuse_cleanly(seed: int, depth: int) -> None:
    rng = random.Random(seed)
    f = random_formula(rng, 2)
    for _ in range(depth):
        f = rng.choice([Next, Finally, lambda g: Until(Atom("p0"), g), lambda g: Xor(Atom("p1"), g)])(f)
    try:
        translate(f)
    except TranslationTooLarge as err:  # too deep, too long in NNF, or a tableau over the term budget
        limit = "MAX_FORMULA_DEPTH" if f.depth > MAX_FORMULA_DEPTH else ("MAX_FORMULA_TEXT", "tableau")
        assert any(word in str(err) for word in ((limit,) if isinstance(limit, str) else limit))
    assert parse(str(f)) is f


def test_translate_arguments_are_checked() -> None:
    with pytest.raises(TypeError, match="aps"):
        translate("a & b", aps="ab")
    with pytest.raises(TypeError, match="aps"):
        translate("a", aps=[1])
    with pytest.raises(TypeError, match="simplify_formula"):
        translate("a", simplify_formula="no")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="backend"):
        translate("a", backend=["native"])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="repeats"):
        specs.benchmark_translation(repeats="3")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="variant"):
        specs.cooking(["phi_cb"])  # type: ignore[arg-type]
