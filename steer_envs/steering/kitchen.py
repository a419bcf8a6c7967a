"""A Kitchen rollout steered by clicks (thesis Table 2.3) and the guide-ratio sweep (thesis Fig. 2.10).

:func:`kitchen_trial` resets Kitchen at an evaluation scene
(:data:`~steer_envs.steering.study.SCENE_SEED_OFFSET` ``+ seed``: never a
training scene) and rolls the frozen skill policy out one skill at a time with
re-planning: at every skill boundary a batch of whole-skill plans is sampled
conditioned on the current observation, the chosen plan runs on the arm
(:func:`~steer_envs.control.kitchen.execute_kitchen_plan`; ``execution``
``"open_loop"`` by default, or ``"closed_loop"``: waypoints reached within a
tolerance, grasps checked and retried, releases settled), and this repeats
until the task's goal, a failed skill, or ``max_skills``.

At each of the first ``max_interactions`` skill boundaries the simulated user
(:class:`~steer_envs.users.kitchen_clicker.KitchenClickUser`) watches an
unsteered (RS) sample, wants a different legal skill, and clicks its target in
the scene camera (a :class:`~steer_envs.core.interaction.Point` on the plan's
xyz). The method then makes the plan (:func:`steered_plan`; thesis Table 2.3's columns):

* ``DP-RS``: a fresh random sample; the click is ignored;
* ``DP-GD``: guided diffusion toward the clicked point, ``gd_ratio`` (beta, 5 as
  in the thesis) at every one of the 100 DDIM steps; the batch's plan nearest
  the point is run;
* ``DP-SS``: stochastic sampling, ``ss_ratio`` (beta, 100 as in the thesis),
  4 MCMC iterations per noise level; nearest plan run;
* ``DP-OP``: a physical correction: the end effector is pushed
  (``env.unwrapped.perturb``) toward the clicked point by ``op_distance`` m
  (less when the point is nearer), then a random sample from there is run.

A boundary where the mode allows no skill besides the watched one gets no
interaction (the watched plan runs). After ``max_interactions`` interactions
the rollout goes on unsteered (RS plans).

Scoring, per interaction:

* *aligned* (TA): the run plan performs the intended skill, read off the plan
  (:func:`~steer_envs.control.kitchen.classify_kitchen_plan`); where the plan
  reads as no skill, the world's mode change decides (a plan heading for
  another skill that knocks the door open is not aligned);
* *success* (CS): the executed skill happened (a mode change some skill makes),
  no constraint was violated, and the change is a transition of the task's tree
  (a placement into a shut microwave, a moved door while holding the bowl, a
  dropped bowl are failures);
* *valid* and *executed_ok*: the policy's part and the robot's part of
  success, apart: the run plan is some skill (``valid``:
  :func:`~steer_envs.control.kitchen.classify_kitchen_plan` reads one, the
  intended one or not), and a valid plan's execution did that skill, legally
  and without a violation (``executed_ok``, a share of the valid plans; None
  without one).

Default tasks: the thesis's merged setting, ``tasks[seed % 2]`` with
``tasks = ("microwave", "sink")`` (seeds alternate): the policy is trained on
exactly those demonstrations merged, and a steered switch (e.g. picking the bowl
instead of opening the door) turns one task's rollout into the other's. The
``"clean"`` task needs the bowl picked from the sink, which the demonstrations
never show, so it would measure the data's coverage rather than steering.

:func:`guide_ratio_sweep` is thesis Fig. 2.10: the share of a batch doing the
intended skill against the guide ratio, for GD and SS.
"""

from __future__ import annotations

import base64
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.core.validation import integer, one_of, real_scalar
from steer_envs.data.shards import LazyEnvs
from steer_envs.steering.base import Sampler
from steer_envs.steering.diffusion import GuidedDiffusion, StochasticSampling
from steer_envs.steering.ranking import RandomSampling
from steer_envs.steering.study import SCENE_SEED_OFFSET, quadrant_shares

__all__ = [
    "DEFAULT_TASKS",
    "METHODS",
    "SS_MCMC_STEPS",
    "SWEEP_STARTS",
    "close_envs",
    "decode_frame",
    "env_for",
    "guide_ratio_sweep",
    "kitchen_trial",
    "make_env",
    "make_method_sampler",
    "steered_plan",
]

