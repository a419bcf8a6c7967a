"""One tli-color-tracing trial: LTL-DS from a single demonstration under the three replanning automata.

Thesis appendix "Robot Experiment 3: Color Tracing": a single demonstration
moves the end-effector through the tiles yellow, blue, green, orange, pink into
red; LTL-DS learns one DS per coloured mode and recombines them, without
retraining, under the replanning automata (a) every D mode re-enters at yellow,
(b) exits after yellow re-enter at blue, (c) a yellow exit continues at blue and
a blue exit at pink (:func:`steer_envs.ltl.specs.color_tracing`).

* **Demonstration** (:func:`color_demonstration`): one scripted-expert episode
  (a wave through the tiles' centres).
* **Mode DSs** (:func:`fit_tile_dynamics`): one LPV-DS per tile mode from its
  segment of the demonstration (attractor: the first state on the next tile,
  ``OVERSHOOT`` further along the crossing), fitted once per experiment and
  shared by every automaton; red reuses pink's.
* **D modes** (:class:`ReentryFlow`): the demonstration never enters D, so the
  way back is not learned: a D mode's flow heads for the tile its automaton
  re-enters at, through the dark region only
  (:func:`~steer_envs.envs.color_tracing.reentry_target`: straight in when
  that crosses no other tile, else through a lane beside the row). This is our
  completion; the thesis's arm moves in 3D and does not say how it returned.
* **Policy**: :class:`~steer_envs.baselines.lpv_ds.ltl_ds.LTLDSPolicy` with
  the automaton's spec; ``modulation`` learns cuts from invariance failures
  (persisting across the trial's episodes). The automaton tells D1..D4 apart
  from the sensor history alone (the dark reading ``k`` is the same).
* **Pushes** (:func:`push_schedule`): up to ``n_pushes`` per episode, each
  with its own trigger tile (distinct tiles before red, in random order) and
  dwell (uniform in ``[1, max_dwell]`` steps): the ``k``-th push fires once the
  end-effector has been ``dwell`` steps on its tile after the previous push,
  and moves it into D: to a random side of the row, ``|y|`` uniform in
  ``[2.5, 6]``, ``x`` shifted by up to ``1.5``. So every D mode is pushed
  into; a trigger tile the automaton's route no longer visits (``(c)`` skips
  green and orange after a blue exit) gives no push.
* **Outcome** per episode: success (red reached), replans (automaton-unexpected
  transitions: pushes and invariance failures), and per push: the D mode the
  env entered, the mode the automaton tracked, and the next tile entered,
  checked against the automaton's re-entry rule.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from steer_envs.baselines.lpv_ds.ltl_ds import LTLDSPolicy, ModeDynamics, fit_mode_dynamics
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import boolean, integer, one_of, real_scalar
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

__all__ = [
    "AUTOMATA",
    "ENV_ID",
    "ReentryFlow",
    "color_demonstration",
    "color_episode",
    "color_policy",
    "color_trial",
    "fit_tile_dynamics",
    "push_schedule",
]

ENV_ID = "steer_envs/ColorTracing-v0"
#: LPV-DS stability margin of the mode DSs (as tli-inspection)
DS_EPS = 1.0
#: attractors sit this far past the mean guard crossing (> dt * max_speed = 0.1)
OVERSHOOT = 0.25
#: gain of the D modes' flow toward their re-entry target (1/s)
REENTRY_GAIN = 5.0
#: the tile modes alone: the demonstration's labels index them (the env's modes start with the tiles)
TILE_TASK = TaskSpec(name="ColorTracingTiles", modes=TILES, transitions=frozenset(itertools.pairwise(TILES)))
#: the push's distance from the row's axis and its horizontal shift
PUSH_Y = (2.5, 6.0)
PUSH_X = 1.5


@functools.lru_cache(maxsize=4)
def color_demonstration(seed: int) -> Any:
    """The single expert demonstration of experiment ``seed`` (cached)."""
    from steer_envs.data.demos import collect_demonstrations

    seed = integer(seed, "seed", low=0, owner="color_demonstration")
    demo = collect_demonstrations(ENV_ID, 1, seed=1000 * seed)[0]
    if not demo.success:
        raise RuntimeError(f"color_demonstration: the expert failed from seed {seed}")
    return demo


@functools.lru_cache(maxsize=4)
def fit_tile_dynamics(seed: int) -> dict[str, ModeDynamics]:
    """One LPV-DS per tile mode from experiment ``seed``'s demonstration (cached; shared, do not modify)."""
    seed = integer(seed, "seed", low=0, owner="fit_tile_dynamics")
    return fit_mode_dynamics(
        [color_demonstration(seed)], TILE_TASK, overshoot=OVERSHOOT, random_state=seed, ds_options={"eps": DS_EPS}
    )


class ReentryFlow:
    """The flow of a D mode: toward :func:`reentry_target` of ``tile``, ``REENTRY_GAIN * (target - x)``."""

    def __init__(self, tile: str, gain: float = REENTRY_GAIN) -> None:
        self.tile = one_of(tile, "tile", TILES, owner="ReentryFlow")
        self.index = TILES.index(tile)
        self.gain = real_scalar(gain, "gain", low=0.0, low_inclusive=False, owner="ReentryFlow")

    def __call__(self, x: np.ndarray) -> np.ndarray:
        p = np.asarray(x, dtype=np.float64).reshape(-1, 2)
        return self.gain * (reentry_target(p, self.index) - p)


