"""One ITPS Kitchen trial: a skill-level rollout that a clicking user steers toward skills it did not watch.

:func:`kitchen_trial` resets Kitchen at an evaluation scene
(``SCENE_SEED_OFFSET + seed``: never a training scene) and rolls the frozen
skill policy out one skill at a time with re-planning: at every skill
boundary a batch of whole-skill plans is sampled conditioned on the current
observation, the chosen plan runs open-loop on the arm
(:func:`~steer_envs.envs.robosuite.kitchen_plan_execution.execute_kitchen_plan`),
and this repeats until the task's goal, a failed skill, or ``max_skills``.

At each of the first ``max_interactions`` skill boundaries the simulated user
(:class:`~steer_envs.users.kitchen_clicker.KitchenClickUser`) watches an
unsteered (RS) sample, wants a different legal skill, and clicks its target in
the scene camera (a :class:`~steer_envs.core.interaction.Point` on the plan's
xyz). The method then makes the plan (thesis Table 2.3's columns):

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
  (:func:`~steer_envs.envs.robosuite.kitchen_plan_execution.classify_kitchen_plan`);
  where the plan reads as no skill, the world's mode change decides (a plan
  heading for another skill that knocks the door open is not aligned);
* *success* (CS): the executed skill happened (a mode change some skill makes),
  no constraint was violated, and the change is a transition of the task's tree
  (a placement into a shut microwave, a moved door while holding the bowl, a
  dropped bowl are failures).

Default task: the thesis's merged setting, ``tasks[seed % 2]`` with
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
import functools
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from steer_envs.bench.suite import TrialResult, resolve_function
from steer_envs.core.validation import integer, one_of, real_scalar

__all__ = [
    "DEFAULT_TASKS",
    "METHODS",
    "POLICY_UNAVAILABLE",
    "SCENE_SEED_OFFSET",
    "SWEEP_STARTS",
    "close_envs",
    "decode_frame",
    "env_for",
    "guide_ratio_sweep",
    "kitchen_trial",
    "load_kitchen_policy",
    "make_env",
    "make_method_sampler",
    "steered_plan",
]

#: exceptions that mean "the policy is not available (yet)": module, function or checkpoint missing
POLICY_UNAVAILABLE: tuple[type[Exception], ...] = (ImportError, AttributeError, FileNotFoundError)
#: evaluation scenes are reset seeds SCENE_SEED_OFFSET + seed (the skill data uses seeds 0..N-1).
SCENE_SEED_OFFSET = 100_000
#: the thesis's two tasks, merged: seed s rolls out task DEFAULT_TASKS[s % 2].
DEFAULT_TASKS = ("microwave", "sink")
#: Table 2.3's columns.
METHODS = ("DP-RS", "DP-GD", "DP-SS", "DP-OP")
#: SS's MCMC iterations per noise level (ITPS: 4).
SS_MCMC_STEPS = 4
#: the reset options of the sweep's scenes (cycled over seeds): bowl on the table, door shut / open; bowl in the
#: open microwave. Each has two legal skills.
SWEEP_STARTS: tuple[dict[str, str], ...] = ({}, {"door": "open"}, {"bowl": "microwave", "door": "open"})


@functools.lru_cache(maxsize=2)
def load_kitchen_policy(loader: str, checkpoint: str = "") -> Any:
    """The frozen skill policy from a checkpoint file or a ``"module:function"`` loader (cached per process).

    A checkpoint file wins (loaded by :func:`steer_envs.baselines.pretrained.load_kitchen`,
    ``interaction_dims = (0, 1, 2)``); the loader is called without arguments.
    Raises one of :data:`POLICY_UNAVAILABLE` while the policy is not available.
    """
    if checkpoint:
        from steer_envs.baselines.pretrained import load_kitchen

        return load_kitchen(checkpoint=checkpoint)
    policy = resolve_function(loader)()
    from steer_envs.core.policy import TrajectoryPolicy

    if not isinstance(policy, TrajectoryPolicy):
        raise TypeError(f"{loader}() must return a TrajectoryPolicy, got {type(policy).__name__}")
    return policy


def make_method_sampler(method: str, *, gd_ratio: float = 5.0, ss_ratio: float = 100.0) -> Any:
    """The sampler that makes ``method``'s plan (OP's is RS: its steering is the push, not the sampler)."""
    from steer_envs.wrappers.samplers import GuidedDiffusion, RandomSampling, StochasticSampling

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


_ENVS: dict[str, Any] = {}


def env_for(task: str) -> Any:
    """This process's env of ``task`` for trials (made on first use, kept until :func:`close_envs`)."""
    if task not in _ENVS:
        _ENVS[task] = make_env(task)
    return _ENVS[task]


def close_envs() -> None:
    """Close and forget the envs :func:`env_for` made."""
    while _ENVS:
        _ENVS.popitem()[1].close()


def _mode(env: Any) -> str:
    return str(env.task.modes[env._mode])


def _encode_frame(image: np.ndarray, step: int) -> dict[str, Any]:
    small = np.ascontiguousarray(image[::step, ::step])
    return {"shape": list(small.shape), "rgb": base64.b64encode(small.astype(np.uint8).tobytes()).decode("ascii")}


def decode_frame(frame: dict[str, Any]) -> np.ndarray:
    """The uint8 image of a kept frame (:func:`kitchen_trial` with ``keep_frames``)."""
    raw = base64.b64decode(frame["rgb"])
    return np.frombuffer(raw, dtype=np.uint8).reshape(tuple(frame["shape"]))


