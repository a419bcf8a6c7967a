"""Demonstrations of the TLI studies (thesis ch. 3): drawn curves and scripted-expert episodes per task.

* :func:`convex_mode_demos` -- ConvexMode-v0 (the single-mode study): the
  thesis's demos were drawn by hand, curving through the mode from its
  left-most vertex to the attractor. ``demos="drawn"`` simulates them as cubic
  Bezier curves from ``demo_start`` to the attractor whose two inner control
  points are drawn uniformly inside the mode (a Bezier curve lies in the convex
  hull of its control points, so in the convex mode), 200 samples of
  ``dt = 0.01`` with a speed decreasing linearly to 0 at the attractor;
  velocities are the exact derivatives. ``demos="expert"`` uses the ConvexMode
  scripted expert instead (a saturated straight-line flow to the attractor,
  run for 200 steps; the first demo starts at ``demo_start``, further ones at
  ``demo_start + N(0, 0.5^2 I)``).
* :func:`drawn_scoop_demos`, :func:`scoop_demonstrations` -- SoupScoop-v0:
  hand-drawn-like reach -> scoop -> transport curves replayed through the env,
  or the scripted expert.
* :func:`cooking_demonstrations` -- Cooking-v0: the two expert episodes of the
  re-tasking study (chicken first, broccoli first).
* :func:`color_demonstration`, :func:`arm_scoop_demonstrations`,
  :func:`inspection_demonstrations` -- the expert episodes of the robot
  experiments (ColorTracing-v0, ArmScoop-v0, InspectionLine-v0), cached per seed.

>>> xs, vs, model = convex_mode_demos(0, 2)
>>> len(xs), xs[0].shape, bool(model.inside(xs[0]).all())
(2, (200, 2), True)
"""

from __future__ import annotations

import functools
from typing import Any

import gymnasium as gym
import numpy as np

from steer_envs.core.validation import BoundExceeded, integer
from steer_envs.data.demos import Demonstration, collect_demonstrations, first_demos, rollout_expert

__all__ = [
    "COOKING_DEMO_PLANS",
    "arm_scoop_demonstrations",
    "color_demonstration",
    "convex_mode_demos",
    "cooking_demonstrations",
    "drawn_scoop_demos",
    "inspection_demonstrations",
    "scoop_demonstrations",
]

CONVEX_ENV = "steer_envs/ConvexMode-v0"
SCOOP_ENV = "steer_envs/SoupScoop-v0"
COOKING_ENV = "steer_envs/Cooking-v0"
COLOR_ENV = "steer_envs/ColorTracing-v0"
ARM_SCOOP_ENV = "steer_envs/ArmScoop-v0"
INSPECTION_ENV = "steer_envs/InspectionLine-v0"
#: step of the drawn ConvexMode demonstrations (ConvexMode-v0's dt)
DT = 0.01
#: samples per ConvexMode demonstration
DEMO_STEPS = 200
#: draws of a rejection-sampling loop (a start, a control point) before it gives up.
MAX_DRAWS = 100_000
#: the two Cooking demonstrations: (expert order, expert route from the pot to the second food)
COOKING_DEMO_PLANS: tuple[tuple[str, str], ...] = (("cb", "direct"), ("bc", "white"))


def _make_env(layout_seed: int) -> gym.Env:
    import steer_envs  # noqa: F401 - registers the ids

    return gym.make(CONVEX_ENV, layout_seed=layout_seed)


