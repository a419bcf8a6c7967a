"""One tli-cooking trial: DS skills learned once per mode transition, run under four edited automata.

Thesis appendix "Generalization Results": two demonstrations add chicken and
broccoli to the pot in different orders; LTL-DS learns one LPV-DS per *mode
transition* and the skills are recombined, without retraining, by the edited
automata ``phi_cb``, ``phi_bc``, ``phi_c`` and ``phi_cc``
(:func:`steer_envs.ltl.specs.cooking`). The pieces live in the library:

* **Demonstrations**: :func:`~steer_envs.data.tli_demos.cooking_demonstrations`,
  the scripted expert, chicken first (``w y d g d``, the thesis's Fig. (c))
  and broccoli first (``w g d w y d``).
* **Skills and policy**: :func:`~steer_envs.baselines.lpv_ds.transition_ds.learned_skills`
  and :class:`~steer_envs.baselines.lpv_ds.transition_ds.TransitionDSPolicy`
  (with ``modulation``, cuts from invariance failures; they persist across episodes).
* **Episodes**: :func:`~steer_envs.baselines.lpv_ds.episodes.cooking_episode`.
  Outcome per automaton: ``phi_cb``/``phi_bc``: the goal ``d2`` (both foods in
  the pot); ``phi_c``: the goal ``d`` with chicken and without broccoli in the
  pot; ``phi_cc``: ``deliveries`` chicken deliveries within the horizon.
  *Invalid transitions* are automaton-unexpected mode changes not caused by a
  push (the policy's own); *replans* are all unexpected changes (pushes included).
* **Pushes**: :func:`~steer_envs.data.pushes.push_schedule`, ``n_pushes``
  displacements at distinct random steps in ``[1, push_window]``, uniform
  direction, length uniform in ``[0, magnitude]``.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from steer_envs.baselines.lpv_ds.episodes import cooking_episode
from steer_envs.baselines.lpv_ds.transition_ds import TransitionDSPolicy, learned_skills, skills_fingerprint
from steer_envs.bench.suites.tli_cooking.params import ENV_ID, VARIANTS, CookingParams
from steer_envs.bench.trials import episode_means, reset_seed, trial_env
from steer_envs.core.validation import integer, one_of
from steer_envs.data.pushes import push_schedule

__all__ = ["cooking_trial"]


def cooking_trial(seed: int, variant: str, params: CookingParams, *, record: bool = False) -> dict[str, Any]:
    """``params.n_starts`` episodes without and with pushes under automaton ``variant``; JSON-able aggregate."""
    from steer_envs.ltl.specs import cooking

    one_of(variant, "variant", VARIANTS, owner="cooking_trial")
    seed = integer(seed, "seed", low=0, owner="cooking_trial")
    horizon, deliveries = params.horizon, params.deliveries
    skills = learned_skills(seed)
    rng = np.random.default_rng([seed, 5077])
    results: dict[str, list[dict[str, Any]]] = {"clean": [], "push": []}
    with trial_env(ENV_ID) as (env, base):
        policy = TransitionDSPolicy(
            base.task, cooking(variant), skills, max_speed=base.max_speed, modulation=params.modulation
        )
        for i, cond in itertools.product(range(params.n_starts), ("clean", "push")):
            pushes = push_schedule(rng, params.n_pushes, params.push_window, params.magnitude) if cond == "push" else {}
            results[cond].append(
                cooking_episode(
                    env, policy, variant, reset_seed(seed, i, 31), pushes, horizon=horizon, deliveries=deliveries,
                    record=record and i == 0,
                )
            )  # fmt: skip
    out: dict[str, Any] = {"fingerprint": skills_fingerprint(skills), "skills": sorted("->".join(k) for k in skills)}
    for cond, eps in results.items():
        out[cond] = {
            **episode_means(eps, ("success", "invalid", "replans", "failures", "deliveries", "steps")),
            "stuck": int(sum(e["stuck_steps"] > 0 for e in eps)),
        }
        if record:
            out[cond]["figure"] = {k: eps[0][k] for k in ("trace", "pushes", "success", "mode_path", "deliveries")}
    out["num_cuts"] = policy.num_cuts
    if record:
        out["attractors"] = {"->".join(k): s.attractor.round(3).tolist() for k, s in skills.items()}
    return out
