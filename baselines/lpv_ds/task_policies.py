"""LTL-DS policies of the thesis's TLI tasks, fitted from their demonstrations (thesis ch. 3 and appendix).

Each function composes the task's demonstrations
(:mod:`steer_envs.data.tli_demos`), its GR(1) spec and the fit settings of the
study into a policy:

* :func:`soup_scoop_policy` -- SoupScoop-v0 (§3.7.2): one LPV-DS per mode
  under the env's soup-scooping automaton;
* :func:`arm_scoop_policy` -- ArmScoop-v0 (robot experiment 1): the same on
  the Panda arm's ``(y, z, pitch)`` state;
* :func:`color_policy` -- ColorTracing-v0 (robot experiment 3): one LPV-DS per
  tile (:func:`fit_tile_dynamics`, from a single demonstration) and a
  :class:`ReentryFlow` per dark mode, under a replanning automaton;
* :func:`inspection_policy` and :func:`vanilla_ds` -- InspectionLine-v0 (robot
  experiment 2): LTL-DS under :func:`inspection_spec`, and the single LPV-DS
  fitted to whole demonstrations that it is compared with.

>>> inspection_spec().modes
('reach_entry', 'inspect', 'released')
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

from steer_envs.baselines.lpv_ds.lpvds import LPVDS
from steer_envs.baselines.lpv_ds.ltl_ds import LTLDSPolicy, ModeDynamics, fit_mode_dynamics
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import boolean, integer, one_of, real_scalar
from steer_envs.data.tli_demos import arm_scoop_demonstrations, color_demonstration, scoop_demonstrations
from steer_envs.envs.color_tracing import (
    AUTOMATA,
    DARK_MODES,
    REENTRY,
    ROW_X0,
    TILE_WIDTH,
    TILES,
    color_task,
    reentry_target,
)
from steer_envs.envs.robosuite.arm_scoop import arm_scoop_task
from steer_envs.ltl.gr1 import GR1Spec
from steer_envs.ltl.specs import color_tracing, for_env, soup_scoop

__all__ = [
    "ReentryFlow",
    "arm_scoop_policy",
    "color_policy",
    "fit_tile_dynamics",
    "inspection_policy",
    "inspection_spec",
    "soup_scoop_policy",
    "vanilla_ds",
]

#: LPV-DS stability margin of the mode DSs (the library default 1e-3 lets far flows crawl)
DS_EPS = 1.0
#: attractors sit this far past the mean guard crossing (> dt * max_speed = 0.1 in the 2D tasks)
OVERSHOOT = 0.25
#: ArmScoop: attractor overshoot (state units), DS speed bound (norm over m/s, m/s, rad/s) and the radius
#: around each attractor that every cut keeps inside (dt * ARM_MAX_SPEED = 0.03 < ARM_CUT_MARGIN)
ARM_OVERSHOOT = 0.01
ARM_MAX_SPEED = 0.6
ARM_CUT_MARGIN = 0.05
#: gain of the ColorTracing dark modes' flow toward their re-entry target (1/s)
REENTRY_GAIN = 5.0
#: the ColorTracing tile modes alone: the demonstration's labels index them (the env's modes start with the tiles)
TILE_TASK = TaskSpec(name="ColorTracingTiles", modes=TILES, transitions=frozenset(itertools.pairwise(TILES)))


# ------------------------------------------------------------------ soup scooping
def soup_scoop_policy(
    seed: int, n_demos: int, env: Any, *, modulation: bool, demos: str = "drawn", ds_eps: float = DS_EPS,
    overshoot: float = OVERSHOOT,
) -> LTLDSPolicy:  # fmt: skip
    """LTL-DS for SoupScoop ``env`` from experiment ``seed``'s ``n_demos`` demonstrations (``"drawn"``/``"expert"``)."""
    base = env.unwrapped
    return LTLDSPolicy.fit(
        scoop_demonstrations(seed, n_demos, demos),
        base.task,
        for_env(env),
        overshoot=overshoot,
        random_state=seed,
        ds_options={"eps": ds_eps},
        modulation=modulation,
        max_speed=base.max_speed,
        dt=base.dt,
    )


def arm_scoop_policy(seed: int, *, modulation: bool, n_demos: int = 2) -> LTLDSPolicy:
    """LTL-DS fitted on experiment ``seed``'s ArmScoop demonstrations (with or without learning cuts).

    One LPV-DS per mode (``d`` reuses ``c``'s) under :func:`steer_envs.ltl.specs.soup_scoop` (public convention).
    """
    return LTLDSPolicy.fit(
        list(arm_scoop_demonstrations(seed, n_demos)), arm_scoop_task(), soup_scoop("public"),
        overshoot=ARM_OVERSHOOT, random_state=seed, ds_options={"eps": DS_EPS}, modulation=modulation,
        max_speed=ARM_MAX_SPEED, margin=ARM_CUT_MARGIN,
    )  # fmt: skip


