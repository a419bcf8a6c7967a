"""The task specifications of the thesis (ch. 3 appendix), as data.

- **Soup scooping** (appendix "Multi-modal Experiments"): sensor APs ``r s t``,
  mode APs ``a b c d``; the full GR(1) formula. The appendix's ``phi_e_t`` has
  unbalanced parentheses in the source; it is transcribed with each ``<->``
  closed. Two sensor conventions exist for ``d`` (see
  ``steer_envs/envs/soup_scoop.py``): the thesis formula ``d <-> !r & !s & t``
  and the public code's automaton table ``d <-> !r & s & t``; both are here.
- **Cooking** (appendix "Generalization Results"): the ``phi_s_t`` variants
  ``phi_cb`` (chicken first), ``phi_bc`` (broccoli first), ``phi_c`` (chicken
  only), ``phi_cc`` (chicken continuously), verbatim, with the shared parts
  built "following the scooping task": initial white/empty spoon, mode APs
  defined by the Cooking-v0 sensors (``hc hb p ch br``, see
  :data:`COOKING_MODE_FORMULAS`), exactly one mode at a time, goal ``G F d2``
  (``G F d`` for the four-mode variants).
- **Color tracing** (appendix "Robot Experiment 3"): tiles yellow, blue,
  green, orange, pink, then red (goal); perturbations into the dark region
  are modes ``dark1..dark4`` (the figure's D1-D4: the dark region entered from
  yellow, blue, green, and orange or pink; the figure itself is not in the
  thesis source, so this assignment is ours). Automata (a): every dark mode
  re-enters at yellow; (b): exits after the blue tile re-enter at blue (an exit
  at yellow re-enters at yellow); (c): an exit at yellow continues at blue, an
  exit at blue continues at pink (the text), other exits re-enter the tile
  they left (our completion). ``steer_envs/ColorTracing-v0``
  (:mod:`steer_envs.envs.color_tracing`) implements it; its task adds the
  exits and re-entries and labels no sensor reading (the dark reading is
  ambiguous), :data:`COLOR_TRACING_TASK` is the labelled chain.

:func:`for_env` returns the spec attached to a registered env id, and
:func:`benchmark_translation` times the translation of every spec.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Sequence
from functools import partial
from types import MappingProxyType
from typing import Any

from steer_envs.core.cooking_aps import COOKING_MODE_FORMULAS, COOKING_SENSORS
from steer_envs.core.task import TaskSpec
from steer_envs.ltl.gr1 import GR1Spec

__all__ = [
    "COLOR_MODES",
    "COLOR_SENSORS",
    "COLOR_TRACING_TASK",
    "COOKING_MODE_FORMULAS",
    "COOKING_SENSORS",
    "all_specs",
    "benchmark_translation",
    "color_tracing",
    "cooking",
    "for_env",
    "soup_scoop",
    "variants",
]


def exactly_one(aps: Sequence[str]) -> str:
    """LTL text: exactly one of ``aps`` is true (the thesis's one-mode-at-a-time constraint)."""
    terms = []
    for ap in aps:
        terms.append("(" + " & ".join(ap if other == ap else f"!{other}" for other in aps) + ")")
    return " | ".join(terms)


# ------------------------------------------------------------ soup scooping
SOUP_SENSORS = ("r", "s", "t")
SOUP_MODES = ("a", "b", "c", "d")
_SOUP_D_SENSORS = MappingProxyType({"thesis": "!r & !s & t", "public": "!r & s & t"})


def soup_scoop(convention: str = "thesis") -> GR1Spec:
    """The soup-scooping GR(1) spec; ``convention`` picks the sensor state of ``d`` (``"thesis"``/``"public"``)."""
    if not isinstance(convention, str) or convention not in _SOUP_D_SENSORS:
        raise ValueError(f"convention must be one of {tuple(_SOUP_D_SENSORS)}, got {convention!r}")
    d = _SOUP_D_SENSORS[convention]
    return GR1Spec(
        env_init="!r & !s & !t",
        env_safety=(
            f"G((a <-> (!r & !s & !t)) & (b <-> (r & !s & !t)) & (c <-> (!r & s & !t)) & (d <-> ({d}))) "
            f"& G({exactly_one(SOUP_MODES)})"
        ),
        env_liveness="true",
        sys_init="a",
        sys_safety=("G((a -> (X a | X b)) & (b -> (X a | X b | X c)) & (c -> (X a | X b | X c | X d)) & (d -> X d))"),
        sys_liveness="G F d",
        modes=SOUP_MODES,
        name=f"soup_scoop_{convention}",
        description="thesis appendix 'Multi-modal Experiments' (reach a, scoop b, transport c, done d)",
    )


# ------------------------------------------------------------------ cooking
_COOKING_SYS_SAFETY = MappingProxyType(
    {
        "phi_cb": "G((w1 -> X y) & (y -> (X w1 | X d1)) & (d1 -> (X w2 | X g)) & (w2 -> X g) "
        "& (g -> (X w2 | X d2)) & (d2 -> X d2))",
        "phi_bc": "G((w1 -> X g) & (g -> (X w1 | X d1)) & (d1 -> (X w2 | X y)) & (w2 -> X y) "
        "& (y -> (X w2 | X d2)) & (d2 -> X d2))",
        "phi_c": "G((w -> (X y | X g)) & (y -> (X w | X d)) & (g -> X w) & (d -> X d))",
        "phi_cc": "G((w -> X y) & (y -> (X w | X d)) & (d -> X w))",
    }
)
_COOKING_DESCRIPTIONS = MappingProxyType(
    {
        "phi_cb": "chicken first, then broccoli (thesis Fig. (c): w y d g d)",
        "phi_bc": "broccoli first, then chicken (thesis Fig. (d): w g d y d)",
        "phi_c": "chicken only (thesis Fig. (e))",
        "phi_cc": "chicken continuously (thesis Fig. (f))",
    }
)


def cooking(variant: str = "phi_cb") -> GR1Spec:
    """A cooking re-tasking: the thesis's ``phi_s_t`` variant plus the shared parts."""
    if not isinstance(variant, str) or variant not in _COOKING_SYS_SAFETY:
        raise ValueError(f"variant must be one of {tuple(_COOKING_SYS_SAFETY)}, got {variant!r}")
    memory = variant in ("phi_cb", "phi_bc")
    modes = ("w1", "w2", "y", "g", "d1", "d2") if memory else ("w", "y", "g", "d")
    definitions = " & ".join(f"({m} <-> ({COOKING_MODE_FORMULAS[m]}))" for m in modes)
    return GR1Spec(
        env_init="!hc & !hb & !p & !ch & !br",
        # the env reports at most one of hc, hb, p (the spoon is in one region)
        env_safety=f"G({definitions}) & G({exactly_one(modes)}) & G(!(hc & hb) & !(hc & p) & !(hb & p))",
        env_liveness="true",
        sys_init="w1" if memory else "w",
        sys_safety=_COOKING_SYS_SAFETY[variant],
        sys_liveness="G F d2" if memory else "G F d",
        modes=modes,
        name=variant,
        description="thesis appendix 'Generalization Results': " + _COOKING_DESCRIPTIONS[variant],
    )


# ------------------------------------------------------------ color tracing
COLOR_TILES = ("yellow", "blue", "green", "orange", "pink")
COLOR_MODES = (*COLOR_TILES, "red", "dark1", "dark2", "dark3", "dark4")
#: sensor APs: the tile under the end-effector (k: the dark region)
COLOR_SENSORS = ("y", "b", "g", "o", "p", "r", "k")
_TILE_SENSOR = MappingProxyType(dict(zip((*COLOR_TILES, "red"), ("y", "b", "g", "o", "p", "r"), strict=True)))
#: dark mode entered when leaving each tile (the figure's D1..D4; pink shares dark4 with orange)
_EXIT_MODE = MappingProxyType(
    {"yellow": "dark1", "blue": "dark2", "green": "dark3", "orange": "dark4", "pink": "dark4"}
)
_REENTRY = MappingProxyType(
    {
        "a": {"dark1": "yellow", "dark2": "yellow", "dark3": "yellow", "dark4": "yellow"},
        "b": {"dark1": "yellow", "dark2": "blue", "dark3": "blue", "dark4": "blue"},
        "c": {"dark1": "blue", "dark2": "pink", "dark3": "green", "dark4": "orange"},
    }
)
_COLOR_DESCRIPTIONS = MappingProxyType(
    {
        "a": "(a) a mode exit at any colored tile re-enters at the yellow tile",
        "b": "(b) a mode exit at any tile after yellow re-enters at the blue tile",
        "c": "(c) an exit at yellow continues at blue, an exit at blue at pink",
    }
)


def _color_task() -> TaskSpec:
    sensor_modes: dict[frozenset[str], str] = {frozenset({s}): tile for tile, s in _TILE_SENSOR.items()}
    # the demonstrated chain; exits into the dark region and re-entries belong to the automata (a)-(c)
    chain = (*COLOR_TILES, "red")
    transitions = {(chain[i], chain[i + 1]) for i in range(len(chain) - 1)}
    return TaskSpec(
        name="ColorTracing",
        modes=COLOR_MODES,
        sensors=COLOR_SENSORS,
        sensor_modes=sensor_modes,  # the dark readings are ambiguous (dark1..dark4): tracked by the automaton
        transitions=frozenset(transitions),
        initial="yellow",
        goal=("red",),
    )


#: the labelled chain of the color-tracing experiment (the env's own task: ``steer_envs.envs.color_tracing``)
COLOR_TRACING_TASK = _color_task()


def color_tracing(variant: str = "a") -> GR1Spec:
    """Color-tracing automaton ``variant`` in ``("a", "b", "c")`` as a GR(1) spec (see the module doc)."""
    if not isinstance(variant, str) or variant not in _REENTRY:
        raise ValueError(f"variant must be one of {tuple(_REENTRY)}, got {variant!r}")
    definitions = [f"({tile} <-> {s})" for tile, s in _TILE_SENSOR.items()]
    definitions.append("((dark1 | dark2 | dark3 | dark4) <-> k)")
    chain = (*COLOR_TILES, "red")
    rules = []
    for i, tile in enumerate(COLOR_TILES):
        rules.append(f"({tile} -> (X {tile} | X {chain[i + 1]} | X {_EXIT_MODE[tile]}))")
    rules.append("(red -> X red)")
    for dark, tile in _REENTRY[variant].items():
        rules.append(f"({dark} -> (X {dark} | X {tile}))")
    return GR1Spec(
        env_init="y & !b & !g & !o & !p & !r & !k",
        env_safety=f"G({' & '.join(definitions)}) & G({exactly_one(COLOR_MODES)})",
        env_liveness="true",
        sys_init="yellow",
        sys_safety="G(" + " & ".join(rules) + ")",
        sys_liveness="G F red",
        modes=COLOR_MODES,
        recovery_modes=("dark1", "dark2", "dark3", "dark4"),
        name=f"color_tracing_{variant}",
        description="thesis appendix 'Robot Experiment 3: Color Tracing' " + _COLOR_DESCRIPTIONS[variant],
    )


# ------------------------------------------------------------------ lookup
_ENVS: dict[str, tuple[str, dict[str, Callable[[], GR1Spec]]]] = {
    "SoupScoop-v0": ("public", {c: partial(soup_scoop, c) for c in ("public", "thesis")}),
    "Cooking-v0": ("phi_cb", {v: partial(cooking, v) for v in _COOKING_SYS_SAFETY}),
    "ColorTracing-v0": ("a", {v: partial(color_tracing, v) for v in _REENTRY}),
}


def _env_name(env: Any) -> tuple[str, Any]:
    """``(registered name without namespace, the env instance or None)``."""
    if isinstance(env, str):
        return env.split("/")[-1], None
    spec = getattr(env, "spec", None)
    if spec is None or not getattr(spec, "id", None):
        raise ValueError("for_env: the env has no registered id (env.spec.id); pass the id string instead")
    return str(spec.id).split("/")[-1], env


def variants(env: Any) -> tuple[str, ...]:
    """The spec variants attached to an env id (or env)."""
    name, _ = _env_name(env)
    if name not in _ENVS:
        raise ValueError(f"no LTL spec is attached to {name!r}; specs exist for {tuple(_ENVS)}")
    return tuple(_ENVS[name][1])


def for_env(env: Any, variant: str | None = None) -> GR1Spec:
    """The thesis spec attached to an env id (``"steer_envs/SoupScoop-v0"``) or a made env.

    Args:
        env: env id (with or without namespace) or a Gymnasium env made from one.
        variant: which spec (see :func:`variants`); default: the env's own
            (SoupScoop: the env's ``sensor_convention``, else ``"public"``;
            Cooking: ``"phi_cb"``; ColorTracing: ``"a"``).

    >>> for_env("steer_envs/Cooking-v0").name, variants("steer_envs/Cooking-v0")
    ('phi_cb', ('phi_cb', 'phi_bc', 'phi_c', 'phi_cc'))
    """
    name, instance = _env_name(env)
    if name not in _ENVS:
        raise ValueError(f"no LTL spec is attached to {name!r}; specs exist for {tuple(_ENVS)}")
    default, table = _ENVS[name]
    if variant is None:
        variant = default
        model = getattr(getattr(instance, "unwrapped", None), "model", None)
        convention = getattr(model, "sensor_convention", None)
        if name == "SoupScoop-v0" and convention in table:
            variant = convention
    if not isinstance(variant, str) or variant not in table:
        raise ValueError(f"variant for {name!r} must be one of {tuple(table)}, got {variant!r}")
    return table[variant]()


def all_specs() -> dict[str, GR1Spec]:
    """Every thesis spec by name (soup scooping x2, cooking x4, color tracing x3)."""
    out: dict[str, GR1Spec] = {}
    for _, table in _ENVS.values():
        for make in table.values():
            spec = make()
            out[spec.name] = spec
    return out


def benchmark_translation(repeats: int = 5, *, backend: str = "native", cold: bool = True) -> dict[str, float]:
    """Seconds (median of ``repeats``) to translate each thesis spec's full GR(1) formula.

    The formula translated is :meth:`GR1Spec.translation_formula` (the same
    language as ``phi_e -> phi_s``). ``cold=True`` clears the simplifier's
    caches before every run, so each timing includes NNF and simplification.
    The thesis target is < 50 ms per spec.
    """
    from steer_envs.ltl.buchi import translate
    from steer_envs.ltl.simplify import clear_caches

    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"repeats must be an int >= 1, got {repeats!r}")
    timings: dict[str, float] = {}
    for name, spec in all_specs().items():
        formula = spec.translation_formula()
        runs = []
        for _ in range(repeats):
            if cold:
                clear_caches()
            start = time.perf_counter()
            translate(formula, backend=backend)
            runs.append(time.perf_counter() - start)
        timings[name] = statistics.median(runs)
    return timings