#: the thesis's two tasks, merged: seed s rolls out task DEFAULT_TASKS[s % 2].
DEFAULT_TASKS = ("microwave", "sink")
#: Table 2.3's columns.
METHODS = ("DP-RS", "DP-GD", "DP-SS", "DP-OP")
#: SS's MCMC iterations per noise level (ITPS: 4).
SS_MCMC_STEPS = 4
#: the reset options of the sweep's scenes (cycled over seeds): bowl on the table, door shut / open; bowl in the
#: open microwave. Each has two legal skills.
SWEEP_STARTS: tuple[dict[str, str], ...] = ({}, {"door": "open"}, {"bowl": "microwave", "door": "open"})


def make_method_sampler(method: str, *, gd_ratio: float = 5.0, ss_ratio: float = 100.0) -> Sampler:
    """The sampler that makes ``method``'s plan (OP's is RS: its steering is the push, not the sampler).

    >>> make_method_sampler("DP-SS", ss_ratio=50.0)
    StochasticSampling(guide_ratio=50.0, min_guided_t=0, use_clipped_model_output=False, mcmc_steps=4)
    """
    one_of(method, "method", METHODS, owner="make_method_sampler")
    if method == "DP-GD":
        return GuidedDiffusion(guide_ratio=gd_ratio)
    if method == "DP-SS":
        return StochasticSampling(guide_ratio=ss_ratio, mcmc_steps=SS_MCMC_STEPS)
    return RandomSampling()


def make_env(task: str) -> Any:
    """The Kitchen env of a trial: ``task``, the scene camera rendered (depth for the clicks), fast rendering."""
    from steer_envs.envs.robosuite.kitchen import KitchenEnv

    return KitchenEnv(task=task, render_mode="rgb_array", fast_render=True)


_ENVS: LazyEnvs[str, Any] = LazyEnvs(make_env)


def env_for(task: str) -> Any:
    """This process's env of ``task`` for trials (made on first use, kept until :func:`close_envs`)."""
    return _ENVS.get(task)


def close_envs() -> None:
    """Close and forget the envs :func:`env_for` made."""
    _ENVS.close()


def _mode(env: Any) -> str:
    return str(env.task.modes[env._mode])


def encode_frame(image: np.ndarray, step: int) -> dict[str, Any]:
    """A camera frame kept in a JSON record: every ``step``-th pixel, base64 ``rgb`` and its ``shape``."""
    small = np.ascontiguousarray(image[::step, ::step])
    return {"shape": list(small.shape), "rgb": base64.b64encode(small.astype(np.uint8).tobytes()).decode("ascii")}


def decode_frame(frame: dict[str, Any]) -> np.ndarray:
    """The uint8 image of a kept frame (:func:`kitchen_trial` with ``keep_frames``).

    >>> decode_frame(encode_frame(np.full((4, 4, 3), 7, dtype=np.uint8), 2)).shape
    (2, 2, 3)
    """
    raw = base64.b64decode(frame["rgb"])
    return np.frombuffer(raw, dtype=np.uint8).reshape(tuple(frame["shape"]))


def steered_plan(
    env: Any,
    policy: Any,
    obs: Any,
    method: str,
    point: Any,
    sampler: Sampler,
    batch: int,
    generator: np.random.Generator,
    *,
    op_distance: float = 0.15,
) -> tuple[np.ndarray, Any, float]:
    """``method``'s plan for a click at world ``point``: ``(plan, observation it starts from, latency ms)``.

    ``sampler``: :func:`make_method_sampler` of ``method``. RS ignores the
    point; GD and SS are steered by ``Point(point)`` on the xyz dims; OP
    pushes the end effector (``env.unwrapped.perturb``) toward the point by
    ``op_distance`` m (less when nearer) and samples unsteered from there.
    """
    from steer_envs.core.interaction import Point
    from steer_envs.envs.robosuite.kitchen import push_toward

    base = env.unwrapped
    target = np.asarray(point, dtype=np.float64).reshape(3)
    t0 = time.perf_counter()
    if method == "DP-OP":
        push_toward(base, target, op_distance)
        obs = base._obs()
        result = sampler(policy, obs, None, batch, generator=generator)
    elif method == "DP-RS":
        result = sampler(policy, obs, None, batch, generator=generator)
    else:
        result = sampler(policy, obs, Point(target, dim=3), batch, generator=generator)
    return np.asarray(result.plan), obs, (time.perf_counter() - t0) * 1e3


