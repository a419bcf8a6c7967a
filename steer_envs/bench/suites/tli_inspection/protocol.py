"""One tli-inspection trial: vanilla DS vs LTL-DS on InspectionLine-v0 under large pushes.

Thesis appendix "Robot Experiment 2: Inspection Line": a single LPV-DS
(*vanilla DS*) fitted to whole demonstrations is stable at the release
station, so after a large push it always reaches it, but it may skip the
inspection line; LTL-DS (one LPV-DS per mode, the two-mode automaton, cuts
from invariance failures) returns to the inspection entry and re-does the
inspection whenever the object is pushed off the line.

* **Demonstrations**: :func:`~steer_envs.data.tli_demos.inspection_demonstrations`,
  two scripted-expert episodes from the grasping region.
* **Methods**: ``vanilla-ds`` (:func:`~steer_envs.baselines.lpv_ds.task_policies.vanilla_ds`,
  an LPV-DS on the whole demonstrations, attractor at their mean end),
  ``ltl-ds`` and ``ltl-ds+mod``
  (:func:`~steer_envs.baselines.lpv_ds.task_policies.inspection_policy`, an
  :class:`~steer_envs.baselines.lpv_ds.ltl_ds.LTLDSPolicy` without / with cuts)
  under :func:`~steer_envs.baselines.lpv_ds.task_policies.inspection_spec`.
* **Pushes** (:func:`~steer_envs.data.pushes.track_pushes`): the ``k``-th
  push fires when the end-effector is on the track at
  ``x >= threshold_k`` (thresholds uniform in ``[-3, 2.5]``, the same for every
  method), with a uniform direction and a length uniform in
  ``[min_push, max_push]``; ``max_push = 0`` gives the unperturbed runs.
* **Outcome** (:func:`~steer_envs.baselines.lpv_ds.episodes.inspection_episode`):
  ``success`` = released after the inspection; ``uninspected`` =
  the episode ended at the release station with the object never inspected
  (the vanilla DS's attractor reached without the task); ``inspections`` =
  times the object was put on the line.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.baselines.lpv_ds.episodes import inspection_episode
from steer_envs.baselines.lpv_ds.task_policies import inspection_policy, vanilla_ds
from steer_envs.bench.suites.tli_inspection.params import ENV_ID, METHODS, InspectionParams
from steer_envs.bench.trials import episode_means, reset_seed, trial_env
from steer_envs.core.validation import integer, one_of
from steer_envs.data.pushes import track_pushes
from steer_envs.data.tli_demos import inspection_demonstrations

__all__ = ["inspection_trial"]


def inspection_trial(seed: int, method: str, params: InspectionParams, *, record: bool = False) -> dict[str, Any]:
    """``params.n_episodes`` episodes of ``method`` from the grasping region under the push rule; JSON-able means."""
    one_of(method, "method", METHODS, owner="inspection_trial")
    seed = integer(seed, "seed", low=0, owner="inspection_trial")
    with trial_env(ENV_ID) as (_, base):
        demos = inspection_demonstrations(seed)
        if method == "vanilla-ds":
            policy: Any = vanilla_ds(demos, base.dt, seed)
        else:
            policy = inspection_policy(demos, base, seed, modulation=method == "ltl-ds+mod")
        rng = np.random.default_rng([seed, 881])
        episodes: list[dict[str, Any]] = []
        for i in range(params.n_episodes):
            pushes = track_pushes(rng, params.n_pushes, params.min_push, params.max_push)  # drawn even when unused
            start = reset_seed(seed, i, 5)
            episodes.append(
                inspection_episode(base, policy, start, pushes if params.max_push > 0 else [], params.max_steps)
            )
    out: dict[str, Any] = episode_means(episodes, ("success", "uninspected", "inspections", "steps"))
    out["num_cuts"] = 0 if method == "vanilla-ds" else policy.num_cuts
    if record:
        out["figure"] = {"episodes": [{k: e[k] for k in ("trace", "pushes", "success")} for e in episodes[:4]]}
    return out
