"""Pushed episodes of the TLI tasks: run an LTL-DS policy on an env while a push schedule perturbs it.

Each runner resets the env, lets the policy act until success (or a step cap),
applies the pushes of a schedule from :mod:`steer_envs.data.pushes` through
``env.unwrapped.perturb`` (the policy sees the reading before and after each
push, so a push is never taken for an invariance failure) and returns a
JSON-able outcome:

* :func:`soup_scoop_episode` -- SoupScoop-v0, pushes at scheduled steps;
* :func:`cooking_episode` -- Cooking-v0 under an edited automaton, pushes at scheduled steps;
* :func:`color_episode` -- ColorTracing-v0, pushes into the dark region after a dwell on a trigger tile;
* :func:`arm_scoop_episode` -- ArmScoop-v0, pushes after a dwell in a trigger mode;
* :func:`inspection_episode` -- InspectionLine-v0, pushes once the object passes a point of the track.

:func:`sampled_exits` integrates ArmScoop's scoop DS from pushed demonstration
states (the thesis's 3D modulation figure).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from steer_envs.baselines.lpv_ds.ltl_ds import LTLDSPolicy
from steer_envs.baselines.lpv_ds.transition_ds import TransitionDSPolicy
from steer_envs.data.pushes import ARM_PUSH_SCALE, dark_push_target
from steer_envs.data.tli_demos import arm_scoop_demonstrations
from steer_envs.envs.color_tracing import REENTRY, TILES
from steer_envs.envs.robosuite.arm_scoop import (
    BOWL_RADIUS,
    PITCH_HIGH,
    PITCH_LOW,
    SOUP_SURFACE,
    SOUP_Y,
    WORKSPACE,
    arm_scoop_task,
)

__all__ = [
    "arm_scoop_episode",
    "color_episode",
    "cooking_episode",
    "inspection_episode",
    "sampled_exits",
    "soup_scoop_episode",
]

#: InspectionLine: an episode that rests this slowly (units/s) inside the release station has converged
REST_SPEED = 0.05
#: ArmScoop sampled flows: starts per trial, Euler step (s) and steps
SAMPLES, SAMPLE_DT, SAMPLE_STEPS = 400, 0.05, 300


def soup_scoop_episode(
    env: Any, policy: Any, seed: int, schedule: list[tuple[int, np.ndarray]], max_steps: int, record: bool
) -> dict[str, Any]:
    """One SoupScoop episode with the push schedule; success, steps, applied pushes, the trajectory, first mode.

    The trajectory is a list of segments split at pushes (a push is a jump, not motion).
    """
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info)
    first_mode = policy.mode
    base = env.unwrapped
    pushes = dict(schedule)
    push_log: list[dict[str, Any]] = []
    traj: list[list[list[float]]] = [[base.state.tolist()]]  # segments between pushes
    success = bool(info["success"])
    steps = 0
    while not success and steps < max_steps:
        if steps in pushes:
            before = base.state
            info = base.perturb(pushes[steps])
            obs = base.state.astype(np.float32)
            push_log.append({"step": steps, "from": before.tolist(), "to": base.state.tolist()})
            success = bool(info["success"])
            if record:
                traj.append([base.state.tolist()])  # a push is a jump, not motion: new segment
            if success:
                break
        action = policy.act(obs, info)
        obs, _, terminated, truncated, info = env.step(action)
        steps += 1
        success = bool(info["success"])
        if record:
            traj[-1].append(base.state.tolist())
        if terminated or truncated:
            break
    if success:  # let the policy see the final transition (into the goal mode)
        policy.observe(obs, info)
    return {"success": success, "steps": steps, "push_log": push_log, "trajectory": traj, "first_mode": first_mode}


def _cooking_success(variant: str, policy: TransitionDSPolicy, info: Mapping[str, Any], delivered: int,
                     deliveries: int) -> bool:  # fmt: skip
    """Cooking's goal under ``variant``: both foods in the pot, chicken only, or ``deliveries`` deliveries."""
    s = info["sensors"]
    if variant in ("phi_cb", "phi_bc"):
        return bool(info["success"] and policy.mode == "d2")
    if variant == "phi_c":
        return bool(policy.mode == "d" and s["ch"] and not s["br"])
    return delivered >= deliveries


