"""One tli-arm-scoop trial: LTL-DS soup scooping on the Panda arm under random pushes.

Thesis appendix "Robot Experiment 1: Soup-Scooping": two demonstrations, one
DS per mode of the end effector, the soup-scooping automaton, cuts from
invariance failures and modulation; six subjects pushed the robot in 30 trials
and all succeeded.

* **Demonstrations** (:func:`scoop_demonstrations`): two scripted-expert
  episodes of ``ArmScoop-v0`` (reach, dip, sweep while turning the spoon up,
  lift, carry), states ``(y, z, pitch)``, the commanded velocities as actions.
* **Policy** (:func:`scoop_policy`): :class:`~steer_envs.baselines.lpv_ds.ltl_ds.LTLDSPolicy`
  with one LPV-DS per mode (``d`` reuses ``c``'s) under
  :func:`steer_envs.ltl.specs.soup_scoop` (public convention); ``ltl-ds`` runs
  the automaton and the DSs only, ``ltl-ds+mod`` also learns cuts from
  invariance failures (kept across the trial's episodes: the robot learns) and
  modulates by them.
* **Pushes** (:func:`push_plan`): per episode ``n_pushes`` pushes, the first
  while scooping, the second while carrying, any further in a random mode; the
  ``k``-th fires after the spoon has spent a random ``1..max_dwell`` steps in
  its mode (after the previous push), and moves ``(y, z, pitch)`` by a uniform
  direction times a length uniform in ``[0.5, 1]`` times :data:`PUSH_SCALE`.
  Pushes are drawn per episode from the seed, the same for both methods.
* **Outcome** per episode: success (beads delivered within ``max_steps``),
  invariance failures (unplanned mode changes not caused by a push), pushes
  that undid task progress (spilled the beads or lifted the spoon out empty),
  spills, steps.
* **Sampled flows** (:func:`sampled_exits`, the thesis's 3D modulation figure):
  the scoop DS integrated from pushed demonstration states, nominal and
  modulated by the cuts the trial learned: the share that leaves the scoop mode
  other than through its guard (empty, or through the bowl's side).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from steer_envs.baselines.lpv_ds.ltl_ds import LTLDSPolicy
from steer_envs.core.validation import integer, one_of
from steer_envs.envs.robosuite.arm_scoop import (
    BOWL_RADIUS,
    PITCH_HIGH,
    PITCH_LOW,
    SOUP_SURFACE,
    SOUP_Y,
    WORKSPACE,
    arm_scoop_task,
)
from steer_envs.wrappers.ds_modulation import CutSet, resolve_cuts

__all__ = [
    "ENV_ID",
    "METHODS",
    "PUSH_SCALE",
    "push_plan",
    "repeated_failures",
    "sampled_exits",
    "scoop_demonstrations",
    "scoop_episode",
    "scoop_policy",
    "scoop_trial",
]

ENV_ID = "steer_envs/ArmScoop-v0"
METHODS: tuple[str, ...] = ("ltl-ds", "ltl-ds+mod")
#: LPV-DS stability margin of the mode DSs
DS_EPS = 1.0
#: attractors sit this far past the mean guard crossing (state units)
OVERSHOOT = 0.01
#: speed bound of the DS velocity (norm over m/s, m/s, rad/s); dt * MAX_SPEED = 0.03 < CUT_MARGIN
MAX_SPEED = 0.6
#: radius (state units) around each attractor that every cut keeps inside
CUT_MARGIN = 0.05
#: a push's scale per axis (m, m, rad): a uniform direction times a length in [0.5, 1] times this
PUSH_SCALE = np.array([0.06, 0.04, 1.0])
#: modes the first pushes wait for: scooping, then carrying; further pushes pick any of a, b, c
PUSH_MODES = ("b", "c")
#: sampled flows: starts per trial, Euler step (s) and steps
SAMPLES, SAMPLE_DT, SAMPLE_STEPS = 400, 0.05, 300


@functools.lru_cache(maxsize=4)
def scoop_demonstrations(seed: int, n_demos: int = 2) -> tuple[Any, ...]:
    """The ``n_demos`` expert demonstrations of experiment ``seed`` (cached)."""
    from steer_envs.data.demos import collect_demonstrations

    seed = integer(seed, "seed", low=0, owner="scoop_demonstrations")
    n_demos = integer(n_demos, "n_demos", low=1, owner="scoop_demonstrations")
    return tuple(collect_demonstrations(ENV_ID, n_demos, seed=1000 * seed))


def scoop_policy(seed: int, *, modulation: bool, n_demos: int = 2) -> LTLDSPolicy:
    """LTL-DS fitted on experiment ``seed``'s demonstrations (with or without learning cuts)."""
    from steer_envs.ltl.specs import soup_scoop

    return LTLDSPolicy.fit(
        list(scoop_demonstrations(seed, n_demos)), arm_scoop_task(), soup_scoop("public"), overshoot=OVERSHOOT,
        random_state=seed, ds_options={"eps": DS_EPS}, modulation=modulation, max_speed=MAX_SPEED,
        margin=CUT_MARGIN,
    )  # fmt: skip