def color_policy(seed: int, automaton: str, *, modulation: bool = True, max_speed: float = 10.0, dt: float = 0.01
                 ) -> LTLDSPolicy:  # fmt: skip
    """LTL-DS for ``automaton``: the experiment's tile DSs plus the automaton's D-mode flows."""
    from steer_envs.ltl.specs import color_tracing

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


def push_schedule(rng: np.random.Generator, n_pushes: int, max_dwell: int) -> list[tuple[str, int]]:
    """``n_pushes`` ``(trigger tile, dwell steps)``: tiles before red, distinct while there are enough."""
    n = integer(n_pushes, "n_pushes", low=0, owner="push_schedule")
    max_dwell = integer(max_dwell, "max_dwell", low=1, owner="push_schedule")
    tiles = list(TILES[:-1])
    order = [str(t) for t in rng.permutation(tiles)] * (n // len(tiles) + 1)
    return [(order[k], int(rng.integers(1, max_dwell + 1))) for k in range(n)]


def _push_target(rng: np.random.Generator, x: np.ndarray) -> np.ndarray:
    side = 1.0 if rng.random() < 0.5 else -1.0
    return np.array([np.clip(x[0] + rng.uniform(-PUSH_X, PUSH_X), -7.5, 7.5), side * rng.uniform(*PUSH_Y)])


def color_episode(
    base: Any, policy: LTLDSPolicy, automaton: str, reset_seed: int, pushes: list[tuple[str, int]],
    rng: np.random.Generator,
    max_steps: int,
) -> dict[str, Any]:  # fmt: skip
    """One episode of ``policy`` on the unwrapped env ``base`` with the pushes of :func:`push_schedule`."""
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
            info = base.perturb(to=_push_target(rng, x))
            obs = base.state.astype(np.float32)
            tracked = policy.observe(obs, info)
            open_push = {"from": x.tolist(), "to": base.state.tolist(), "left": mode, "env_mode": info["mode_name"],
                         "tracked": tracked, "expected": REENTRY[automaton].get(str(info["mode_name"])),
                         "reentered": None}  # fmt: skip
            push_log.append(open_push)
            trace.append([base.state.tolist()])
        action = policy.act(obs, info)
        obs, _, _, _, info = base.step(action)
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
    kinds = [e.kind for e in policy.events]
    return {
        "success": bool(info["success"]),
        "steps": steps,
        "replans": kinds.count("push") + kinds.count("failure"),  # mode changes off the plan
        "failures": kinds.count("failure"),
        "failure_events": [
            (e.source, e.target, e.before.round(2).tolist()) for e in policy.events if e.kind == "failure"
        ],
        "violations": violations,
        "pushes": push_log,
        "modes": modes,
        "trace": [np.round(np.asarray(s), 3).tolist() for s in trace],
    }


def color_trial(
    seed: int,
    automaton: str,
    *,
    n_episodes: int = 10,
    n_pushes: int = 2,
    max_dwell: int = 15,
    max_steps: int = 2500,
    modulation: bool = True,
    record: bool = False,
) -> dict[str, Any]:
    """``n_episodes`` episodes without and with pushes under ``automaton``; JSON-able summaries."""
    import gymnasium as gym

    import steer_envs  # noqa: F401 - registers the ids in a fresh worker

    owner = "color_trial"
    seed = integer(seed, "seed", low=0, owner=owner)
    one_of(automaton, "automaton", AUTOMATA, owner=owner)
    n_episodes = integer(n_episodes, "n_episodes", low=1, owner=owner)
    n_pushes = integer(n_pushes, "n_pushes", low=0, owner=owner)
    max_dwell = integer(max_dwell, "max_dwell", low=1, owner=owner)
    max_steps = integer(max_steps, "max_steps", low=1, owner=owner)
    env = gym.make(ENV_ID, automaton=automaton)
    base: Any = env.unwrapped
    try:
        policy = color_policy(seed, automaton, modulation=modulation, max_speed=base.max_speed, dt=base.dt)
        out: dict[str, Any] = {}
        for cond, k in (("clean", 0), ("push", n_pushes)):
            rng = np.random.default_rng([seed, 2020, k])
            episodes = []
            for i in range(n_episodes):
                reset_seed = int(np.random.SeedSequence([seed, i, 7]).generate_state(1)[0] % 2**31)
                schedule = push_schedule(rng, k, max_dwell)
                episodes.append(color_episode(base, policy, automaton, reset_seed, schedule, rng, max_steps))
            out[cond] = _summary(episodes, record)
        out["num_cuts"] = policy.num_cuts
        return out
    finally:
        env.close()


def _summary(episodes: Sequence[Mapping[str, Any]], record: bool) -> dict[str, Any]:
    pushes = [p for e in episodes for p in e["pushes"]]
    out: dict[str, Any] = {
        k: float(np.mean([float(e[k]) for e in episodes])) for k in ("success", "steps", "replans", "failures",
                                                                       "violations")
    }  # fmt: skip
    out["n_pushes"] = len(pushes)
    out["reentry_ok"] = sum(p["reentered"] == p["expected"] for p in pushes)
    out["tracked_ok"] = sum(p["tracked"] == p["env_mode"] for p in pushes)
    out["push_log"] = [{k: p[k] for k in ("left", "env_mode", "tracked", "expected", "reentered")} for p in pushes]
    if record:
        out["figure"] = [{k: e[k] for k in ("trace", "pushes", "success")} for e in episodes[:3]]
    return out