def cooking_episode(
    env: Any,
    policy: TransitionDSPolicy,
    variant: str,
    start_seed: int,
    pushes: Mapping[int, np.ndarray],
    *,
    horizon: int,
    deliveries: int,
    record: bool = False,
) -> dict[str, Any]:
    """One episode on the unwrapped Cooking env under automaton ``variant`` with pushes ``step -> delta``.

    Success: ``phi_cb``/``phi_bc`` the goal ``d2`` (both foods in the pot); ``phi_c`` the goal ``d`` with
    chicken and without broccoli in the pot; ``phi_cc`` ``deliveries`` chicken deliveries (a ``hc -> p``
    sensor change) within ``horizon``. Also the policy's counts (invalid transitions, replans, failures).
    """
    base = env.unwrapped
    obs, info = base.reset(seed=start_seed)
    policy.reset(obs, info)
    delivered, steps, success = 0, 0, False
    holding = bool(info["sensors"]["hc"])
    trace: list[list[list[float]]] = [[base.state.tolist()]]
    push_log: list[dict[str, Any]] = []
    for steps in range(1, horizon + 1):
        if steps in pushes:
            before = base.state
            info = base.perturb(delta=pushes[steps])
            obs = base.state.astype(np.float32)
            push_log.append({"step": steps, "from": before.tolist(), "to": base.state.tolist()})
            if record:
                trace.append([base.state.tolist()])
            policy.observe(obs, info)
            holding = bool(info["sensors"]["hc"])
        obs, _, _, _, info = base.step(policy.act(obs, info))
        if record:
            trace[-1].append(base.state.tolist())
        s = info["sensors"]
        delivered += holding and s["p"]
        holding = bool(s["hc"])
        policy.observe(obs, info)
        success = _cooking_success(variant, policy, info, delivered, deliveries)
        if success or (info["success"] and variant in ("phi_c", "phi_cc")):
            break  # done, or the broccoli went into the pot (the env's goal absorbs: the task cannot recover)
    out: dict[str, Any] = {
        "success": bool(success),
        "steps": steps,
        "invalid": policy.invalid,
        "replans": policy.replans,
        "failures": policy.failures,
        "stuck_steps": policy.stuck_steps,
        "deliveries": delivered,
        "mode_path": policy.mode_path,
    }
    if record:
        out["trace"] = [np.round(np.asarray(seg), 3).tolist() for seg in trace]
        out["pushes"] = push_log
    return out


def color_episode(
    base: Any, policy: LTLDSPolicy, automaton: str, reset_seed: int, pushes: list[tuple[str, int]],
    rng: np.random.Generator,
    max_steps: int,
) -> dict[str, Any]:  # fmt: skip
    """One ColorTracing episode on the unwrapped env ``base`` with ``(tile, dwell)`` pushes into the dark region.

    Per push: the tile left, the dark mode the env entered, the mode the policy tracked, the tile the
    automaton's re-entry rule expects (``REENTRY``) and the next tile entered.
    """
    obs, info = base.reset(seed=reset_seed)
    policy.reset(obs, info)
    pending = list(pushes)
    trace = [[base.state.tolist()]]
    push_log: list[dict[str, Any]] = []
    modes = [str(info["mode_name"])]
    violations = 0
    open_push: dict[str, Any] | None = None
    steps = dwell = 0
    for steps in range(1, max_steps + 1):  # noqa: B007
        mode = str(info["mode_name"])
        dwell = dwell + 1 if pending and mode == pending[0][0] else 0
        if pending and dwell >= pending[0][1]:
            pending.pop(0)
            dwell = 0
            policy.observe(obs, info)  # the reading before the push (the policy has not acted on it yet)
            x = base.state
            info = base.perturb(to=dark_push_target(rng, x))
            obs = base.state.astype(np.float32)
            tracked = policy.observe(obs, info)
            open_push = {"from": x.tolist(), "to": base.state.tolist(), "left": mode, "env_mode": info["mode_name"],
                         "tracked": tracked, "expected": REENTRY[automaton].get(str(info["mode_name"])),
                         "reentered": None}  # fmt: skip
            push_log.append(open_push)
            trace.append([base.state.tolist()])
        obs, _, _, _, info = base.step(policy.act(obs, info))
        trace[-1].append(base.state.tolist())
        violations += bool(info["constraint_violation"])
        name = str(info["mode_name"])
        if name != modes[-1]:
            modes.append(name)
            if open_push is not None and name in TILES:
                open_push["reentered"] = name
                open_push = None
        if info["success"]:
            break
    policy.observe(obs, info)
    out = {"success": bool(info["success"]), "steps": steps, **_event_counts(policy), "violations": violations}
    return {**out, "pushes": push_log, "modes": modes, "trace": [np.round(np.asarray(s), 3).tolist() for s in trace]}


def _event_counts(policy: LTLDSPolicy) -> dict[str, Any]:
    """Replans (mode changes off the plan: pushes and failures), failures and each failure's transition and state."""
    kinds = [e.kind for e in policy.events]
    return {
        "replans": kinds.count("push") + kinds.count("failure"),
        "failures": kinds.count("failure"),
        "failure_events": [
            (e.source, e.target, e.before.round(2).tolist()) for e in policy.events if e.kind == "failure"
        ],
    }