@dataclass(frozen=True)
class _Rollout:
    """What every skill boundary of one :func:`kitchen_trial` shares."""

    seed: int
    policy: Any
    method: str
    sampler: Sampler
    batch: int
    op_distance: float
    keep_frames: bool
    frame_step: int
    execution: str


@dataclass(frozen=True)
class _Boundary:
    """One skill boundary's outcome: the observation after, the executed skill, and the interaction if any."""

    obs: Any
    executed: str | None
    success: bool
    row: dict[str, Any] | None
    frame: dict[str, Any] | None


def _row(
    outcome: Any, watched: Any, click: Any, planned: Any, aligned: bool, success: bool, ms: float
) -> dict[str, Any]:
    return {
        "mode": outcome.mode_before,
        "watched": watched,
        "intended": click.skill,
        "planned": planned,
        "executed": outcome.executed,
        "mode_after": outcome.mode_after,
        "violation": outcome.violation,
        "aligned": aligned,
        "success": success,
        "valid": planned is not None,
        "executed_ok": planned is not None and outcome.executed == planned and success,
        "regrasps": outcome.regrasps,
        "pixel": list(click.pixel),
        "point": np.round(click.point, 4).tolist(),
        "click_error": round(click.error, 4),
        "latency_ms": ms,
    }


def _frame(
    base: Any, image: np.ndarray, plan: np.ndarray, step: int, click: Any, row: dict[str, Any]
) -> dict[str, Any]:
    """The camera frame before an interaction with the click and the run plan projected into it."""
    uv = [base.world_to_pixel(p)[:2] / step for p in plan[:, :3]]
    return {
        **encode_frame(image, step),
        "pixel": [c / step for c in click.pixel],
        "plan_uv": np.round(np.asarray(uv), 2).tolist(),
        "grip": np.round(plan[:, 4], 2).tolist(),
        **{key: row[key] for key in ("watched", "intended", "planned", "aligned", "success")},
    }


def _boundary(base: Any, run: _Rollout, obs: Any, user: Any, k: int, steer: bool) -> _Boundary:
    """Skill boundary ``k``: watch an RS sample, let the user click (when ``steer``), run the plan."""
    from steer_envs.control.kitchen import classify_kitchen_plan, execute_kitchen_plan

    rng_watch, rng_method = np.random.default_rng([run.seed, k, 0]), np.random.default_rng([run.seed, k, 1])
    watched_plan = RandomSampling()(run.policy, obs, None, run.batch, generator=rng_watch).plan
    watched = classify_kitchen_plan(base, watched_plan)
    click = user.act(base, watched) if steer else None
    image = base.render() if click is not None and run.keep_frames else None
    latency, plan = 0.0, watched_plan
    if click is not None:
        args = (base, run.policy, obs, run.method, click.point, run.sampler, run.batch, rng_method)
        plan, obs, latency = steered_plan(*args, op_distance=run.op_distance)
    planned = classify_kitchen_plan(base, plan)
    outcome = execute_kitchen_plan(base, plan, execution=run.execution)
    success = bool(outcome.success and (outcome.mode_before, outcome.mode_after) in base.task.transitions)
    row = frame = None
    if click is not None:
        aligned = (planned if planned is not None else outcome.executed) == click.skill
        row = _row(outcome, watched, click, planned, aligned, success, latency)
        if image is not None:
            frame = _frame(base, image, plan, run.frame_step, click, row)
    return _Boundary(outcome.obs, outcome.executed, success, row, frame)


def _kitchen_metrics(rows: list[dict[str, Any]], goal: bool, skills: int) -> dict[str, float | None]:
    n = len(rows)
    valid = [r for r in rows if r["valid"]]
    return {
        **quadrant_shares([r["aligned"] for r in rows], [r["success"] for r in rows]),
        "valid": float(np.mean([r["valid"] for r in rows])) if n else None,
        "executed_ok": float(np.mean([r["executed_ok"] for r in valid])) if valid else None,
        "goal": float(goal),
        "skills": float(skills),
        "interactions": float(n),
        "latency_ms": float(np.mean([r["latency_ms"] for r in rows])) if n else None,
    }


