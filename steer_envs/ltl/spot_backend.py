"""Optional Spot backend: ``spot.translate`` -> :class:`~steer_envs.ltl.automaton.Automaton`.

Spot (https://spot.lre.epita.fr) is what the thesis used; its Python bindings
come from conda-forge or the Debian/Ubuntu packages of the Spot project, not
from PyPI. When ``import spot`` works, ``translate(f, backend="spot")`` asks
Spot for a transition-based generalized Büchi automaton, exchanges it through
HOA (so this module needs nothing else from Spot) and returns the same
automaton type as the native translator, with guards over the requested APs.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from typing import Any

from steer_envs.ltl.automaton import Automaton
from steer_envs.ltl.hoa import from_hoa
from steer_envs.ltl.parser import parse
from steer_envs.ltl.syntax import Formula

__all__ = ["spot_available", "translate_spot"]


def _import_spot() -> Any:
    return importlib.import_module("spot")


def spot_available() -> bool:
    """True when Spot's Python bindings can be imported."""
    try:
        _import_spot()
    except ImportError:
        return False
    return True


def translate_spot(
    formula: str | Formula, aps: Sequence[str] | None = None, *, options: Sequence[str] = ("TGBA", "small")
) -> Automaton:
    """Translate with ``spot.translate(formula, *options)``.

    Args:
        formula: LTL text or :class:`Formula`; it is printed in Spot syntax.
        aps: AP order of the result (default: the formula's APs, sorted).
            Spot drops APs that do not matter (``a | !a``); they are added back.
        options: passed to ``spot.translate`` (default: small TGBA, Spot's
            default output type).

    Raises:
        ImportError: Spot's Python bindings are not installed.
    """
    try:
        spot = _import_spot()
    except ImportError as exc:
        raise ImportError(
            "backend='spot' needs Spot's Python bindings (`import spot`), which are not on PyPI: install Spot "
            "from conda-forge (`conda install -c conda-forge spot`) or your distribution, or use backend='native'"
        ) from exc
    f = parse(formula)
    atoms = f.atoms()
    target = tuple(sorted(atoms)) if aps is None else tuple(aps)
    missing = sorted(atoms - set(target))
    if missing:
        raise ValueError(f"translate: `aps` must include every AP of the formula; missing {missing}")
    aut = spot.translate(str(f), *options)
    result = from_hoa(aut.to_str("hoa"))
    extra = [ap for ap in result.aps if ap not in target]
    if extra:  # pragma: no cover - Spot never invents APs
        raise ValueError(f"Spot returned APs {extra} that are not in the formula")
    return result.with_aps(target)
