"""One tli-arm-scoop trial: LTL-DS soup scooping on the Panda arm under random pushes.

Thesis appendix "Robot Experiment 1: Soup-Scooping": two demonstrations, one
DS per mode of the end effector, the soup-scooping automaton, cuts from
invariance failures and modulation; six subjects pushed the robot in 30 trials
and all succeeded. The pieces live in the library:

* **Demonstrations**: :func:`~steer_envs.data.tli_demos.arm_scoop_demonstrations`,
  two scripted-expert episodes of ``ArmScoop-v0`` (reach, dip, sweep while
  turning the spoon up, lift, carry), states ``(y, z, pitch)``, the commanded
  velocities as actions.
* **Policy**: :func:`~steer_envs.baselines.lpv_ds.task_policies.arm_scoop_policy`,
  an :class:`~steer_envs.baselines.lpv_ds.ltl_ds.LTLDSPolicy` with one LPV-DS
  per mode (``d`` reuses ``c``'s) under :func:`steer_envs.ltl.specs.soup_scoop`
  (public convention); ``ltl-ds`` runs the automaton and the DSs only,
  ``ltl-ds+mod`` also learns cuts from invariance failures (kept across the
  trial's episodes: the robot learns) and modulates by them.
* **Pushes**: :func:`~steer_envs.data.pushes.push_plan`, per episode
  ``n_pushes`` pushes, the first while scooping, the second while carrying, any
  further in a random mode; the ``k``-th fires after the spoon has spent a
  random ``1..max_dwell`` steps in its mode (after the previous push), and
  moves ``(y, z, pitch)`` by a uniform direction times a length uniform in
  ``[0.5, 1]`` times :data:`~steer_envs.data.pushes.ARM_PUSH_SCALE`. Pushes are
  drawn per episode from the seed, the same for both methods.
* **Outcome** per episode (:func:`~steer_envs.baselines.lpv_ds.episodes.arm_scoop_episode`):
  success (beads delivered within ``max_steps``), invariance failures
  (unplanned mode changes not caused by a push), pushes that undid task
  progress (spilled the beads or lifted the spoon out empty), spills, steps;
  per trial the failures experienced again
  (:func:`~steer_envs.baselines.lpv_ds.ltl_ds.repeated_failures`).
* **Sampled flows** (:func:`~steer_envs.baselines.lpv_ds.episodes.sampled_exits`,
  the thesis's 3D modulation figure): the scoop DS integrated from pushed
  demonstration states, nominal and modulated by the cuts the trial learned:
  the share that leaves the scoop mode other than through its guard (empty,
  or through the bowl's side).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from steer_envs.baselines.lpv_ds.episodes import arm_scoop_episode, sampled_exits
from steer_envs.baselines.lpv_ds.ltl_ds import LTLDSPolicy, repeated_failures
from steer_envs.baselines.lpv_ds.task_policies import arm_scoop_policy
from steer_envs.bench.suites.tli_arm_scoop.params import ENV_ID, METHODS, ArmScoopParams
from steer_envs.bench.trials import episode_means, reset_seed, trial_env
from steer_envs.core.validation import integer, one_of
from steer_envs.data.pushes import push_plan

__all__ = ["scoop_trial"]


def scoop_trial(seed: int, method: str, params: ArmScoopParams, *, record: bool = False) -> dict[str, Any]:
    """``params.n_episodes`` pushed episodes of ``method``; JSON-able means (and figure data with ``record``)."""
    one_of(method, "method", METHODS, owner="scoop_trial")
    seed = integer(seed, "seed", low=0, owner="scoop_trial")
    with trial_env(ENV_ID) as (_, base):
        policy = arm_scoop_policy(seed, modulation=method == "ltl-ds+mod")
        episodes = []
        for i in range(params.n_episodes):
            plan = push_plan(np.random.default_rng([seed, i, 99]), params.n_pushes, params.max_dwell)
            episodes.append(arm_scoop_episode(base, policy, reset_seed(seed, i, 11), plan, params.max_steps))
    out: dict[str, Any] = episode_means(episodes, ("success", "steps", "failures", "task_pushes", "spills"))
    undone = [e for e in episodes if e["task_pushes"] > 0]
    out["undone_episodes"] = len(undone)
    out["recovered"] = sum(e["success"] for e in undone)
    out["num_cuts"] = policy.num_cuts
    out["repeats"] = repeated_failures(policy)
    out["failure_modes"] = [m for e in episodes for m in e["failure_modes"]]
    nominal, nominal_traces = sampled_exits(policy, seed, modulated=False, keep=12 if record else 0)
    modulated, modulated_traces = sampled_exits(policy, seed, modulated=True, keep=12 if record else 0)
    out["sampled_exits_nominal"], out["sampled_exits_modulated"] = nominal, modulated
    if record:
        out["figure"] = _figure_data(policy, episodes, nominal_traces, modulated_traces)
    return out


def _figure_data(
    policy: LTLDSPolicy, episodes: Sequence[Mapping[str, Any]], nominal: Any, modulated: Any
) -> dict[str, Any]:
    """What the 3D figure draws: the scoop mode's cuts and attractor, sampled flows, arm traces and failures."""
    cuts = [
        {"point": c.point.round(5).tolist(), "normal": c.normal.round(5).tolist()} for c in policy.cut_sets["b"].cuts
    ]
    shown = sorted(range(len(episodes)), key=lambda i: -episodes[i]["failures"])[:3]
    return {
        "attractor": policy.dynamics["b"].attractor.round(5).tolist(),
        "cuts": cuts,
        "sampled_nominal": nominal,
        "sampled_modulated": modulated,
        "episodes": [{k: episodes[i][k] for k in ("trace", "success", "failure_states")} for i in shown],
        "failure_states": [s for e in episodes for s in e["failure_states"]],
    }