def push_plan(rng: np.random.Generator, n_pushes: int, max_dwell: int) -> list[tuple[str, int, np.ndarray]]:
    """``n_pushes`` ``(trigger mode, dwell steps, delta (y, z, pitch))`` (see the module docstring)."""
    n = integer(n_pushes, "n_pushes", low=0, owner="push_plan")
    max_dwell = integer(max_dwell, "max_dwell", low=1, owner="push_plan")
    plan = []
    for k in range(n):
        mode = PUSH_MODES[k] if k < len(PUSH_MODES) else str(rng.choice(["a", "b", "c"]))
        direction = rng.normal(size=3)
        direction /= max(float(np.linalg.norm(direction)), 1e-12)
        delta = direction * rng.uniform(0.5, 1.0) * PUSH_SCALE
        plan.append((mode, int(rng.integers(1, max_dwell + 1)), delta))
    return plan


def scoop_episode(
    base: Any, policy: LTLDSPolicy, reset_seed: int, pushes: Sequence[tuple[str, int, np.ndarray]], max_steps: int
) -> dict[str, Any]:
    """One episode of ``policy`` on the unwrapped env ``base`` with the pushes of :func:`push_plan`."""
    obs, info = base.reset(seed=reset_seed)
    policy.reset(obs, info)
    pending = list(pushes)
    trace = [[base.state.tolist()]]
    push_log: list[dict[str, Any]] = []
    spills = steps = dwell = 0
    for steps in range(1, max_steps + 1):  # noqa: B007
        mode = str(info["mode_name"])
        dwell = dwell + 1 if pending and mode == pending[0][0] else 0
        if pending and dwell >= pending[0][1]:
            _, _, delta = pending.pop(0)
            dwell = 0
            policy.observe(obs, info)  # the reading before the push
            x = base.state
            info = base.perturb(delta=delta)
            obs = base.state.astype(np.float32)
            push_log.append({"from": x.tolist(), "to": base.state.tolist(), "mode": mode,
                             "after": str(info["mode_name"])})  # fmt: skip
            trace.append([base.state.tolist()])
        action = policy.act(obs, info)
        obs, _, _, _, info = base.step(action)
        trace[-1].append(base.state.tolist())
        spills += bool(info["constraint_violation"])
        if info["success"]:
            break
    policy.observe(obs, info)
    order = arm_scoop_task().modes
    failures = [e for e in policy.events if e.kind == "failure"]
    return {
        "success": bool(info["success"]),
        "steps": steps,
        "failures": len(failures),
        "failure_states": [e.before.round(4).tolist() for e in failures],
        "failure_modes": [f"{e.source}->{e.target}" for e in failures],
        "task_pushes": sum(order.index(p["after"]) < order.index(p["mode"]) for p in push_log),
        "spills": spills,
        "pushes": push_log,
        "trace": [np.round(np.asarray(s), 4).tolist() for s in trace],
    }


def _in_soup(x: np.ndarray) -> np.ndarray:
    """The scoop mode's region in state space (the bowl's y extent below the surface; x is held on the axis)."""
    return (np.abs(x[:, 0] - SOUP_Y) <= BOWL_RADIUS) & (x[:, 1] <= SOUP_SURFACE)


