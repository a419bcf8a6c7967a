"""Stable dynamical systems from demonstrations (thesis ch. 3): LPV-DS and LTL-DS.

* :mod:`.lpvds` -- :class:`LPVDS`, a globally asymptotically stable
  linear-parameter-varying DS fitted by convex programs, and its numerical
  stability check (:meth:`LPVDS.check_stability` -> :class:`StabilityReport`);
* :mod:`.ltl_ds` -- :class:`LTLDSPolicy`: one LPV-DS per mode
  (:func:`fit_mode_dynamics`), sequenced by the task automaton and bounded by
  cuts learned from invariance failures.

>>> import numpy as np
>>> from steer_envs.baselines.lpv_ds import LPVDS
>>> ds = LPVDS.from_parameters(np.zeros(2), np.eye(2), [-np.eye(2)], [1.0], [np.zeros(2)], [np.eye(2)])
>>> ds.check_stability().stable
True
"""

from steer_envs.baselines.lpv_ds.lpvds import LPVDS, StabilityReport, benchmark_fit_time, velocities_from_positions
from steer_envs.baselines.lpv_ds.ltl_ds import (
    AttractorRule,
    LTLDSPolicy,
    ModeDynamics,
    ModeEvent,
    fit_mode_dynamics,
    hold_beyond_cuts,
)

__all__ = [
    "LPVDS",
    "AttractorRule",
    "LTLDSPolicy",
    "ModeDynamics",
    "ModeEvent",
    "StabilityReport",
    "benchmark_fit_time",
    "fit_mode_dynamics",
    "hold_beyond_cuts",
    "velocities_from_positions",
]