def _bezier(points: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A cubic Bezier curve and its derivative ``d/ds`` at parameters ``s`` (``(n,)``)."""
    p0, p1, p2, p3 = points
    b = s[:, None]
    x = (1 - b) ** 3 * p0 + 3 * (1 - b) ** 2 * b * p1 + 3 * (1 - b) * b**2 * p2 + b**3 * p3
    dx = 3 * (1 - b) ** 2 * (p1 - p0) + 6 * (1 - b) * b * (p2 - p1) + 3 * b**2 * (p3 - p2)
    return x, dx


# ------------------------------------------------------------------ ConvexMode
def convex_mode_demos(
    layout_seed: int, n_demos: int, steps: int = DEMO_STEPS, demos: str = "drawn"
) -> tuple[list[np.ndarray], list[np.ndarray], Any]:
    """``n_demos`` demonstrations of a ConvexMode layout: (states list, velocities list, model); see module doc.

    >>> xs, vs, model = convex_mode_demos(0, 1, demos="expert")
    >>> xs[0].shape == vs[0].shape == (200, 2)
    True
    """
    if not isinstance(n_demos, int) or n_demos < 1:
        raise ValueError(f"n_demos must be a positive int, got {n_demos!r}")
    steps = integer(steps, "steps", low=2, owner="convex_mode_demos")
    if demos == "drawn":
        return _drawn_demos(layout_seed, n_demos, steps)
    if demos != "expert":
        raise ValueError(f"demos must be 'drawn' or 'expert', got {demos!r}")
    return _expert_demos(layout_seed, n_demos, steps)


def _expert_demos(layout_seed: int, n_demos: int, steps: int) -> tuple[list[np.ndarray], list[np.ndarray], Any]:
    """ConvexMode's scripted expert from ``demo_start`` (and from noisy copies of it); see the module docstring."""
    from steer_envs.data.experts import make_expert

    env = _make_env(layout_seed)
    base: Any = env.unwrapped
    model = base.model
    expert = make_expert(env)
    rng = np.random.default_rng([layout_seed, 7919])
    xs, vs = [], []
    for i in range(n_demos):
        start = model.demo_start.copy()
        for _ in range(MAX_DRAWS if i > 0 else 0):
            cand = model.demo_start + rng.normal(0.0, 0.5, size=2)
            if model.inside(cand[None])[0]:
                start = cand
                break
        else:
            if i > 0:
                raise BoundExceeded(
                    f"convex_mode_demos: no start of demo {i} inside the mode within MAX_DRAWS={MAX_DRAWS} draws"
                )
        obs, info = base.reset(options={"state": start})
        expert.reset(obs, info)
        states, actions = [], []
        for _ in range(steps):  # the unwrapped env keeps stepping after success: full convergence
            action = np.asarray(expert.act(obs, info), dtype=np.float64)
            states.append(base.state)
            actions.append(action)
            obs, _, _, _, info = base.step(action.astype(np.float32))
        xs.append(np.asarray(states))
        vs.append(np.asarray(actions))
    env.close()
    return xs, vs, model


def _drawn_demos(layout_seed: int, n_demos: int, steps: int) -> tuple[list[np.ndarray], list[np.ndarray], Any]:
    """Simulated hand-drawn demos: cubic Bezier curves inside the mode (see the module docstring)."""
    env = _make_env(layout_seed)
    model: Any = env.unwrapped.model  # type: ignore[attr-defined]
    env.close()
    rng = np.random.default_rng([layout_seed, 104729])
    lo, hi = model.vertices.min(axis=0), model.vertices.max(axis=0)
    tau = np.arange(steps) / (steps - 1)
    duration = DT * (steps - 1)
    s = 1.0 - (1.0 - tau) ** 2  # progress along the curve: speed falls linearly to 0
    ds_dt = 2.0 * (1.0 - tau) / duration
    xs, vs = [], []
    for _ in range(n_demos):
        ctrl: list[np.ndarray] = []
        for _ in range(MAX_DRAWS):
            if len(ctrl) == 2:
                break
            cand = rng.uniform(lo, hi)
            if model.inside(cand[None])[0]:
                ctrl.append(cand)
        if len(ctrl) < 2:
            raise BoundExceeded(
                f"convex_mode_demos: no control points inside the mode within MAX_DRAWS={MAX_DRAWS} draws"
            )
        x, dx_ds = _bezier(np.stack([model.demo_start, ctrl[0], ctrl[1], model.attractor]), s)
        xs.append(x)
        vs.append(dx_ds * ds_dt[:, None])
    return xs, vs, model


# ------------------------------------------------------------------ SoupScoop
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


def _replay_drawn(base: Any, path: np.ndarray, seed: int) -> Demonstration | None:
    """``path`` tracked point by point through the unwrapped SoupScoop env; None when the drawing must be redrawn.

    Redrawn: a replay that does not visit every mode in order, or whose transitions fire on a region's
    attractor disc instead of its rectangle.
    """
    task = base.task
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
        return None  # the drawing left a mode on the way: draw again
    entered = [states[t + 1] for t in np.nonzero(np.diff(order))[0]]
    if not all(_in_rect(base.model, r, x) for r, x in zip(("yellow", "pink", "green"), entered, strict=True)):
        return None  # a transition fired on an attractor disc, not on the region's guard: draw again
    return Demonstration(
        env_id=SCOOP_ENV,
        seed=int(seed),
        states=np.asarray(states),
        actions=np.asarray(actions),
        modes=order.astype(np.int64),
        sensors=np.asarray(sensors, dtype=bool),
        success=True,
    )


def drawn_scoop_demos(seed: int, n: int, *, max_tries: int = 200) -> list[Demonstration]:
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
    import steer_envs  # noqa: F401

    if not isinstance(n, int) or n < 1:
        raise ValueError(f"n must be a positive int, got {n!r}")
    max_tries = integer(max_tries, "max_tries", low=1, owner="drawn_scoop_demos")
    env = gym.make(SCOOP_ENV)
    base: Any = env.unwrapped
    rng = np.random.default_rng([int(seed), 4409])
    try:
        paths = (_drawn_path(rng, base.model, base.dt, base.max_speed) for _ in range(max_tries * n))
        demos = first_demos((_replay_drawn(base, path, seed) for path in paths), n)
    finally:
        env.close()
    if len(demos) == n:
        return demos
    raise BoundExceeded(
        f"drawn_scoop_demos: drew only {len(demos)} of {n} valid soup-scooping demonstrations in "
        f"max_tries * n = {max_tries * n} tries"
    )


def scoop_demonstrations(seed: int, n_demos: int, demos: str = "drawn") -> list[Demonstration]:
    """The SoupScoop demonstrations of experiment ``seed``: ``"drawn"`` (:func:`drawn_scoop_demos`) or ``"expert"``."""
    if demos == "drawn":
        return drawn_scoop_demos(seed, n_demos)
    if demos != "expert":
        raise ValueError(f"demos must be 'drawn' or 'expert', got {demos!r}")
    demo_seed = int(np.random.SeedSequence([seed, 211]).generate_state(1)[0] % (2**31))
    return collect_demonstrations(SCOOP_ENV, n_demos, seed=demo_seed)


# ------------------------------------------------------------------ the other tasks
def cooking_demonstrations(seed: int) -> list[Demonstration]:
    """The two Cooking expert demonstrations of experiment ``seed``.

    Chicken first leaving the pot sideways (``w y d g d``, the thesis's Fig. (c))
    and broccoli first leaving the pot through the white gap (``w g d w y d``);
    see :data:`COOKING_DEMO_PLANS`.
    """
    import steer_envs  # noqa: F401 - registers the ids in a fresh worker

    seed = integer(seed, "seed", low=0, owner="cooking_demonstrations")
    env = gym.make(COOKING_ENV)
    try:
        demos = []
        for i, (order, route) in enumerate(COOKING_DEMO_PLANS):
            demo = rollout_expert(env, 1000 * seed + i, expert_kwargs={"order": order, "route": route})
            if not demo.success:
                raise RuntimeError(f"cooking_demonstrations: the expert ({order}, {route}) failed from seed {seed}")
            demos.append(demo)
        return demos
    finally:
        env.close()


@functools.lru_cache(maxsize=4)
def color_demonstration(seed: int) -> Demonstration:
    """The single ColorTracing expert demonstration of experiment ``seed`` (cached; shared, do not modify)."""
    seed = integer(seed, "seed", low=0, owner="color_demonstration")
    demo = collect_demonstrations(COLOR_ENV, 1, seed=1000 * seed)[0]
    if not demo.success:
        raise RuntimeError(f"color_demonstration: the expert failed from seed {seed}")
    return demo


@functools.lru_cache(maxsize=4)
def arm_scoop_demonstrations(seed: int, n_demos: int = 2) -> tuple[Demonstration, ...]:
    """The ``n_demos`` ArmScoop expert demonstrations of experiment ``seed`` (cached)."""
    seed = integer(seed, "seed", low=0, owner="arm_scoop_demonstrations")
    n_demos = integer(n_demos, "n_demos", low=1, owner="arm_scoop_demonstrations")
    return tuple(collect_demonstrations(ARM_SCOOP_ENV, n_demos, seed=1000 * seed))


@functools.lru_cache(maxsize=4)
def inspection_demonstrations(seed: int) -> tuple[Demonstration, ...]:
    """The two InspectionLine expert demonstrations of experiment ``seed`` (cached)."""
    return tuple(collect_demonstrations(INSPECTION_ENV, 2, seed=1000 * integer(seed, "seed", low=0)))
