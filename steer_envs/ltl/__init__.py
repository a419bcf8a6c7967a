"""LTL for task specifications: parse, simplify, evaluate, translate to Büchi automata, replan modes.

Pipeline (thesis ch. 3): an LTL formula in Spot syntax is parsed
(:func:`parse`) into an immutable :class:`Formula`, simplified to negation
normal form (:func:`simplify`), and translated (:func:`translate`) into an
explicit generalized Büchi :class:`Automaton` (native tableau translator, or
Spot when installed: ``backend="spot"``), which exports to HOA. The exact
lasso-word semantics (:func:`evaluate`) is the reference the translator is
tested against. :class:`ModeReplanner` turns a GR(1)-style task specification
(:class:`GR1Spec`) over a :class:`~steer_envs.core.task.TaskSpec` into a task
automaton over modes that answers "which mode next?" from sensor readings.

Deep input never ends in a ``RecursionError``: parsing and printing use
explicit stacks (:data:`MAX_PARSE_DEPTH`), NNF, simplification and
translation refuse formulas deeper than :data:`MAX_FORMULA_DEPTH`
(:class:`FormulaTooDeep`, :class:`TranslationTooLarge`; both ``ValueError``).
Sensor readings must hold real bools (``"False"`` is an error, not true).

>>> from steer_envs.ltl import LassoWord, evaluate, parse, translate
>>> formula = parse("G(request -> F grant)")
>>> automaton = translate(formula)
>>> automaton.accepts(prefix=[{"request"}], loop=[{"grant"}])
True
>>> evaluate(formula, LassoWord.of([], [{"request"}]))
False
"""

from steer_envs.ltl.automaton import Automaton, Edge
from steer_envs.ltl.buchi import BACKENDS, TranslationTooLarge, translate, translate_native
from steer_envs.ltl.gr1 import GR1Spec
from steer_envs.ltl.hoa import from_hoa, to_hoa, write_hoa
from steer_envs.ltl.parser import MAX_PARSE_DEPTH, LTLParseError, parse
from steer_envs.ltl.replanner import (
    ModeReplanner,
    TaskAutomaton,
    UnknownSensorReading,
    UnrealizableSpecError,
)
from steer_envs.ltl.semantics import LassoWord, evaluate, evaluate_positions
from steer_envs.ltl.simplify import nnf, simplify
from steer_envs.ltl.spot_backend import spot_available, translate_spot
from steer_envs.ltl.syntax import (
    BINARY_OPERATORS,
    FALSE,
    MAX_FORMULA_DEPTH,
    MAX_FORMULA_TEXT,
    TRUE,
    UNARY_OPERATORS,
    And,
    Atom,
    Const,
    Equiv,
    Finally,
    Formula,
    FormulaTooDeep,
    Globally,
    Implies,
    Next,
    Not,
    Or,
    Release,
    StrongRelease,
    Until,
    WeakUntil,
    Xor,
)

__all__ = [
    "BACKENDS",
    "BINARY_OPERATORS",
    "FALSE",
    "MAX_FORMULA_DEPTH",
    "MAX_FORMULA_TEXT",
    "MAX_PARSE_DEPTH",
    "TRUE",
    "UNARY_OPERATORS",
    "And",
    "Atom",
    "Automaton",
    "Const",
    "Edge",
    "Equiv",
    "Finally",
    "Formula",
    "FormulaTooDeep",
    "GR1Spec",
    "Globally",
    "Implies",
    "LTLParseError",
    "LassoWord",
    "ModeReplanner",
    "Next",
    "Not",
    "Or",
    "Release",
    "StrongRelease",
    "TaskAutomaton",
    "TranslationTooLarge",
    "UnknownSensorReading",
    "UnrealizableSpecError",
    "Until",
    "WeakUntil",
    "Xor",
    "evaluate",
    "evaluate_positions",
    "from_hoa",
    "nnf",
    "parse",
    "simplify",
    "spot_available",
    "to_hoa",
    "translate",
    "translate_native",
    "translate_spot",
    "write_hoa",
]