def arm_scoop_episode(
    base: Any, policy: LTLDSPolicy, reset_seed: int, pushes: Sequence[tuple[str, int, np.ndarray]], max_steps: int
) -> dict[str, Any]:
    """One ArmScoop episode on the unwrapped env ``base`` with the ``(mode, dwell, delta)`` pushes of a push plan.

    ``task_pushes`` counts pushes that undid task progress (spilled the beads or lifted the spoon out empty).
    """
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
        obs, _, _, _, info = base.step(policy.act(obs, info))
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


def inspection_episode(
    base: Any, policy: Any, reset_seed: int, pushes: list[tuple[float, np.ndarray]], max_steps: int
) -> dict[str, Any]:
    """One InspectionLine episode on the unwrapped env ``base``.

    ``policy`` is an :class:`~steer_envs.baselines.lpv_ds.ltl_ds.LTLDSPolicy` or a plain velocity field
    ``(N, 2) -> (N, 2)`` (the vanilla DS). The ``k``-th push ``(threshold, delta)`` fires when the object is
    on the track at ``x >= threshold``. Outcome: ``success`` (released after the inspection),
    ``uninspected`` (ended at the release station with the object never inspected), ``inspections``
    (times the object was put on the line), ``steps``, ``trace``, ``pushes``.
    """
    obs, info = base.reset(seed=reset_seed)
    ltl = isinstance(policy, LTLDSPolicy)
    if ltl:
        policy.reset(obs, info)
    inspections = int(info["sensors"]["l"])
    was_on = bool(info["sensors"]["l"])
    trace = [[base.state.tolist()]]
    push_log = []
    uninspected = False
    steps = 0
    pending = list(pushes)
    for steps in range(1, max_steps + 1):  # noqa: B007
        x = base.state
        rx0, ry0, rx1, ry1 = base.model.rects["track"]
        if pending and rx0 <= x[0] <= rx1 and ry0 <= x[1] <= ry1 and x[0] >= pending[0][0]:
            info = base.perturb(delta=pending.pop(0)[1])
            obs = base.state.astype(np.float32)
            push_log.append({"from": x.tolist(), "to": base.state.tolist()})
            trace.append([base.state.tolist()])
        action = policy.act(obs, info) if ltl else policy(obs[None].astype(np.float64))[0]
        obs, _, _, _, info = base.step(np.asarray(action, dtype=np.float32))
        trace[-1].append(base.state.tolist())
        on = bool(info["sensors"]["l"])
        inspections += on and not was_on
        was_on = on
        if info["success"]:
            break
        speed = float(np.linalg.norm(np.clip(action, -1e6, 1e6)))
        if info["sensors"]["r"] and not on and speed < REST_SPEED:
            uninspected = True  # converged at the station with an uninspected object
            break
    at_station = bool(info["sensors"]["r"])
    return {
        "success": bool(info["success"]),
        "uninspected": uninspected or (at_station and not info["success"]),
        "inspections": inspections,
        "steps": steps,
        "trace": [np.round(np.asarray(s), 3).tolist() for s in trace],
        "pushes": push_log,
    }


def _in_soup(x: np.ndarray) -> np.ndarray:
    """ArmScoop's scoop-mode region in state space (the bowl's y extent below the surface; x is held on the axis)."""
    return (np.abs(x[:, 0] - SOUP_Y) <= BOWL_RADIUS) & (x[:, 1] <= SOUP_SURFACE)


def sampled_exits(
    policy: LTLDSPolicy, seed: int, *, modulated: bool, n: int = SAMPLES, keep: int = 0
) -> tuple[float, list[list[list[float]]]]:
    """Share of ArmScoop scoop-DS flows from pushed demonstration states that exit the scoop mode wrongly.

    Starts: scoop states of experiment ``seed``'s demonstrations pushed as in the
    trials (kept when still in the soup). A flow exits *wrongly* when it leaves
    the soup other than upward with the pitch in the holding range. ``modulated``
    uses the policy's cuts (its ``flow`` with modulation on), else the nominal
    DS. Also returns the first ``keep`` traces.
    """
    rng = np.random.default_rng([seed, 31])
    demos = arm_scoop_demonstrations(seed)
    states = np.concatenate([np.asarray(d.states)[np.asarray(d.modes) == 1] for d in demos])
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    x = states[rng.integers(len(states), size=n)] + direction * rng.uniform(0.5, 1.0, (n, 1)) * ARM_PUSH_SCALE
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
