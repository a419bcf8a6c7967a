"""The TLI robustness protocol: LTL-DS soup scooping under random pushes (thesis §3.7.2, appendix "Multi-modal").

One *experiment* (``scoop_trial``) of the thesis's ten:

* **Demonstrations**: ``n_demos`` (1-3, drawn from ``seed`` when not given),
  segmented by their sensors into the modes a (reach), b (scoop), c
  (transport), d (done). ``demos="drawn"`` (default): hand-drawn-like curves
  (:func:`drawn_scoop_demos`; the thesis's were drawn by hand);
  ``demos="expert"``: the scripted expert
  (:func:`~steer_envs.data.demos.collect_demonstrations`). The expert moves in
  straight lines through the middle of each region, and the per-mode DSs fitted
  to it hardly ever leave a mode: too few invariance failures to test the claim.
* **Policy**: :class:`~steer_envs.baselines.lpv_ds.ltl_ds.LTLDSPolicy` - one LPV-DS
  per mode, the soup-scooping GR(1) automaton choosing the mode from the
  sensors, with or without modulation by cuts learned from invariance failures.
* **Perturbations** ("uniformly sampled in all directions of any magnitudes up
  to the dimension of the entire workspace"; Asm. 2: finitely many): up to
  ``n_perturbations`` pushes at distinct random steps in ``[1, push_window]``,
  each a displacement with a uniform direction and a magnitude uniform in
  ``[0, magnitude]`` (default 16, the workspace's side), applied through
  ``env.unwrapped.perturb`` (the state is clipped to the workspace; the soup
  falls off a spoon pushed out of the transport region). A push scheduled
  after the task is done is not applied.
* **Outcome**: *eventual success* = mode d reached within ``max_steps`` (the
  cap stands in for "forever": without modulation the automaton can loop
  between modes, the thesis's first row of Fig. 3.6). ``invariance_failures``
  counts the policy's own unplanned mode exits; each one sends the automaton
  back along its plan, so it is the number of discrete loop iterations.
  ``mode_reentries`` counts entries into a mode already visited in the
  episode (pushes included).

The same ``seed`` gives the same demonstrations, fits, start state and push
schedule with and without modulation, so the two runs are paired.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from steer_envs.core.validation import BoundExceeded, integer, real_scalar

__all__ = [
    "DS_EPS",
    "ENV_ID",
    "OVERSHOOT",
    "THESIS_SCOOP",
    "WORKSPACE_SIZE",
    "drawn_scoop_demos",
    "perturbation_schedule",
    "scoop_demonstrations",
    "scoop_trial",
]

ENV_ID = "steer_envs/SoupScoop-v0"
#: thesis §3.7.2 / appendix: 10 experiments, all succeed with modulation (no number is given without it).
THESIS_SCOOP: Mapping[str, float] = {"experiments": 10, "success_with_modulation": 1.0}
#: side of SoupScoop's square workspace [-8, 8]^2: the largest push magnitude.
WORKSPACE_SIZE = 16.0
#: LPV-DS stability margin: with LPVDS's default 1e-3 some fitted components contract so slowly that
#: flows stall far from the attractor within an episode; 1.0 (per second) keeps reaching times short.
DS_EPS = 1.0
#: the guard attractors sit this far past the mean crossing point (dt * max_speed = 0.1 < 0.25 < margin 0.4).
OVERSHOOT = 0.25
#: draws of a rejection-sampling loop (a control point away from an attractor disc) before it gives up.
MAX_DRAWS = 100_000


def perturbation_schedule(
    rng: np.random.Generator, n: int, push_window: int, magnitude: float, dim: int = 2
) -> list[tuple[int, np.ndarray]]:
    """``n`` pushes ``(step, displacement)`` at distinct steps in ``[1, push_window]``, sorted by step.

    Directions are uniform on the circle (sphere), magnitudes uniform in ``[0, magnitude]``.

    >>> pushes = perturbation_schedule(np.random.default_rng(0), 3, 600, WORKSPACE_SIZE)
    >>> [step for step, _ in pushes] == sorted(step for step, _ in pushes), all(
    ...     np.linalg.norm(d) <= WORKSPACE_SIZE for _, d in pushes)
    (True, True)
    """
    if not isinstance(n, int) or n < 0:
        raise ValueError(f"n must be an int >= 0, got {n!r}")
    if not isinstance(push_window, int) or push_window < max(1, n):
        raise ValueError(f"push_window must be an int >= max(1, n) = {max(1, n)}, got {push_window!r}")
    magnitude = real_scalar(magnitude, "magnitude", low=0.0, owner="perturbation_schedule")
    dim = integer(dim, "dim", low=1, owner="perturbation_schedule")
    steps = np.sort(rng.choice(np.arange(1, push_window + 1), size=n, replace=False))
    direction = rng.normal(size=(n, dim))
    direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-12)
    size = rng.uniform(0.0, magnitude, size=n)
    return [(int(s), d * m) for s, d, m in zip(steps, direction, size, strict=True)]


def _bezier(points: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A cubic Bezier curve and its derivative ``d/ds`` at parameters ``s`` (``(n,)``)."""
    p0, p1, p2, p3 = points
    b = s[:, None]
    x = (1 - b) ** 3 * p0 + 3 * (1 - b) ** 2 * b * p1 + 3 * (1 - b) * b**2 * p2 + b**3 * p3
    dx = 3 * (1 - b) ** 2 * (p1 - p0) + 6 * (1 - b) * b * (p2 - p1) + 3 * b**2 * (p3 - p2)
    return x, dx


