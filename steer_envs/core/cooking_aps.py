"""The Cooking task's atomic propositions, which the env reports and its LTL specs read.

Cooking-v0 (:mod:`steer_envs.envs.cooking`) reports the sensor APs; the
thesis's mode APs of its edited automata (:func:`steer_envs.ltl.specs.cooking`)
are boolean formulas over them (Spot syntax). Both layers take them from here,
so the env and the specs cannot drift apart.

>>> COOKING_MODE_FORMULAS["w2"]
'!hc & !hb & !p & (ch | br)'
"""

from __future__ import annotations

from types import MappingProxyType

__all__ = ["COOKING_MODE_FORMULAS", "COOKING_SENSORS"]

#: the sensor APs: spoon holds chicken / broccoli, spoon in the pot, chicken / broccoli added to the pot
COOKING_SENSORS: tuple[str, ...] = ("hc", "hb", "p", "ch", "br")
#: the thesis's mode APs as Spot formulas over :data:`COOKING_SENSORS`
COOKING_MODE_FORMULAS: MappingProxyType[str, str] = MappingProxyType(
    {
        "w": "!hc & !hb & !p",
        "y": "hc",
        "g": "hb",
        "d": "p",
        "w1": "!hc & !hb & !p & !ch & !br",
        "w2": "!hc & !hb & !p & (ch | br)",
        "d1": "p & ((ch & !br) | (!ch & br))",
        "d2": "p & ch & br",
    }
)
