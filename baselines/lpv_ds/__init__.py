"""Stable dynamical systems from demonstrations (thesis ch. 3): LPV-DS, cuts, modulation and LTL-DS.

* :mod:`.lpvds` -- :class:`LPVDS`, a globally asymptotically stable
  linear-parameter-varying DS fitted by convex programs, and its numerical
  stability check (:meth:`LPVDS.check_stability` -> :class:`StabilityReport`);
* :mod:`.cuts` -- :class:`Cut`, :class:`CutSet`: the half-spaces learned from
  invariance failures (:func:`solve_cut`, the thesis's QCQP; :func:`resolve_cuts`);
* :mod:`.modulation` -- :func:`modulate`, :class:`ModulatedPolicy`: a velocity
  field bent so that it never crosses the cuts;
* :mod:`.ltl_ds` -- :class:`LTLDSPolicy`: one LPV-DS per mode
  (:func:`fit_mode_dynamics`), sequenced by the task automaton and bounded by
  cuts learned from invariance failures;
* :mod:`.transition_ds` -- :class:`TransitionDSPolicy`: one LPV-DS per mode
  *transition* (:func:`fit_skills`), recombined by edited automata;
* :mod:`.single_mode` -- the single-mode study's fit, start states, rollout
  and cut loop (:func:`fitted_policy`, :func:`rollout`, :func:`cut_loop`);
* :mod:`.task_policies` -- the LTL-DS policies of the thesis's tasks
  (soup scooping, the arm, colour tracing with :class:`ReentryFlow`, the
  inspection line) fitted from their demonstrations;
* :mod:`.episodes` -- pushed episodes of those tasks.

Names are imported lazily, so ``from steer_envs.baselines.lpv_ds import Cut``
does not pay for cvxpy and scikit-learn (the LPV-DS fit).

>>> import numpy as np
>>> from steer_envs.baselines.lpv_ds import LPVDS
>>> ds = LPVDS.from_parameters(np.zeros(2), np.eye(2), [-np.eye(2)], [1.0], [np.zeros(2)], [np.eye(2)])
>>> ds.check_stability().stable
True
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from steer_envs.core.lazy import lazy_exports

if TYPE_CHECKING:
    from steer_envs.baselines.lpv_ds.cuts import (
        ATTRACTOR_MARGIN,
        Cut,
        CutSet,
        FailureRecord,
        resolve_cuts,
        solve_cut,
    )
    from steer_envs.baselines.lpv_ds.episodes import (
        arm_scoop_episode,
        color_episode,
        cooking_episode,
        inspection_episode,
        sampled_exits,
        soup_scoop_episode,
    )
    from steer_envs.baselines.lpv_ds.lpvds import (
        LPVDS,
        StabilityReport,
        benchmark_fit_time,
        velocities_from_positions,
    )
    from steer_envs.baselines.lpv_ds.ltl_ds import (
        AttractorRule,
        LTLDSPolicy,
        ModeDynamics,
        ModeEvent,
        fit_mode_dynamics,
        repeated_failures,
    )
    from steer_envs.baselines.lpv_ds.modulation import (
        ModulatedPolicy,
        clip_speed,
        gamma,
        hold_beyond_cuts,
        modulate,
        modulation_matrix,
    )
    from steer_envs.baselines.lpv_ds.single_mode import (
        CutLoopResult,
        cut_loop,
        fitted_policy,
        rollout,
        sample_starts,
    )
    from steer_envs.baselines.lpv_ds.task_policies import (
        ReentryFlow,
        arm_scoop_policy,
        color_policy,
        fit_tile_dynamics,
        inspection_policy,
        inspection_spec,
        soup_scoop_policy,
        vanilla_ds,
    )
    from steer_envs.baselines.lpv_ds.transition_ds import (
        Skill,
        TransitionDSPolicy,
        fit_skills,
        learned_skills,
        skills_fingerprint,
        spoon_letters,
    )

_EXPORTS: dict[str, str] = {
    "LPVDS": "lpvds",
    "StabilityReport": "lpvds",
    "benchmark_fit_time": "lpvds",
    "velocities_from_positions": "lpvds",
    "ATTRACTOR_MARGIN": "cuts",
    "Cut": "cuts",
    "CutSet": "cuts",
    "FailureRecord": "cuts",
    "resolve_cuts": "cuts",
    "solve_cut": "cuts",
    "ModulatedPolicy": "modulation",
    "clip_speed": "modulation",
    "gamma": "modulation",
    "hold_beyond_cuts": "modulation",
    "modulate": "modulation",
    "modulation_matrix": "modulation",
    "AttractorRule": "ltl_ds",
    "LTLDSPolicy": "ltl_ds",
    "ModeDynamics": "ltl_ds",
    "ModeEvent": "ltl_ds",
    "fit_mode_dynamics": "ltl_ds",
    "repeated_failures": "ltl_ds",
    "Skill": "transition_ds",
    "TransitionDSPolicy": "transition_ds",
    "fit_skills": "transition_ds",
    "learned_skills": "transition_ds",
    "skills_fingerprint": "transition_ds",
    "spoon_letters": "transition_ds",
    "CutLoopResult": "single_mode",
    "cut_loop": "single_mode",
    "fitted_policy": "single_mode",
    "rollout": "single_mode",
    "sample_starts": "single_mode",
    "ReentryFlow": "task_policies",
    "arm_scoop_policy": "task_policies",
    "color_policy": "task_policies",
    "fit_tile_dynamics": "task_policies",
    "inspection_policy": "task_policies",
    "inspection_spec": "task_policies",
    "soup_scoop_policy": "task_policies",
    "vanilla_ds": "task_policies",
    "arm_scoop_episode": "episodes",
    "color_episode": "episodes",
    "cooking_episode": "episodes",
    "inspection_episode": "episodes",
    "sampled_exits": "episodes",
    "soup_scoop_episode": "episodes",
}

__all__ = [
    "ATTRACTOR_MARGIN",
    "LPVDS",
    "AttractorRule",
    "Cut",
    "CutLoopResult",
    "CutSet",
    "FailureRecord",
    "LTLDSPolicy",
    "ModeDynamics",
    "ModeEvent",
    "ModulatedPolicy",
    "ReentryFlow",
    "Skill",
    "StabilityReport",
    "TransitionDSPolicy",
    "arm_scoop_episode",
    "arm_scoop_policy",
    "benchmark_fit_time",
    "clip_speed",
    "color_episode",
    "color_policy",
    "cooking_episode",
    "cut_loop",
    "fit_mode_dynamics",
    "fit_skills",
    "fit_tile_dynamics",
    "fitted_policy",
    "gamma",
    "hold_beyond_cuts",
    "inspection_episode",
    "inspection_policy",
    "inspection_spec",
    "learned_skills",
    "modulate",
    "modulation_matrix",
    "repeated_failures",
    "resolve_cuts",
    "rollout",
    "sample_starts",
    "sampled_exits",
    "skills_fingerprint",
    "solve_cut",
    "soup_scoop_episode",
    "soup_scoop_policy",
    "spoon_letters",
    "vanilla_ds",
    "velocities_from_positions",
]


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