def _drawn_path(rng: np.random.Generator, model: Any, dt: float, max_speed: float) -> np.ndarray:
    """A hand-drawn-like reach -> scoop -> transport path, sampled every ``dt`` (see :func:`drawn_scoop_demos`)."""
    (slo, shi), (yx0, _, _, ysurf), (px0, py0, px1, _), (_, gy0, _, _) = (
        (model.start_low, model.start_high),
        model.rects["yellow"],
        model.rects["pink"],
        model.rects["green"],
    )
    inset, depth = 0.3, 0.15  # control points this far inside their region; end points this far past a guard
    x0 = rng.uniform(slo, shi)
    away = 2.0 * model.attractor_radius  # guard crossings stay clear of the regions' "near the attractor" discs
    for _ in range(MAX_DRAWS):
        p1 = np.array([rng.uniform(yx0 + inset, px0 - 4.0), ysurf - depth])  # into the soup, left of the pink column
        if np.linalg.norm(p1 - model.region_attractors["yellow"]) > away:
            break
    else:
        raise BoundExceeded(f"drawn_scoop_demos: no soup entry point off the attractor disc in MAX_DRAWS={MAX_DRAWS}")
    for _ in range(MAX_DRAWS):
        p2 = np.array([px0 + depth, rng.uniform(py0 + inset, ysurf - 0.5)])  # through the soup into the pink column
        if np.linalg.norm(p2 - model.region_attractors["pink"]) > away:
            break
    else:
        raise BoundExceeded(f"drawn_scoop_demos: no column entry point off the attractor disc in MAX_DRAWS={MAX_DRAWS}")
    p3 = np.array([rng.uniform(px0 + inset, px1 - inset), gy0 + depth])  # up the column into green
    boxes = (  # the convex region each curve stays in (a Bezier lies in the hull of its control points)
        ((yx0 + inset, ysurf + 0.5), (px0 - inset, model.high[1] - inset)),  # white, left of pink, above the soup
        ((yx0 + inset, py0 + inset), (px0 - inset, ysurf - inset)),  # soup, left of pink
        ((px0 + inset, py0 + inset), (px1 - inset, gy0 - inset)),  # pink column
    )
    pieces = []
    for (a, b), (lo, hi) in zip(((x0, p1), (p1, p2), (p2, p3)), boxes, strict=True):
        ctrl = np.stack([a, rng.uniform(lo, hi), rng.uniform(lo, hi), b])
        fine = np.linspace(0.0, 1.0, 400)
        pts, deriv = _bezier(ctrl, fine)
        length = float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
        # drawing speed 4-7 units/s, slower where the parametrisation is uneven (|x'| stays below max_speed)
        duration = max(length / rng.uniform(4.0, 7.0), float(np.max(np.linalg.norm(deriv, axis=1))) / (0.9 * max_speed))
        n = max(2, int(np.ceil(duration / dt)))
        pieces.append(_bezier(ctrl, np.linspace(0.0, 1.0, n + 1))[0][:-1])
    pieces.append(p3[None])
    return np.concatenate(pieces)


def _in_rect(model: Any, name: str, x: np.ndarray) -> bool:
    """``x`` lies in region ``name``'s rectangle proper (not only in its attractor disc)."""
    x0, y0, x1, y1 = model.rects[name]
    return bool(x0 <= x[0] <= x1 and y0 <= x[1] <= y1)