def _rollout(base: Any, run: _Rollout, max_skills: int, max_interactions: int) -> dict[str, Any]:
    """The skill-level rollout from the reset scene: its interactions, executed skills and kept frames."""
    from steer_envs.users.kitchen_clicker import KitchenClickUser

    obs, _ = base.reset(seed=SCENE_SEED_OFFSET + run.seed)
    user = KitchenClickUser(run.seed)
    rows: list[dict[str, Any]] = []
    kept: list[dict[str, Any]] = []
    skills: list[str | None] = []
    for k in range(max_skills):
        mode = _mode(base)
        if mode in base.task.goal or mode == "lost":
            break
        step = _boundary(base, run, obs, user, k, steer=len(rows) < max_interactions)
        obs = step.obs
        skills.append(step.executed)
        if step.row is not None:
            rows.append(step.row)
        if step.frame is not None:
            kept.append(step.frame)
        if not step.success:
            break
    goal = _mode(base) in base.task.goal
    if run.keep_frames:
        end = base.render()
        if end is not None:
            kept.append({**encode_frame(end, run.frame_step), "end": True, "goal": goal})
    return {"rows": rows, "skills": skills, "frames": kept, "goal": goal}


def kitchen_trial(
    seed: int,
    policy: Any,
    method: str,
    *,
    tasks: Sequence[str] = DEFAULT_TASKS,
    batch: int = 32,
    max_interactions: int = 4,
    max_skills: int = 6,
    gd_ratio: float = 5.0,
    ss_ratio: float = 100.0,
    op_distance: float = 0.15,
    keep_frames: bool = False,
    frame_step: int = 2,
    env: Any = None,
    execution: str = "open_loop",
) -> tuple[dict[str, float | None], dict[str, Any]]:
    """One steered rollout of ``method`` from evaluation scene ``seed``: ``(metrics, extra)`` (module docstring).

    ``env``: a Kitchen env made by :func:`make_env` to reuse (its task must be
    the seed's); None builds one and closes it after. ``keep_frames`` keeps
    the camera frame before every interaction (subsampled by ``frame_step``)
    with the click and the run plan projected into it, for a rollout strip.
    ``execution``: how the plans run on the arm, ``"open_loop"`` or ``"closed_loop"``
    (:data:`~steer_envs.control.plans.EXECUTIONS`).
    """
    from steer_envs.control.plans import check_execution

    owner = "kitchen_trial"
    seed = integer(seed, "seed", low=0, owner=owner)
    if isinstance(tasks, str) or not tasks:
        raise ValueError(f"{owner}: `tasks` must be a non-empty sequence of task names, got {tasks!r}")
    task = tasks[seed % len(tasks)]
    batch = integer(batch, "batch", low=1, high=4096, owner=owner)
    max_interactions = integer(max_interactions, "max_interactions", low=0, high=100, owner=owner)
    max_skills = integer(max_skills, "max_skills", low=1, high=100, owner=owner)
    op_distance = real_scalar(op_distance, "op_distance", low=0.0, high=1.0, owner=owner)
    frame_step = integer(frame_step, "frame_step", low=1, high=16, owner=owner)
    execution = check_execution(execution, owner)
    sampler = make_method_sampler(method, gd_ratio=gd_ratio, ss_ratio=ss_ratio)
    run = _Rollout(seed, policy, method, sampler, batch, op_distance, keep_frames, frame_step, execution)
    own_env = env is None
    env = make_env(task) if own_env else env
    base = env.unwrapped
    if base.kitchen_task != task:
        raise ValueError(f"{owner}: `env` has task {base.kitchen_task!r}; seed {seed} needs {task!r}")
    try:
        done = _rollout(base, run, max_skills, max_interactions)
    finally:
        if own_env:
            env.close()
    extra: dict[str, Any] = {"task": task, "interactions": done["rows"], "skills": done["skills"]}
    if keep_frames:
        extra["frames"] = done["frames"]
    return _kitchen_metrics(done["rows"], done["goal"], len(done["skills"])), extra


