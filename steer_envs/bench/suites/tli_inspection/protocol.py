"""One tli-inspection trial: vanilla DS vs LTL-DS on InspectionLine-v0 under large pushes.

Thesis appendix "Robot Experiment 2: Inspection Line": a single LPV-DS
(*vanilla DS*) fitted to whole demonstrations is stable at the release
station, so after a large push it always reaches it, but it may skip the
inspection line; LTL-DS (one LPV-DS per mode, the two-mode automaton, cuts
from invariance failures) returns to the inspection entry and re-does the
inspection whenever the object is pushed off the line.

* **Demonstrations**: two scripted-expert episodes from the grasping region.
* **Methods**: ``vanilla-ds`` (:class:`~steer_envs.baselines.lpv_ds.lpvds.LPVDS`
  on the whole demonstrations, attractor at their mean end), ``ltl-ds`` and
  ``ltl-ds+mod`` (:class:`~steer_envs.baselines.lpv_ds.ltl_ds.LTLDSPolicy`
  without / with cuts) under :func:`inspection_spec`.
* **Pushes**: the ``k``-th push fires when the end-effector is on the track at
  ``x >= threshold_k`` (thresholds uniform in ``[-3, 2.5]``, the same for every
  method), with a uniform direction and a length uniform in
  ``[min_push, max_push]``; ``max_push = 0`` gives the unperturbed runs.
* **Outcome**: ``success`` = released after the inspection; ``uninspected`` =
  the episode ended at the release station with the object never inspected
  (the vanilla DS's attractor reached without the task); ``inspections`` =
  times the object was put on the line.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from steer_envs.core.validation import integer, one_of, real_scalar
from steer_envs.ltl.gr1 import GR1Spec

__all__ = ["ENV_ID", "METHODS", "inspection_demonstrations", "inspection_spec", "inspection_trial"]

ENV_ID = "steer_envs/InspectionLine-v0"
METHODS: tuple[str, ...] = ("vanilla-ds", "ltl-ds", "ltl-ds+mod")
DS_EPS = 1.0
OVERSHOOT = 0.25
#: an episode that rests this slowly (units/s) inside the release station has converged
REST_SPEED = 0.05


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


@functools.lru_cache(maxsize=4)
def inspection_demonstrations(seed: int) -> tuple[Any, ...]:
    """The two expert demonstrations of experiment ``seed`` (cached)."""
    from steer_envs.data.demos import collect_demonstrations

    return tuple(collect_demonstrations(ENV_ID, 2, seed=1000 * integer(seed, "seed", low=0)))


def _vanilla(demos: tuple[Any, ...], dt: float, seed: int) -> Any:
    from steer_envs.baselines.lpv_ds.lpvds import LPVDS

    xs = [np.asarray(d.states, dtype=np.float64) for d in demos]
    vs = [np.vstack([np.diff(x, axis=0) / dt, np.zeros((1, 2))]) for x in xs]
    attractor = np.mean([x[-1] for x in xs], axis=0)
    return LPVDS(eps=DS_EPS, random_state=seed).fit(xs, vs, attractor=attractor)


def inspection_trial(
    seed: int,
    method: str,
    *,
    n_episodes: int = 10,
    n_pushes: int = 1,
    min_push: float = 4.0,
    max_push: float = 10.0,
    max_steps: int = 3000,
    record: bool = False,
) -> dict[str, Any]:
    """``n_episodes`` episodes of ``method`` from the grasping region under the push rule; JSON-able means."""
    import gymnasium as gym

    import steer_envs  # noqa: F401
    from steer_envs.baselines.lpv_ds.ltl_ds import LTLDSPolicy

    seed = integer(seed, "seed", low=0, owner="inspection_trial")
    one_of(method, "method", METHODS, owner="inspection_trial")
    n_episodes = integer(n_episodes, "n_episodes", low=1, owner="inspection_trial")
    max_push = real_scalar(max_push, "max_push", low=0.0, owner="inspection_trial")
    min_push = real_scalar(min_push, "min_push", low=0.0, high=max_push, owner="inspection_trial")
    env = gym.make(ENV_ID)
    base: Any = env.unwrapped
    demos = inspection_demonstrations(seed)
    if method == "vanilla-ds":
        ds = _vanilla(demos, base.dt, seed)
        policy: Any = None
    else:
        policy = LTLDSPolicy.fit(
            list(demos), base.task, inspection_spec(), overshoot=OVERSHOOT, random_state=seed,
            ds_options={"eps": DS_EPS}, modulation=method == "ltl-ds+mod", max_speed=base.max_speed, dt=base.dt,
        )  # fmt: skip
    rng = np.random.default_rng([seed, 881])
    episodes: list[dict[str, Any]] = []
    for i in range(n_episodes):
        thresholds = sorted(rng.uniform(-3.0, 2.5, size=n_pushes).tolist())
        pushes = [
            (t, m * np.array([np.cos(a), np.sin(a)]))
            for t, a, m in zip(
                thresholds, rng.uniform(0, 2 * np.pi, n_pushes), rng.uniform(min_push, max_push, n_pushes), strict=True
            )
        ]
        obs, info = base.reset(seed=int(np.random.SeedSequence([seed, i, 5]).generate_state(1)[0] % 2**31))
        if policy is not None:
            policy.reset(obs, info)
        inspections = int(info["sensors"]["l"])
        was_on = bool(info["sensors"]["l"])
        trace = [[base.state.tolist()]]
        push_log = []
        uninspected = False
        steps = 0
        for steps in range(1, max_steps + 1):  # noqa: B007
            x = base.state
            rx0, ry0, rx1, ry1 = base.model.rects["track"]
            if pushes and max_push > 0 and rx0 <= x[0] <= rx1 and ry0 <= x[1] <= ry1 and x[0] >= pushes[0][0]:
                info = base.perturb(delta=pushes.pop(0)[1])
                obs = base.state.astype(np.float32)
                push_log.append({"from": x.tolist(), "to": base.state.tolist()})
                trace.append([base.state.tolist()])
            action = ds(obs[None].astype(np.float64))[0] if policy is None else policy.act(obs, info)
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
        episodes.append(
            {
                "success": bool(info["success"]),
                "uninspected": uninspected or (at_station and not info["success"]),
                "inspections": inspections,
                "steps": steps,
                "trace": [np.round(np.asarray(s), 3).tolist() for s in trace],
                "pushes": push_log,
            }
        )
    env.close()
    out: dict[str, Any] = {
        k: float(np.mean([float(e[k]) for e in episodes])) for k in ("success", "uninspected", "inspections", "steps")
    }
    out["num_cuts"] = 0 if policy is None else policy.num_cuts
    if record:
        out["figure"] = {"episodes": [{k: e[k] for k in ("trace", "pushes", "success")} for e in episodes[:4]]}
    return out