def drawn_scoop_demos(seed: int, n: int, *, max_tries: int = 200) -> list[Any]:
    """``n`` hand-drawn-like SoupScoop demonstrations (the thesis's were drawn by hand).

    Each is three cubic Bezier curves (reach: start box -> just inside the
    soup; scoop: through the soup -> just inside the pink column; transport:
    up the column -> just inside green) whose inner control points are drawn
    uniformly inside the region the curve belongs to, so each curve stays in
    its mode and hugs no boundary on purpose. The path is replayed through
    SoupScoop-v0 (the env labels modes and sensors); a replay that does not
    visit a -> b -> c -> d in order, or whose transitions fire on a region's
    attractor disc (SoupScoop's "within 0.4 of the attractor" rule, which makes
    the modes non-convex there) instead of its rectangle, is redrawn. Returns
    :class:`~steer_envs.data.demos.Demonstration` objects.
    """
    import gymnasium as gym

    import steer_envs  # noqa: F401
    from steer_envs.data.demos import Demonstration

    if not isinstance(n, int) or n < 1:
        raise ValueError(f"n must be a positive int, got {n!r}")
    max_tries = integer(max_tries, "max_tries", low=1, owner="drawn_scoop_demos")
    env = gym.make(ENV_ID)
    base: Any = env.unwrapped
    task = base.task
    rng = np.random.default_rng([int(seed), 4409])
    demos: list[Any] = []
    try:
        for _ in range(max_tries * n):
            path = _drawn_path(rng, base.model, base.dt, base.max_speed)
            _, info = base.reset(options={"state": path[0]})
            states, actions = [base.state], []
            modes, sensors = [info["mode"]], [[info["sensors"][ap] for ap in task.sensors]]
            for target in path[1:]:
                action = (target - base.state) / base.dt  # track the drawn path point by point
                _, _, terminated, _, info = base.step(action.astype(np.float32))
                states.append(base.state)
                actions.append(action)
                modes.append(info["mode"])
                sensors.append([info["sensors"][ap] for ap in task.sensors])
                if terminated:
                    break
            order = np.asarray(modes)
            if not info["success"] or np.any(np.diff(order) < 0) or set(order.tolist()) != set(range(len(task.modes))):
                continue  # the drawing left a mode on the way: draw again
            entered = [states[t + 1] for t in np.nonzero(np.diff(order))[0]]
            if not all(_in_rect(base.model, r, x) for r, x in zip(("yellow", "pink", "green"), entered, strict=True)):
                continue  # a transition fired on an attractor disc, not on the region's guard: draw again
            demos.append(
                Demonstration(
                    env_id=ENV_ID,
                    seed=int(seed),
                    states=np.asarray(states),
                    actions=np.asarray(actions),
                    modes=order.astype(np.int64),
                    sensors=np.asarray(sensors, dtype=bool),
                    success=True,
                )
            )
            if len(demos) == n:
                return demos
    finally:
        env.close()
    raise BoundExceeded(
        f"drawn_scoop_demos: drew only {len(demos)} of {n} valid soup-scooping demonstrations in "
        f"max_tries * n = {max_tries * n} tries"
    )


def scoop_demonstrations(seed: int, n_demos: int, demos: str = "drawn") -> list[Any]:
    """The demonstrations of experiment ``seed``: ``"drawn"`` (:func:`drawn_scoop_demos`) or ``"expert"``."""
    from steer_envs.data.demos import collect_demonstrations

    if demos == "drawn":
        return drawn_scoop_demos(seed, n_demos)
    if demos != "expert":
        raise ValueError(f"demos must be 'drawn' or 'expert', got {demos!r}")
    demo_seed = int(np.random.SeedSequence([seed, 211]).generate_state(1)[0] % (2**31))
    return collect_demonstrations(ENV_ID, n_demos, seed=demo_seed)


def _fit_policy(
    seed: int, n_demos: int, modulation: bool, env: Any, demos: str, ds_eps: float, overshoot: float
) -> Any:
    from steer_envs.baselines.lpv_ds.ltl_ds import LTLDSPolicy
    from steer_envs.ltl.specs import for_env

    base = env.unwrapped
    return LTLDSPolicy.fit(
        scoop_demonstrations(seed, n_demos, demos),
        base.task,
        for_env(env),
        overshoot=overshoot,
        random_state=seed,
        ds_options={"eps": ds_eps},
        modulation=modulation,
        max_speed=base.max_speed,
        dt=base.dt,
    )


