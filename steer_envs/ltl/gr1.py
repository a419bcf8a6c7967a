"""GR(1) task specifications (thesis §3.4, appendix "Multi-modal Experiments").

A GR(1) formula is ``(phi_e_i & phi_e_t & phi_e_g) -> (phi_s_i & phi_s_t &
phi_s_g)``: environment (sensor) assumptions imply system (mode) guarantees,
each split into *initial* conditions (propositional), *safety* (``G`` of a
propositional formula over the current step and ``X`` of the next one) and
*liveness* (``G F`` of propositional goals). :class:`GR1Spec` holds the six
parts as text, validates that each belongs to its fragment (errors name the
part), and builds the full formula for the translator.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

from steer_envs.core.validation import describe, name_tuple
from steer_envs.ltl import syntax as s
from steer_envs.ltl.parser import LTLParseError, parse
from steer_envs.ltl.syntax import Formula, FormulaTooDeep, check_depth

__all__ = ["PARTS", "GR1Spec", "SafetyPart"]

#: the six parts, in formula order
PARTS = ("env_init", "env_safety", "env_liveness", "sys_init", "sys_safety", "sys_liveness")


@dataclass(frozen=True)
class SafetyPart:
    """A safety part split into invariants (no ``X``) and transition constraints (with ``X``)."""

    invariants: tuple[Formula, ...]
    transitions: tuple[Formula, ...]


def _conjuncts(f: Formula) -> tuple[Formula, ...]:
    if f is s.TRUE:
        return ()
    return f.args if isinstance(f, s.And) else (f,)


def _has_next(f: Formula) -> bool:
    return any(isinstance(g, s.Next) for g in f.subformulas())


def _names(value: Any, what: str) -> tuple[str, ...]:
    return name_tuple(value, f"GR1Spec.{what}", what="mode names")


@dataclass(frozen=True)
class GR1Spec:
    """A GR(1) specification over sensor APs (environment) and mode APs (system).

    Args:
        env_init, sys_init: propositional formulas on the first step.
        env_safety, sys_safety: conjunctions of ``G(body)``, ``body`` propositional
            over the current step plus ``X p`` (``p`` propositional) for the next.
        env_liveness, sys_liveness: ``true`` or conjunctions of ``G F p``.
        modes: the system (mode) APs; ``None`` means the task's modes.
        recovery_modes: modes entered only through perturbations (the dark
            region of color tracing): the automaton tracks them and plans out
            of them, but a plan never leads into one.
        name: a label (e.g. ``"phi_cb"``).
        description: free text (where the spec comes from).

    All parts are LTL text in Spot syntax; they are parsed and checked here
    (a part nested deeper than :data:`~steer_envs.ltl.syntax.MAX_FORMULA_DEPTH`
    raises :class:`~steer_envs.ltl.syntax.FormulaTooDeep` naming it). Mode
    names are str (a single string is not a tuple of its characters).

    >>> spec = GR1Spec(sys_init="m0", sys_safety="G(m0 -> X m1) & G(m1 -> X m1)", sys_liveness="G F m1")
    >>> str(spec.formula())
    '(true & true & true) -> (m0 & G(m0 -> Xm1) & G(m1 -> Xm1) & GFm1)'
    >>> spec.retask("G(m0 -> X m0)").sys_safety
    'G(m0 -> X m0)'
    """

    env_init: str = "true"
    env_safety: str = "true"
    env_liveness: str = "true"
    sys_init: str = "true"
    sys_safety: str = "true"
    sys_liveness: str = "true"
    modes: tuple[str, ...] | None = None
    recovery_modes: tuple[str, ...] = ()
    name: str = ""
    description: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        for part in PARTS:
            text = getattr(self, part)
            if not isinstance(text, str):
                raise TypeError(f"GR1Spec.{part} must be LTL text (str), got {type(text).__name__}")
        for label in ("name", "description"):
            if not isinstance(getattr(self, label), str):
                raise TypeError(f"GR1Spec.{label} must be a str, got {describe(getattr(self, label))}")
        if self.modes is not None:
            modes = _names(self.modes, "modes")
            if not modes or len(set(modes)) != len(modes):
                raise ValueError(f"GR1Spec.modes must be distinct mode APs, got {self.modes!r}")
            object.__setattr__(self, "modes", modes)
        recovery = _names(self.recovery_modes, "recovery_modes")
        if self.modes is not None and not set(recovery) <= set(self.modes):
            raise ValueError(f"GR1Spec.recovery_modes {recovery} must be among GR1Spec.modes {self.modes}")
        object.__setattr__(self, "recovery_modes", recovery)
        # parse and validate every part now, so errors surface where the spec is written
        for part in ("env_init", "sys_init"):
            self.initial_condition(part)
        for part in ("env_safety", "sys_safety"):
            self.safety(part)
        for part in ("env_liveness", "sys_liveness"):
            self.liveness(part)

    # -------------------------------------------------------------- parts
    def part(self, name: str) -> Formula:
        """The parsed formula of part ``name`` (one of :data:`PARTS`)."""
        if name not in PARTS:
            raise ValueError(f"part must be one of {PARTS}, got {name!r}")
        return self._parsed[name]

    @cached_property
    def _parsed(self) -> dict[str, Formula]:
        out = {}
        for name in PARTS:
            try:
                out[name] = parse(getattr(self, name))
            except LTLParseError as err:
                raise ValueError(f"GR1Spec.{name}: {err}") from None
            check_depth(out[name], f"GR1Spec.{name}", error=FormulaTooDeep)
        return out

    def initial_condition(self, name: str) -> Formula:
        """``env_init`` / ``sys_init``: must be propositional."""
        f = self.part(name)
        if not f.is_boolean:
            raise ValueError(f"GR1Spec.{name} must be propositional (no temporal operator), got {str(f)!r}")
        return f

    def safety(self, name: str) -> SafetyPart:
        """``env_safety`` / ``sys_safety`` split into invariants and transition constraints."""
        f = self.part(name)
        invariants: list[Formula] = []
        transitions: list[Formula] = []
        for conj in _conjuncts(f):
            if not isinstance(conj, s.Globally):
                raise ValueError(
                    f"GR1Spec.{name} must be a conjunction of G(...) formulas (GR(1) safety); "
                    f"{str(conj)!r} is not under G"
                )
            for item in _conjuncts(conj.arg):
                for g in item.subformulas():
                    if isinstance(g, s.Next):
                        if not g.arg.is_boolean:
                            raise ValueError(
                                f"GR1Spec.{name}: X may only apply to propositional formulas (GR(1) safety), "
                                f"got {str(g)!r}"
                            )
                    elif not g.propositional:
                        raise ValueError(
                            f"GR1Spec.{name}: inside G(...) only propositional formulas and X of them are allowed "
                            f"(GR(1) safety), got {str(g)!r}"
                        )
                (transitions if _has_next(item) else invariants).append(item)
        return SafetyPart(tuple(invariants), tuple(transitions))

    def liveness(self, name: str) -> tuple[Formula, ...]:
        """``env_liveness`` / ``sys_liveness``: the propositional goals ``p`` of its ``G F p`` conjuncts."""
        f = self.part(name)
        goals: list[Formula] = []
        for conj in _conjuncts(f):
            if isinstance(conj, s.Globally) and isinstance(conj.arg, s.Finally) and conj.arg.arg.is_boolean:
                goals.append(conj.arg.arg)
            else:
                raise ValueError(
                    f"GR1Spec.{name} must be 'true' or a conjunction of G F p with p propositional (GR(1) "
                    f"liveness); got {str(conj)!r}"
                )
        return tuple(goals)

    # ------------------------------------------------------------ formulas
    @property
    def environment(self) -> Formula:
        """``phi_e = phi_e_i & phi_e_t & phi_e_g``."""
        return s.And(self.part("env_init"), self.part("env_safety"), self.part("env_liveness"))

    @property
    def system(self) -> Formula:
        """``phi_s = phi_s_i & phi_s_t & phi_s_g``."""
        return s.And(self.part("sys_init"), self.part("sys_safety"), self.part("sys_liveness"))

    def formula(self) -> Formula:
        """The GR(1) formula ``phi_e -> phi_s``."""
        return s.Implies(self.environment, self.system)

    def translation_formula(self) -> Formula:
        """``!phi_e | (phi_e & phi_s)``: the same language as :meth:`formula`, easier to translate.

        In ``phi_e -> phi_s`` a tableau explores the system guarantee on every
        valuation, also those the environment's invariants exclude (with ten
        one-hot modes, 2**10 mode combinations). Conjoining ``phi_e`` puts the
        invariants under the same ``G`` as the system's safety, where they
        prune the guards at once.
        """
        env = self.environment
        return s.Or(s.Not(env), s.And(env, self.system))

    def atoms(self) -> frozenset[str]:
        """Every AP the spec mentions."""
        return frozenset().union(*(self.part(p).atoms() for p in PARTS))

    def __str__(self) -> str:
        return str(self.formula())

    def retask(self, sys_safety: str, *, name: str = "", modes: tuple[str, ...] | None = None, **parts: str) -> GR1Spec:
        """A copy with a new ``sys_safety`` (thesis: re-tasking edits ``phi_s_t``) and optionally other parts."""
        changes: dict[str, Any] = {"sys_safety": sys_safety, **parts}
        if name:
            changes["name"] = name
        if modes is not None:
            changes["modes"] = modes
        return replace(self, **changes)