def steered_plan(
    env: Any,
    policy: Any,
    obs: Any,
    method: str,
    point: Any,
    sampler: Any,
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
) -> TrialResult:
    """One steered rollout of ``method`` from evaluation scene ``seed`` (see the module docstring).

    ``env``: a Kitchen env made by :func:`make_env` to reuse (its task must be
    the seed's); None builds one and closes it after. ``keep_frames`` keeps
    the camera frame before every interaction (subsampled by ``frame_step``)
    with the click and the run plan projected into it, for the rollout strip.
    """
    from steer_envs.envs.robosuite.kitchen_plan_execution import classify_kitchen_plan, execute_kitchen_plan
    from steer_envs.users.kitchen_clicker import KitchenClickUser
    from steer_envs.wrappers.samplers import RandomSampling

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
    sampler = make_method_sampler(method, gd_ratio=gd_ratio, ss_ratio=ss_ratio)
    watch = RandomSampling()
    own_env = env is None
    env = make_env(task) if own_env else env
    base = env.unwrapped
    if base.kitchen_task != task:
        raise ValueError(f"{owner}: `env` has task {base.kitchen_task!r}; seed {seed} needs {task!r}")
    rows: list[dict[str, Any]] = []
    kept: list[dict[str, Any]] = []
    skills: list[str | None] = []
    try:
        obs, _ = base.reset(seed=SCENE_SEED_OFFSET + seed)
        user = KitchenClickUser(seed)
        for k in range(max_skills):
            mode = _mode(base)
            if mode in base.task.goal or mode == "lost":
                break
            rng_watch, rng_method = np.random.default_rng([seed, k, 0]), np.random.default_rng([seed, k, 1])
            watched_plan = watch(policy, obs, None, batch, generator=rng_watch).plan
            watched = classify_kitchen_plan(base, watched_plan)
            click = user.act(base, watched) if len(rows) < max_interactions else None
            image = base.render() if click is not None and keep_frames else None
            latency = 0.0
            if click is None:
                plan = watched_plan
            else:
                plan, obs, latency = steered_plan(
                    base, policy, obs, method, click.point, sampler, batch, rng_method, op_distance=op_distance
                )
            planned = classify_kitchen_plan(base, plan)
            outcome = execute_kitchen_plan(base, plan)
            obs = outcome.obs
            legal = (outcome.mode_before, outcome.mode_after) in base.task.transitions
            success = bool(outcome.success and legal)
            skills.append(outcome.executed)
            if click is not None:
                aligned = (planned if planned is not None else outcome.executed) == click.skill
                rows.append(
                    {
                        "mode": outcome.mode_before,
                        "watched": watched,
                        "intended": click.skill,
                        "planned": planned,
                        "executed": outcome.executed,
                        "mode_after": outcome.mode_after,
                        "violation": outcome.violation,
                        "aligned": aligned,
                        "success": success,
                        "pixel": list(click.pixel),
                        "point": np.round(click.point, 4).tolist(),
                        "click_error": round(click.error, 4),
                        "latency_ms": latency,
                    }
                )
                if image is not None:
                    uv = [base.world_to_pixel(p)[:2] / frame_step for p in plan[:, :3]]
                    kept.append(
                        {
                            **_encode_frame(image, frame_step),
                            "pixel": [c / frame_step for c in click.pixel],
                            "plan_uv": np.round(np.asarray(uv), 2).tolist(),
                            "grip": np.round(plan[:, 4], 2).tolist(),
                            "watched": watched,
                            "intended": click.skill,
                            "planned": planned,
                            "aligned": aligned,
                            "success": success,
                        }
                    )
            if not success:
                break
        goal = _mode(base) in base.task.goal
        if keep_frames:
            end = base.render()
            if end is not None:
                kept.append({**_encode_frame(end, frame_step), "end": True, "goal": goal})
    finally:
        if own_env:
            env.close()
    n = len(rows)
    aligned_arr = np.array([r["aligned"] for r in rows], dtype=bool)
    success_arr = np.array([r["success"] for r in rows], dtype=bool)

    def share(mask: np.ndarray) -> float | None:
        return float(mask.mean()) if n else None

    metrics = {
        "TA": share(aligned_arr),
        "CS": share(success_arr),
        "AS": share(aligned_arr & success_arr),
        "AF": share(aligned_arr & ~success_arr),
        "MS": share(~aligned_arr & success_arr),
        "MF": share(~aligned_arr & ~success_arr),
        "goal": float(goal),
        "skills": float(len(skills)),
        "interactions": float(n),
        "latency_ms": float(np.mean([r["latency_ms"] for r in rows])) if n else None,
    }
    extra: dict[str, Any] = {"task": task, "interactions": rows, "skills": skills}
    if keep_frames:
        extra["frames"] = kept
    return TrialResult(metrics, extra)


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
    ``{"ratios": [...], "share": {method: [mean share per ratio]}, "scenes": [...]}``.
    """
    from steer_envs.envs.robosuite.kitchen_plan_execution import classify_kitchen_plan
    from steer_envs.users.kitchen_clicker import KitchenClickUser
    from steer_envs.wrappers.samplers import RandomSampling

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
    own_env = env is None
    env = make_env("microwave") if own_env else env
    base = env.unwrapped
    shares: dict[str, list[list[float]]] = {m: [[] for _ in values] for m in methods}
    scenes: list[dict[str, Any]] = []
    try:
        for s in range(seeds):
            start = SWEEP_STARTS[start_list[s % len(start_list)]]
            obs, _ = base.reset(seed=SCENE_SEED_OFFSET + s, options=dict(start))
            watched = classify_kitchen_plan(
                base, RandomSampling()(policy, obs, None, batch, generator=np.random.default_rng([s, 0])).plan
            )
            click = KitchenClickUser(s).act(base, watched)
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