def _sweep_scene(base: Any, policy: Any, s: int, start: dict[str, str], batch: int) -> tuple[Any, Any, Any]:
    """Scene ``s`` reset into ``start``: ``(obs, the user's click or None, the watched skill)``."""
    from steer_envs.control.kitchen import classify_kitchen_plan
    from steer_envs.users.kitchen_clicker import KitchenClickUser

    obs, _ = base.reset(seed=SCENE_SEED_OFFSET + s, options=dict(start))
    watched = classify_kitchen_plan(
        base, RandomSampling()(policy, obs, None, batch, generator=np.random.default_rng([s, 0])).plan
    )
    return obs, KitchenClickUser(s).act(base, watched), watched


def _check_sweep(
    ratios: Any, seeds: Any, batch: Any, methods: Sequence[str], starts: Any
) -> tuple[list[float], int, int, list[int]]:
    owner = "guide_ratio_sweep"
    if isinstance(ratios, str) or not isinstance(ratios, Sequence) or not ratios:
        raise ValueError(f"{owner}: `ratios` must be a non-empty sequence of reals >= 0, got {ratios!r}")
    values = [real_scalar(r, "ratios", low=0.0, owner=owner) for r in ratios]
    seeds = integer(seeds, "seeds", low=1, high=1000, owner=owner)
    batch = integer(batch, "batch", low=1, high=4096, owner=owner)
    for m in methods:
        one_of(m, "methods", ("DP-GD", "DP-SS"), owner=owner)
    if isinstance(starts, str) or not isinstance(starts, Sequence) or not starts:
        raise ValueError(f"{owner}: `starts` must be a non-empty sequence of indices into SWEEP_STARTS, got {starts!r}")
    start_list = [integer(i, "starts", low=0, high=len(SWEEP_STARTS) - 1, owner=owner) for i in starts]
    return values, seeds, batch, start_list


def guide_ratio_sweep(
    policy: Any,
    ratios: Sequence[float],
    *,
    seeds: int = 3,
    batch: int = 16,
    methods: Sequence[str] = ("DP-GD", "DP-SS"),
    env: Any = None,
    starts: Sequence[int] = (0, 1, 2),
) -> dict[str, Any]:
    """Thesis Fig. 2.10: per method and guide ratio, the share of the batch doing the user's intended skill.

    Scene ``s`` (of ``seeds``) is evaluation scene ``s`` reset with
    :data:`SWEEP_STARTS` ``[starts[s % len(starts)]]`` (``starts=(0,)``: the
    task's start state only, the one state every training plan set shares); the user watches an RS sample and clicks
    another legal skill, as in :func:`kitchen_trial`, then every ratio of every
    method samples a batch (the same noise across ratios). Returns
    ``{"ratios": [...], "share": {method: [mean share per ratio]}, "scenes": [...], "batch": batch}``.
    """
    from steer_envs.control.kitchen import classify_kitchen_plan

    values, seeds, batch, start_list = _check_sweep(ratios, seeds, batch, methods, starts)
    own_env = env is None
    env = make_env("microwave") if own_env else env
    base = env.unwrapped
    shares: dict[str, list[list[float]]] = {m: [[] for _ in values] for m in methods}
    scenes: list[dict[str, Any]] = []
    try:
        for s in range(seeds):
            obs, click, watched = _sweep_scene(base, policy, s, SWEEP_STARTS[start_list[s % len(start_list)]], batch)
            if click is None:
                continue
            scenes.append({"mode": _mode(base), "watched": watched, "intended": click.skill})
            for m in methods:
                for i, ratio in enumerate(values):
                    sampler = make_method_sampler(m, gd_ratio=ratio, ss_ratio=ratio)
                    res = sampler(policy, obs, click.interaction, batch, generator=np.random.default_rng([s, 1]))
                    kinds = [classify_kitchen_plan(base, p) for p in res.plans]
                    shares[m][i].append(float(np.mean([kind == click.skill for kind in kinds])))
    finally:
        if own_env:
            env.close()
    mean = {m: [float(np.mean(v)) if v else float("nan") for v in shares[m]] for m in methods}
    return {"ratios": values, "share": mean, "scenes": scenes, "batch": batch}