def sampled_exits(
    policy: LTLDSPolicy, seed: int, *, modulated: bool, n: int = SAMPLES, keep: int = 0
) -> tuple[float, list[list[list[float]]]]:
    """Share of scoop-DS flows from pushed demonstration states that exit the scoop mode wrongly; ``keep`` traces.

    Starts: scoop states of the demonstrations pushed as in the trials (kept
    when still in the soup). A flow exits *wrongly* when it leaves the soup
    other than upward with the pitch in the holding range. ``modulated`` uses
    the policy's cuts (its ``flow`` with modulation on), else the nominal DS.
    """
    rng = np.random.default_rng([seed, 31])
    states = np.concatenate([np.asarray(d.states)[np.asarray(d.modes) == 1] for d in scoop_demonstrations(seed)])
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    x = states[rng.integers(len(states), size=n)] + direction * rng.uniform(0.5, 1.0, (n, 1)) * PUSH_SCALE
    x = np.clip(x[_in_soup(x)], WORKSPACE[0], WORKSPACE[1])
    if len(x) == 0:
        return 0.0, []
    traces = [[row.tolist()] for row in x[:keep]]
    alive = np.ones(len(x), dtype=bool)
    wrong = np.zeros(len(x), dtype=bool)
    saved = policy.modulation
    policy.modulation = modulated
    try:
        for _ in range(SAMPLE_STEPS):
            if not alive.any():
                break
            idx = np.nonzero(alive)[0]
            x[idx] = np.clip(x[idx] + SAMPLE_DT * policy.flow(x[idx], "b"), WORKSPACE[0], WORKSPACE[1])
            for i in idx[idx < keep]:
                traces[i].append(x[i].tolist())
            out = alive & ~_in_soup(x)
            good = (x[:, 1] > SOUP_SURFACE) & (x[:, 2] >= PITCH_LOW) & (x[:, 2] <= PITCH_HIGH)
            wrong |= out & ~good
            alive &= ~out
    finally:
        policy.modulation = saved
    return float(wrong.mean()), [np.round(np.asarray(t), 4).tolist() for t in traces]


def repeated_failures(policy: LTLDSPolicy) -> int:
    """Invariance failures that crossed a cut learned from the earlier failures of their mode.

    The cuts are re-solved from the failures recorded before each one (what
    ``ltl-ds+mod`` had at that moment; for ``ltl-ds`` what it would have had):
    a failure whose last in-mode state was inside those cuts and whose failure
    state lies beyond one of them is a failure experienced again. With
    modulation the thesis's guarantee says there are none.
    """
    repeats = 0
    for mode, records in policy.failures.items():
        attractor = policy.dynamics[mode].attractor
        for k in range(1, len(records)):
            try:
                cuts = CutSet(attractor, resolve_cuts(records[:k], attractor, policy.margin))
            except ValueError:
                continue  # no cut for an earlier failure (the policy skipped it too)
            last, fail = records[k].last_in_mode[None], records[k].failure[None]
            repeats += bool(cuts.inside(last)[0] and not cuts.inside(fail)[0])
    return repeats


def scoop_trial(
    seed: int,
    method: str,
    *,
    n_episodes: int = 30,
    n_pushes: int = 3,
    max_dwell: int = 20,
    max_steps: int = 600,
    record: bool = False,
) -> dict[str, Any]:
    """``n_episodes`` pushed episodes of ``method``; JSON-able means (and figure data with ``record``)."""
    import gymnasium as gym

    import steer_envs  # noqa: F401 - registers the ids in a fresh worker

    owner = "scoop_trial"
    seed = integer(seed, "seed", low=0, owner=owner)
    one_of(method, "method", METHODS, owner=owner)
    n_episodes = integer(n_episodes, "n_episodes", low=1, owner=owner)
    n_pushes = integer(n_pushes, "n_pushes", low=0, owner=owner)
    max_dwell = integer(max_dwell, "max_dwell", low=1, owner=owner)
    max_steps = integer(max_steps, "max_steps", low=1, owner=owner)
    env = gym.make(ENV_ID)
    base: Any = env.unwrapped
    try:
        policy = scoop_policy(seed, modulation=method == "ltl-ds+mod")
        episodes = []
        for i in range(n_episodes):
            reset_seed = int(np.random.SeedSequence([seed, i, 11]).generate_state(1)[0] % 2**31)
            plan = push_plan(np.random.default_rng([seed, i, 99]), n_pushes, max_dwell)
            episodes.append(scoop_episode(base, policy, reset_seed, plan, max_steps))
    finally:
        env.close()
    out: dict[str, Any] = {
        k: float(np.mean([float(e[k]) for e in episodes])) for k in ("success", "steps", "failures", "task_pushes",
                                                                       "spills")
    }  # fmt: skip
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
