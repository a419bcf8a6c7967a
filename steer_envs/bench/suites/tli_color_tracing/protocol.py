"""One tli-color-tracing trial: LTL-DS from a single demonstration under the three replanning automata.

Thesis appendix "Robot Experiment 3: Color Tracing": a single demonstration
moves the end-effector through the tiles yellow, blue, green, orange, pink into
red; LTL-DS learns one DS per coloured mode and recombines them, without
retraining, under the replanning automata (a) every D mode re-enters at yellow,
(b) exits after yellow re-enter at blue, (c) a yellow exit continues at blue and
a blue exit at pink (:func:`steer_envs.ltl.specs.color_tracing`).

* **Demonstration** (:func:`~steer_envs.data.tli_demos.color_demonstration`):
  one scripted-expert episode (a wave through the tiles' centres).
* **Mode DSs** (:func:`~steer_envs.baselines.lpv_ds.task_policies.fit_tile_dynamics`):
  one LPV-DS per tile mode from its segment of the demonstration (attractor:
  the first state on the next tile, ``OVERSHOOT`` further along the crossing),
  fitted once per experiment and shared by every automaton; red reuses pink's.
* **D modes** (:class:`~steer_envs.baselines.lpv_ds.task_policies.ReentryFlow`):
  the demonstration never enters D, so the way back is not learned: a D mode's
  flow heads for the tile its automaton re-enters at, through the dark region
  only (:func:`~steer_envs.envs.color_tracing.reentry_target`: straight in when
  that crosses no other tile, else through a lane beside the row). This is our
  completion; the thesis's arm moves in 3D and does not say how it returned.
* **Policy**: :func:`~steer_envs.baselines.lpv_ds.task_policies.color_policy`,
  an :class:`~steer_envs.baselines.lpv_ds.ltl_ds.LTLDSPolicy` with the
  automaton's spec; ``modulation`` learns cuts from invariance failures
  (persisting across the trial's episodes). The automaton tells D1..D4 apart
  from the sensor history alone (the dark reading ``k`` is the same).
* **Pushes** (:func:`~steer_envs.data.pushes.tile_push_schedule`,
  :func:`~steer_envs.data.pushes.dark_push_target`): up to ``n_pushes`` per
  episode, each with its own trigger tile (distinct tiles before red, in
  random order) and dwell (uniform in ``[1, max_dwell]`` steps): the ``k``-th
  push fires once the end-effector has been ``dwell`` steps on its tile after
  the previous push, and moves it into D: to a random side of the row, ``|y|``
  uniform in ``[2.5, 6]``, ``x`` shifted by up to ``1.5``. So every D mode is
  pushed into; a trigger tile the automaton's route no longer visits (``(c)``
  skips green and orange after a blue exit) gives no push.
* **Outcome** per episode (:func:`~steer_envs.baselines.lpv_ds.episodes.color_episode`):
  success (red reached), replans (automaton-unexpected transitions: pushes and
  invariance failures), and per push: the D mode the env entered, the mode the
  automaton tracked, and the next tile entered, checked against the
  automaton's re-entry rule.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from steer_envs.baselines.lpv_ds.episodes import color_episode
from steer_envs.baselines.lpv_ds.task_policies import color_policy
from steer_envs.bench.suites.tli_color_tracing.params import ENV_ID, ColorTracingParams
from steer_envs.bench.trials import episode_means, reset_seed, trial_env
from steer_envs.core.validation import integer, one_of
from steer_envs.data.pushes import tile_push_schedule
from steer_envs.envs.color_tracing import AUTOMATA

__all__ = ["color_trial"]


def color_trial(seed: int, automaton: str, params: ColorTracingParams, *, record: bool = False) -> dict[str, Any]:
    """``params.n_episodes`` episodes without and with pushes under ``automaton``; JSON-able summaries."""
    one_of(automaton, "automaton", AUTOMATA, owner="color_trial")
    seed = integer(seed, "seed", low=0, owner="color_trial")
    n_episodes, max_dwell, max_steps = params.n_episodes, params.max_dwell, params.max_steps
    with trial_env(ENV_ID, automaton=automaton) as (_, base):
        policy = color_policy(seed, automaton, modulation=params.modulation, max_speed=base.max_speed, dt=base.dt)
        out: dict[str, Any] = {}
        for cond, k in (("clean", 0), ("push", params.n_pushes)):
            rng = np.random.default_rng([seed, 2020, k])
            episodes = []
            for i in range(n_episodes):
                schedule = tile_push_schedule(rng, k, max_dwell)
                start = reset_seed(seed, i, 7)
                episodes.append(color_episode(base, policy, automaton, start, schedule, rng, max_steps))
            out[cond] = _summary(episodes, record)
        out["num_cuts"] = policy.num_cuts
        return out


def _summary(episodes: Sequence[Mapping[str, Any]], record: bool) -> dict[str, Any]:
    pushes = [p for e in episodes for p in e["pushes"]]
    out: dict[str, Any] = episode_means(episodes, ("success", "steps", "replans", "failures", "violations"))
    out["n_pushes"] = len(pushes)
    out["reentry_ok"] = sum(p["reentered"] == p["expected"] for p in pushes)
    out["tracked_ok"] = sum(p["tracked"] == p["env_mode"] for p in pushes)
    out["push_log"] = [{k: p[k] for k in ("left", "env_mode", "tracked", "expected", "reentered")} for p in pushes]
    if record:
        out["figure"] = [{k: e[k] for k in ("trace", "pushes", "success")} for e in episodes[:3]]
    return out