# ------------------------------------------------------------------ colour tracing
@functools.lru_cache(maxsize=4)
def fit_tile_dynamics(seed: int) -> dict[str, ModeDynamics]:
    """One LPV-DS per ColorTracing tile from experiment ``seed``'s demonstration (cached; shared, do not modify).

    Attractor: the first state on the next tile, :data:`OVERSHOOT` further along the crossing; red reuses pink's.
    """
    seed = integer(seed, "seed", low=0, owner="fit_tile_dynamics")
    return fit_mode_dynamics(
        [color_demonstration(seed)], TILE_TASK, overshoot=OVERSHOOT, random_state=seed, ds_options={"eps": DS_EPS}
    )


class ReentryFlow:
    """The flow of a ColorTracing dark mode: ``gain * (target - x)`` toward the re-entry point of ``tile``.

    The demonstration never enters the dark region, so the way back is not
    learned: the flow heads for the tile the automaton re-enters at, through
    the dark region only (:func:`~steer_envs.envs.color_tracing.reentry_target`:
    straight in when that crosses no other tile, else through a lane beside the row).

    >>> import numpy as np
    >>> ReentryFlow("yellow")(np.zeros((1, 2))).shape
    (1, 2)
    """

    def __init__(self, tile: str, gain: float = REENTRY_GAIN) -> None:
        self.tile = one_of(tile, "tile", TILES, owner="ReentryFlow")
        self.index = TILES.index(tile)
        self.gain = real_scalar(gain, "gain", low=0.0, low_inclusive=False, owner="ReentryFlow")

    def __call__(self, x: np.ndarray) -> np.ndarray:
        p = np.asarray(x, dtype=np.float64).reshape(-1, 2)
        return self.gain * (reentry_target(p, self.index) - p)


def color_policy(seed: int, automaton: str, *, modulation: bool = True, max_speed: float = 10.0, dt: float = 0.01
                 ) -> LTLDSPolicy:  # fmt: skip
    """LTL-DS for ColorTracing ``automaton``: the experiment's tile DSs plus the automaton's dark-mode flows."""
    one_of(automaton, "automaton", AUTOMATA, owner="color_policy")
    modulation = boolean(modulation, "modulation", owner="color_policy")
    dynamics: dict[str, ModeDynamics] = dict(fit_tile_dynamics(seed))
    empty = np.zeros((0, 2))
    for dark in DARK_MODES:
        tile = REENTRY[automaton][dark]
        centre = np.array([ROW_X0 + TILE_WIDTH * (TILES.index(tile) + 0.5), 0.0])
        dynamics[dark] = ModeDynamics(dark, ReentryFlow(tile), centre, "reentry", empty, empty)
    return LTLDSPolicy(
        color_task(automaton), color_tracing(automaton), dynamics, modulation=modulation, max_speed=max_speed, dt=dt
    )


# ------------------------------------------------------------------ inspection line
def inspection_spec() -> GR1Spec:
    """The inspection task's GR(1) spec: reach the entry, inspect (or back on a drop), released absorbs."""
    modes = ("reach_entry", "inspect", "released")
    return GR1Spec(
        env_init="!l & !r",
        env_safety="G((reach_entry <-> !l) & (inspect <-> (l & !r)) & (released <-> (l & r))) "
        "& G((reach_entry & !inspect & !released) | (!reach_entry & inspect & !released) "
        "| (!reach_entry & !inspect & released))",
        env_liveness="true",
        sys_init="reach_entry",
        sys_safety="G((reach_entry -> (X reach_entry | X inspect)) "
        "& (inspect -> (X inspect | X released | X reach_entry)) & (released -> X released))",
        sys_liveness="G F released",
        modes=modes,
        name="inspection_line",
        description="thesis appendix 'Robot Experiment 2': go to the inspection entry, follow the line and release",
    )


def vanilla_ds(demos: Sequence[Any], dt: float, seed: int) -> LPVDS:
    """The *vanilla DS*: one LPV-DS on the whole demonstrations, attractor at their mean end (finite differences)."""
    xs = [np.asarray(d.states, dtype=np.float64) for d in demos]
    vs = [np.vstack([np.diff(x, axis=0) / dt, np.zeros((1, 2))]) for x in xs]
    attractor = np.mean([x[-1] for x in xs], axis=0)
    return LPVDS(eps=DS_EPS, random_state=seed).fit(xs, vs, attractor=attractor)


def inspection_policy(demos: Sequence[Any], base: Any, seed: int, *, modulation: bool) -> LTLDSPolicy:
    """LTL-DS on the unwrapped InspectionLine env ``base`` under :func:`inspection_spec` (with or without cuts)."""
    return LTLDSPolicy.fit(
        list(demos), base.task, inspection_spec(), overshoot=OVERSHOOT, random_state=seed,
        ds_options={"eps": DS_EPS}, modulation=modulation, max_speed=base.max_speed, dt=base.dt,
    )  # fmt: skip