def scoop_trial(
    seed: int,
    modulation: bool,
    n_perturbations: int = 3,
    *,
    n_demos: int | None = None,
    max_steps: int = 5000,
    push_window: int = 600,
    magnitude: float = WORKSPACE_SIZE,
    demos: str = "drawn",
    ds_eps: float = DS_EPS,
    overshoot: float = OVERSHOOT,
    record: bool = False,
) -> dict[str, Any]:
    """One soup-scooping experiment under random pushes (see the module docstring); a JSON-able dict.

    Args:
        seed: the experiment (demonstrations, fits, start state, pushes).
        modulation: LTL-DS with cuts (True) or the plain DS + automaton (False).
        n_perturbations: pushes scheduled in the episode.
        n_demos: 1-3 demonstrations; default drawn from ``seed``.
        max_steps: episode cap (a run still looping then counts as a failure).
        push_window: pushes happen at steps ``1..push_window``.
        magnitude: largest push length (default: the workspace side, 16).
        demos: ``"drawn"`` (hand-drawn-like curves, default) or ``"expert"`` (the scripted expert).
        ds_eps: stability margin of the LPV-DS fits (see :data:`DS_EPS`).
        overshoot: of the guard attractors (see :func:`~steer_envs.baselines.lpv_ds.ltl_ds.fit_mode_dynamics`).
        record: also return the trajectory, the pushes and the learned cuts (for plots).

    Keys: ``success`` (0/1), ``steps``, ``invariance_failures``, ``mode_reentries``,
    ``pushes`` (applied), ``num_cuts``, ``planned_transitions``, ``n_demos``,
    ``fit_seconds``, ``seconds`` and the inputs (+ ``trajectory``, ``push_log``,
    ``cuts``, ``attractors``, ``events`` with ``record``; the trajectory is a list of
    segments, split at pushes).

    >>> result = scoop_trial(0, True, 1, n_demos=1, max_steps=400)
    >>> result["pushes"] <= 1, result["steps"] <= 400, result["success"] in (0.0, 1.0)
    (True, True, True)
    """
    import gymnasium as gym

    import steer_envs  # noqa: F401 - registers the envs in a fresh worker

    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise TypeError(f"seed must be an int, got {type(seed).__name__}")
    if not isinstance(modulation, bool):
        raise TypeError(f"modulation must be a bool, got {type(modulation).__name__}")
    if n_demos is not None and (not isinstance(n_demos, int) or not 1 <= n_demos <= 10):
        raise ValueError(f"n_demos must be None or an int in [1, 10], got {n_demos!r}")
    if not isinstance(max_steps, int) or max_steps < 1:
        raise ValueError(f"max_steps must be a positive int, got {max_steps!r}")
    seed = int(seed)
    t0 = time.perf_counter()
    if n_demos is None:
        n_demos = int(np.random.default_rng([seed, 31]).integers(1, 4))
    rng = np.random.default_rng([seed, 17])
    schedule = perturbation_schedule(rng, n_perturbations, push_window, magnitude)
    with threadpool_limits(limits=1):  # tiny numpy/cvxpy problems: extra BLAS threads only add contention
        env = gym.make(ENV_ID, max_episode_steps=max_steps)
        try:
            t_fit = time.perf_counter()
            policy = _fit_policy(seed, n_demos, modulation, env, demos, ds_eps, overshoot)
            fit_seconds = time.perf_counter() - t_fit
            out = _episode(env, policy, seed, schedule, max_steps, record)
        finally:
            env.close()
    events = policy.events
    visited: set[str] = set()
    reentries = 0
    first = out.pop("first_mode")
    visited.add(first)
    for ev in events:
        reentries += ev.target in visited
        visited.add(ev.target)
    result: dict[str, Any] = {
        "seed": seed,
        "modulation": modulation,
        "n_perturbations": n_perturbations,
        "n_demos": n_demos,
        "demos": demos,
        "max_steps": max_steps,
        "success": float(out["success"]),
        "steps": out["steps"],
        "invariance_failures": sum(ev.kind == "failure" for ev in events),
        "planned_transitions": sum(ev.kind == "planned" for ev in events),
        "mode_reentries": reentries,
        "pushes": len(out["push_log"]),
        "num_cuts": policy.num_cuts,
        "fit_seconds": fit_seconds,
        "seconds": time.perf_counter() - t0,
    }
    if record:
        result["trajectory"] = out["trajectory"]
        result["push_log"] = out["push_log"]
        result["cuts"] = {
            m: [{"point": c.point.tolist(), "normal": c.normal.tolist()} for c in cs.cuts]
            for m, cs in policy.cut_sets.items()
            if len(cs)
        }
        result["attractors"] = {m: policy.dynamics[m].attractor.tolist() for m in policy.modes}
        result["events"] = [
            {"step": ev.step, "from": ev.source, "to": ev.target, "kind": ev.kind, "before": ev.before.tolist()}
            for ev in events
        ]
    return result


def _episode(
    env: Any, policy: Any, seed: int, schedule: list[tuple[int, np.ndarray]], max_steps: int, record: bool
) -> dict[str, Any]:
    """Run one episode with the push schedule; success, steps, applied pushes (and the trajectory)."""
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
