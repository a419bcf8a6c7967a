"""GLiDE on PolygonNav as pure trial functions (for the ``glide-polygon*`` steer-bench suites).

* :func:`grounding_trial` -- learn the modes of one PolygonNav layout with one
  variant (the full loss, or an ablation: no counterfactuals, a wrong
  feasibility matrix, no prediction loss, k-means++) and measure the overlap
  of the learned modes with the ground truth on a 200 x 200 grid.
* :func:`policy_trial` -- success rate of BC, GLiDE+BC or GLiDE+Planning over
  ``n_rollouts`` episodes, with or without the evaluation perturbations
  (:class:`PerturbationSchedule`: after the first mode change, with
  probability 0.03 per step, at least 100 steps apart and at most 3 times per
  episode, the agent is teleported to a uniform free-space point).

The demonstrations of every method go on into the goal polygon for up to
``GlideSetup.demo_goal_steps`` steps (the expert walks to its centroid): the
env ends an episode on entering the goal, and a demo that stops there shows
the classifier nothing of the goal polygon but a point behind its entry edge
(the perturbed replays start and end where their demo does).

Both return plain JSON-able dicts and are deterministic given their
arguments. Trained classifiers and data sets can be cached in ``cache_dir``
(safetensors / npz, written atomically) so the perturbed and unperturbed
columns of a table reuse one classifier.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

import steer_envs  # noqa: F401  (registers the envs)
from steer_envs.baselines.glide.classifier import (
    GlideLossWeights,
    GlideTrainConfig,
    ModeClassifier,
    ModePredictor,
    mode_iou,
    mode_overlap,
    train_mode_classifier,
    workspace_grid,
)
from steer_envs.baselines.glide.kmeans import KMeansSegmentation
from steer_envs.baselines.glide.mode_policies import GlideBCConfig, GlideBCPolicy, GlidePlanningPolicy, train_bc
from steer_envs.baselines.glide.planners import PlannerConfig
from steer_envs.core.validation import integer, real_scalar
from steer_envs.data.counterfactual_dataset import CounterfactualDataset, build_counterfactual_dataset
from steer_envs.data.demos import Demonstration, collect_demonstrations
from steer_envs.io import CheckpointError, DatasetError

VARIANTS: tuple[str, ...] = ("full", "no_counterfactuals", "wrong_feasibility", "no_prediction_loss", "kmeans")
METHODS: tuple[str, ...] = ("bc", "glide_bc", "glide_planning")
#: where evaluation episodes start (:func:`evaluate_policy`)
EVAL_STARTS: tuple[str, ...] = ("free", "first_mode")
ENV_IDS: tuple[str, ...] = tuple(f"steer_envs/PolygonNav-{k}Mode-v0" for k in (3, 4, 5))

#: thesis Table 4.1 (success rates; "+perturb" in brackets there).
THESIS_TABLE_4_1: dict[str, dict[int, tuple[float, float]]] = {
    "bc": {3: (0.967, 0.908), 4: (0.814, 0.614), 5: (0.810, 0.596)},
    "glide_bc": {3: (0.963, 0.887), 4: (0.892, 0.753), 5: (0.893, 0.753)},
    "glide_planning": {3: (0.996, 0.996), 4: (0.987, 0.966), 5: (0.991, 0.974)},
}


@dataclass(frozen=True)
class GlideSetup:
    """Everything a trial depends on besides (env, layout, variant/method, seed).

    Replays and heads: a jump replay adds about one distinct state (its ``Z``) to the data, and
    training time grows with the distinct states times the heads, so many replays with few heads
    (``train``: 5, the best 2 after pruning) cover the workspace densely at the cost of fewer
    replays with more heads. Where no replay's ``Z`` landed, the learned modes are guesses.

    >>> GlideSetup().train.n_heads, GlideSetup().bc.steps, GlideSetup(n_demos=3).n_demos
    (5, 1500, 3)
    """

    n_demos: int = 7
    #: the demos go on into the goal polygon for up to this many steps (the expert walks to its
    #: centroid; 0: they end on entering it, where the env ends the episode). Every replay ends
    #: where its demo ends, so this is what shows the classifier the goal polygon's interior.
    demo_goal_steps: int = 30
    n_success: int = 1000
    n_failure: int = 1000
    kind: str = "segment"
    execution: str = "jump"
    feasibility_convention: str = "shortest_path"
    #: L_fail x 10 instead of the public x 1: with x 1 the classifier can settle where the first polygon
    #: swallows free space (free <-> p1 moves are free, so only failures can push back).
    weights: GlideLossWeights = field(default_factory=lambda: GlideLossWeights(fail=10.0))
    #: the classifier's training: the library defaults (5 heads, the best 2 after pruning)
    train: GlideTrainConfig = field(default_factory=GlideTrainConfig)
    #: BC and GLiDE+BC's per-mode policies
    bc: GlideBCConfig = field(default_factory=GlideBCConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    grid_resolution: int = 200

    #: the fields the perturbation data set depends on (its cache key)
    DATA_FIELDS: ClassVar[tuple[str, ...]] = (
        "n_demos",
        "demo_goal_steps",
        "n_success",
        "n_failure",
        "kind",
        "execution",
    )
    #: the fields a trained classifier depends on (its cache key)
    CLASSIFIER_FIELDS: ClassVar[tuple[str, ...]] = (*DATA_FIELDS, "feasibility_convention", "weights", "train")

    def key(self, *parts: Any, fields: Sequence[str] | None = None) -> str:
        """A short hash of ``fields`` of this setup (default: all) and ``parts`` (cache file names).

        How training runs (threads, progress bar) is left out: it does not change the result.
        """
        everything = asdict(self)
        chosen = {name: everything[name] for name in (fields if fields is not None else everything)}
        if isinstance(chosen.get("train"), dict):
            for name in ("num_threads", "progress"):
                chosen["train"].pop(name, None)
        if isinstance(chosen.get("bc"), dict):
            chosen["bc"].pop("num_threads", None)
        blob = json.dumps([chosen, [str(p) for p in parts]], sort_keys=True, default=str)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class PerturbationSchedule:
    """Evaluation perturbations: teleports to uniform free-space points (see the module docstring).

    >>> PerturbationSchedule(), PerturbationSchedule(probability=0.1).min_gap
    (PerturbationSchedule(probability=0.03, min_gap=100, max_count=3), 100)
    """

    probability: float = 0.03
    min_gap: int = 100
    max_count: int = 3

    def __post_init__(self) -> None:
        real_scalar(self.probability, "probability", low=0.0, high=1.0, owner="PerturbationSchedule")
        integer(self.min_gap, "min_gap", low=0, owner="PerturbationSchedule")
        integer(self.max_count, "max_count", low=0, owner="PerturbationSchedule")


# ------------------------------------------------------------------------------ helpers
def _check_env_id(env_id: str) -> int:
    if env_id not in ENV_IDS:
        raise ValueError(f"env_id must be one of {ENV_IDS}, got {env_id!r}")
    return int(env_id.split("-")[1][0])


def _check_int(name: str, value: Any, low: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name} must be an int >= {low}, got {value!r}")
    return int(value)


def demonstrations(env_id: str, layout_seed: int, n: int, seed: int, *, goal_steps: int = 0) -> list[Demonstration]:
    """``n`` expert demos of one layout; demo start states are drawn from ``seed``.

    ``goal_steps > 0``: each demo goes on for up to that many steps after entering the goal
    polygon, the expert walking to the polygon's centroid (see ``GlideSetup.demo_goal_steps``).
    """
    goal_steps = _check_int("goal_steps", goal_steps)
    return collect_demonstrations(
        env_id,
        n,
        seed=1000 * int(seed),
        steps_after_success=goal_steps,
        expert_kwargs={"final_target": "centroid"} if goal_steps else None,
        layout_seed=int(layout_seed),
    )


def data_cache_path(
    env_id: str, layout_seed: int, seed: int, setup: GlideSetup, cache_dir: str | os.PathLike[str] | None
) -> Path | None:
    """Where :func:`counterfactual_data` caches the data set of one (env, layout, seed) (None: no cache)."""
    if cache_dir is None:
        return None
    key = setup.key(env_id, layout_seed, seed, "data", fields=GlideSetup.DATA_FIELDS)
    return Path(cache_dir) / f"glide-data-{key}.npz"


def counterfactual_data(
    env_id: str,
    layout_seed: int,
    seed: int,
    setup: GlideSetup,
    demos: Sequence[Demonstration],
    cache_dir: str | os.PathLike[str] | None = None,
) -> CounterfactualDataset:
    """The balanced perturbation data set of one (env, layout, seed), cached when ``cache_dir`` is set."""
    path = data_cache_path(env_id, layout_seed, seed, setup, cache_dir)
    if path is not None and path.exists():
        try:
            return CounterfactualDataset.load(path)
        except DatasetError as err:  # a corrupt cache entry is a miss: rebuild and overwrite it
            warnings.warn(f"rebuilding the cached counterfactual data: {err}", RuntimeWarning, stacklevel=2)
    data = build_counterfactual_dataset(
        env_id,
        [d.states for d in demos],
        n_success=setup.n_success,
        n_failure=setup.n_failure,
        kind=setup.kind,
        execution=setup.execution,
        seed=int(seed),
        layout_seed=int(layout_seed),
    )
    if path is not None:
        data.save(path)
    return data


def feasibility_for(env_id: str, layout_seed: int, variant: str, convention: str) -> np.ndarray:
    """The feasibility matrix a variant trains with (``wrong_feasibility``: a plan one mode short)."""
    env = gym.make(env_id, layout_seed=int(layout_seed))
    try:
        feas = env.unwrapped.task.feasibility_matrix(convention)  # type: ignore[attr-defined]
    finally:
        env.close()
    return feas[:-1, :-1] if variant == "wrong_feasibility" else feas


@dataclass
class Grounding:
    """A learned grounding (classifier or baseline) and how it was made."""

    predictor: ModePredictor
    demos: list[Demonstration]
    info: dict[str, Any]


def learn_grounding(
    env_id: str,
    layout_seed: int,
    variant: str,
    seed: int,
    *,
    setup: GlideSetup | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
) -> Grounding:
    """Demos -> (perturbation data) -> classifier for one variant (cached in ``cache_dir``)."""
    k = _check_env_id(env_id)
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    layout_seed, seed = _check_int("layout_seed", layout_seed), _check_int("seed", seed)
    setup = setup or GlideSetup()
    demos = demonstrations(env_id, layout_seed, setup.n_demos, seed, goal_steps=setup.demo_goal_steps)
    info: dict[str, Any] = {"n_demos": len(demos), "data_seconds": 0.0, "train_seconds": 0.0}
    if variant == "kmeans":
        start = time.perf_counter()
        km = KMeansSegmentation(k, seed=seed).fit([d.states for d in demos])
        info["train_seconds"] = time.perf_counter() - start
        return Grounding(km, demos, info)
    weights = setup.weights.without("succ", "fail") if variant == "no_prediction_loss" else setup.weights
    feas = feasibility_for(env_id, layout_seed, variant, setup.feasibility_convention)
    train_config = GlideTrainConfig(**{**asdict(setup.train), "seed": seed})
    cache = None
    if cache_dir is not None:
        key = setup.key(env_id, layout_seed, seed, variant, fields=GlideSetup.CLASSIFIER_FIELDS)
        cache = Path(cache_dir) / f"glide-clf-{key}.safetensors"
        if cache.exists():
            try:
                clf = ModeClassifier.load(cache)
                meta = clf_meta(cache)
            except CheckpointError as err:  # a corrupt cache entry is a miss: retrain and overwrite it
                warnings.warn(f"retraining the cached classifier: {err}", RuntimeWarning, stacklevel=2)
            else:
                return Grounding(clf, demos, {**info, **meta, "cached": True})
    if variant == "no_counterfactuals":
        trajectories = [d.states for d in demos]
        labels = np.ones(len(demos), dtype=bool)
    else:
        cached_data = data_cache_path(env_id, layout_seed, seed, setup, cache_dir)
        info["data_cached"] = cached_data is not None and cached_data.exists()
        start = time.perf_counter()
        data = counterfactual_data(env_id, layout_seed, seed, setup, demos, cache_dir)
        info["data_seconds"] = time.perf_counter() - start
        info["raw_success_rate"] = data.meta.get("raw_success_rate")
        trajectories, labels = data.trajectories(), data.success
    load = os.getloadavg()[0]
    result = train_mode_classifier(trajectories, labels, feas, weights=weights, config=train_config)
    info.update(
        train_seconds=result.seconds,
        load_avg=[load, os.getloadavg()[0]],
        head_losses=result.head_losses,
        best_head=result.classifier.head,
        n_trajectories=len(trajectories),
        num_modes_trained=int(feas.shape[0]),
    )
    if cache is not None:
        result.classifier.save(cache, extra=info)
    return Grounding(result.classifier, demos, info)


def clf_meta(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The training info stored with a cached classifier."""
    from safetensors import safe_open

    with safe_open(str(path), framework="pt") as fh:
        meta = json.loads((fh.metadata() or {})["glide_classifier"])
    return dict(meta.get("extra", {}))


# ------------------------------------------------------------------------------- trials
def grounding_trial(
    env_id: str,
    layout_seed: int,
    variant: str,
    seed: int,
    *,
    setup: GlideSetup | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
    keep_labels: bool = False,
) -> dict[str, Any]:
    """Overlap of one variant's learned modes with the ground truth (200 x 200 grid).

    Also reports the per-mode IoU (free space dominates the grid, so overlap
    alone is lenient: ``all_free_overlap`` is what labelling everything free
    scores), training time and the CPU load average around training.
    ``keep_labels`` adds the predicted grid labels (``"labels"``, an int array
    on :func:`~steer_envs.baselines.glide.classifier.workspace_grid`'s grid) and the demos'
    states (``"demo_states"``) for plots.

    >>> result = grounding_trial("steer_envs/PolygonNav-3Mode-v0", 0, "kmeans", 0, setup=GlideSetup(n_demos=2))
    >>> result["variant"], 0.0 <= result["overlap"] <= 1.0, len(result["iou"])
    ('kmeans', True, 3)
    """
    setup = setup or GlideSetup()
    k = _check_env_id(env_id)
    grounding = learn_grounding(env_id, layout_seed, variant, seed, setup=setup, cache_dir=cache_dir)
    env = gym.make(env_id, layout_seed=int(layout_seed))
    model = env.unwrapped.model  # type: ignore[attr-defined]
    env.close()
    grid = workspace_grid(model.low, model.high, setup.grid_resolution)
    truth = model.mode_of(grid)
    pred = np.asarray(grounding.predictor.predict(grid))
    iou = mode_iou(pred, truth, k)
    extra: dict[str, Any] = {}
    if keep_labels:
        extra = {"labels": pred.astype(np.int64), "demo_states": [d.states for d in grounding.demos]}
    return {
        "env_id": env_id,
        "num_modes": k,
        "layout_seed": int(layout_seed),
        "variant": variant,
        "seed": int(seed),
        "overlap": mode_overlap(pred, truth),
        "mean_iou": float(iou.mean()),
        "iou": [float(v) for v in iou],
        "all_free_overlap": mode_overlap(np.zeros_like(truth), truth),
        **grounding.info,
        **extra,
    }


def make_policy(
    method: str,
    env_id: str,
    layout_seed: int,
    seed: int,
    *,
    setup: GlideSetup | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
) -> tuple[Any, dict[str, Any]]:
    """A trained policy (BC, GLiDE+BC or GLiDE+Planning) and its training info."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    setup = setup or GlideSetup()
    k = _check_env_id(env_id)
    env = gym.make(env_id, layout_seed=int(layout_seed))
    base = env.unwrapped
    max_speed, low, high = float(base.max_speed * base.dt), base.model.low, base.model.high  # type: ignore[attr-defined]
    env.close()
    if method == "bc":
        demos = demonstrations(env_id, layout_seed, setup.n_demos, seed, goal_steps=setup.demo_goal_steps)
        states = np.concatenate([d.states[:-1] for d in demos])
        actions = np.concatenate([d.actions for d in demos])
        start = time.perf_counter()
        policy = train_bc(states, actions, max_speed=max_speed, seed=seed, config=setup.bc)
        return policy, {"train_seconds": time.perf_counter() - start}
    grounding = learn_grounding(env_id, layout_seed, "full", seed, setup=setup, cache_dir=cache_dir)
    demos = grounding.demos
    info = dict(grounding.info)
    if method == "glide_bc":
        policy = GlideBCPolicy(
            grounding.predictor,
            [d.states for d in demos],
            [d.actions for d in demos],
            k,
            max_speed=max_speed,
            seed=seed,
            config=setup.bc,
        )
    else:
        policy = GlidePlanningPolicy(
            grounding.predictor,
            [d.states for d in demos],
            k,
            low=low,
            high=high,
            max_speed=max_speed,
            seed=seed,
            config=setup.planner,
        )
    return policy, info


def evaluate_policy(
    policy: Any,
    env_id: str,
    layout_seed: int,
    *,
    n_rollouts: int,
    perturbed: bool,
    seed: int,
    schedule: PerturbationSchedule | None = None,
    max_steps: int | None = None,
    start: str = "free",
) -> dict[str, Any]:
    """Run ``n_rollouts`` episodes at once in the vector env; success = the env's success flag.

    ``max_steps`` caps each episode (None: the env's registered 500, the public env's nominal
    limit). An episode that ends neither in success nor in an invalid transition timed out
    (``timeout_rate``). ``start``: ``"free"`` (uniform in free space, the env's reset) or
    ``"first_mode"`` (uniform inside the first polygon, as if just entered from free space: the
    public polygon env's default reset; teleports may then come from the first step).
    """
    n = _check_int("n_rollouts", n_rollouts, 1)
    if start not in EVAL_STARTS:
        raise ValueError(f"start must be one of {EVAL_STARTS}, got {start!r}")
    schedule = schedule or PerturbationSchedule()
    horizon_kwargs: dict[str, Any] = (
        {} if max_steps is None else {"max_episode_steps": _check_int("max_steps", max_steps, 1)}
    )
    venv = gym.make_vec(
        env_id, num_envs=n, vectorization_mode="vector_entry_point", layout_seed=int(layout_seed), **horizon_kwargs
    )
    try:
        model = venv.unwrapped.model  # type: ignore[attr-defined]
        horizon = int(venv.unwrapped.max_episode_steps)  # type: ignore[attr-defined]
        obs, info = venv.reset(seed=int(seed))
        rng = np.random.default_rng([int(seed), 7])
        if start == "first_mode":
            obs, info = venv.reset(options={"state": model.sample_in_mode(rng, n, 1)})
        policy.reset()
        done = np.zeros(n, dtype=bool)
        success = np.zeros(n, dtype=bool)
        violation = np.zeros(n, dtype=bool)
        left_start = np.full(n, start == "first_mode")  # teleports start after the first mode change
        start_mode = np.asarray(info["mode"]).copy()
        last_push = np.full(n, -(10**9))
        pushes = np.zeros(n, dtype=np.int64)
        steps = np.zeros(n, dtype=np.int64)
        for t in range(horizon):
            action = np.asarray(policy.act(np.asarray(obs, dtype=np.float64)), dtype=np.float32)
            action[done] = 0.0
            obs, _, terminated, truncated, info = venv.step(action)
            live = ~done
            violation |= live & np.asarray(info["constraint_violation"], dtype=bool)
            ended = live & (np.asarray(terminated) | np.asarray(truncated))
            success |= ended & np.asarray(info["success"], dtype=bool)
            steps[live] += 1
            done |= ended
            if done.all():
                break
            left_start |= ~done & (np.asarray(info["mode"]) != start_mode)
            if perturbed:
                push = (
                    ~done
                    & left_start
                    & (t - last_push >= schedule.min_gap)
                    & (pushes < schedule.max_count)
                    & (rng.random(n) < schedule.probability)
                )
                if push.any():
                    targets = model.sample_start(rng, n)
                    venv.unwrapped.perturb(targets, push)  # type: ignore[attr-defined]
                    obs = np.where(push[:, None], targets.astype(np.float32), obs)
                    last_push[push] = t
                    pushes[push] += 1
    finally:
        venv.close()
    return {
        "success_rate": float(success.mean()),
        "n_success": int(success.sum()),
        "violation_rate": float(violation.mean()),
        "timeout_rate": float((~success & ~violation).mean()),
        "perturbations": int(pushes.sum()),
        "perturbed_episodes": int((pushes > 0).sum()),
        "mean_steps": float(steps.mean()),
    }


def policy_trial(
    env_id: str,
    layout_seed: int,
    method: str,
    perturbed: bool,
    n_rollouts: int,
    seed: int,
    *,
    setup: GlideSetup | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
    max_steps: int | None = None,
    start: str = "free",
) -> dict[str, Any]:
    """Success rate of one method on one layout (thesis Table 4.1 cell; ``seed`` seeds training and rollouts)."""
    k = _check_env_id(env_id)
    if not isinstance(perturbed, (bool, np.bool_)):
        raise TypeError(f"perturbed must be a bool, got {type(perturbed).__name__}")
    seed = _check_int("seed", seed)
    policy, info = make_policy(method, env_id, layout_seed, seed, setup=setup, cache_dir=cache_dir)
    began = time.perf_counter()
    result = _evaluate_column(
        policy, env_id, layout_seed, n_rollouts, bool(perturbed), seed, max_steps=max_steps, start=start
    )
    thesis = THESIS_TABLE_4_1[method][k][1 if perturbed else 0]
    out = {
        "env_id": env_id,
        "num_modes": k,
        "layout_seed": int(layout_seed),
        "method": method,
        "perturbed": bool(perturbed),
        "n_rollouts": int(n_rollouts),
        "seed": seed,
        **result,
        "thesis_success_rate": thesis,
        "eval_seconds": time.perf_counter() - began,
        "train_seconds": info.get("train_seconds", 0.0),
    }
    return out


def _evaluate_column(
    policy: Any,
    env_id: str,
    layout_seed: int,
    n_rollouts: int,
    perturbed: bool,
    seed: int,
    schedule: PerturbationSchedule | None = None,
    max_steps: int | None = None,
    start: str = "free",
) -> dict[str, Any]:
    """:func:`evaluate_policy` plus, for a planner, its call counts over these rollouts (then reset)."""
    res = evaluate_policy(
        policy,
        env_id,
        layout_seed,
        n_rollouts=n_rollouts,
        perturbed=perturbed,
        seed=seed,
        schedule=schedule,
        max_steps=max_steps,
        start=start,
    )
    if isinstance(policy, GlidePlanningPolicy):
        res["planner_calls"] = dict(policy.stats)
        policy.stats = dict.fromkeys(policy.stats, 0)
    return res


def policy_table_trial(
    env_id: str,
    layout_seed: int,
    method: str,
    n_rollouts: int,
    seed: int,
    *,
    setup: GlideSetup | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
    schedule: PerturbationSchedule | None = None,
    max_steps: int | None = None,
    start: str = "free",
) -> dict[str, Any]:
    """Both columns of one thesis Table 4.1 cell: one trained policy, ``n_rollouts`` episodes each
    without and with the evaluation perturbations (the same start states in both), each at most
    ``max_steps`` steps (None: the env's 500), starting as ``start`` says (see :func:`evaluate_policy`).

    Returns ``success`` / ``success_perturbed`` (and the other :func:`evaluate_policy`
    numbers under ``"unperturbed"`` / ``"perturbed"``), the thesis's numbers,
    ``train_seconds`` (the classifier's training for the GLiDE methods, the MLP's
    for BC; a cached classifier reports its original training time) and
    ``eval_seconds`` (both evaluations).

    >>> from steer_envs.baselines.glide.mode_policies import GlideBCConfig
    >>> setup = GlideSetup(n_demos=2, bc=GlideBCConfig(steps=20))
    >>> cell = policy_table_trial("steer_envs/PolygonNav-3Mode-v0", 0, "bc", 2, 0, setup=setup, max_steps=20)
    >>> sorted(k for k in cell if k.startswith("success")), cell["thesis_success"]
    (['success', 'success_perturbed'], 0.967)
    """
    k = _check_env_id(env_id)
    seed = _check_int("seed", seed)
    layout_seed = _check_int("layout_seed", layout_seed)
    policy, info = make_policy(method, env_id, layout_seed, seed, setup=setup, cache_dir=cache_dir)
    out: dict[str, Any] = {
        "env_id": env_id,
        "num_modes": k,
        "layout_seed": layout_seed,
        "method": method,
        "n_rollouts": int(n_rollouts),
        "seed": seed,
        "train_seconds": float(info.get("train_seconds", 0.0)),
        "classifier_cached": bool(info.get("cached", False)),
    }
    began = time.perf_counter()
    for perturbed, name in ((False, "unperturbed"), (True, "perturbed")):
        out[name] = _evaluate_column(
            policy, env_id, layout_seed, n_rollouts, perturbed, seed, schedule, max_steps, start
        )
    out["eval_seconds"] = time.perf_counter() - began
    out["success"] = out["unperturbed"]["success_rate"]
    out["success_perturbed"] = out["perturbed"]["success_rate"]
    out["thesis_success"], out["thesis_success_perturbed"] = THESIS_TABLE_4_1[method][k]
    return out


__all__ = [
    "ENV_IDS",
    "EVAL_STARTS",
    "METHODS",
    "THESIS_TABLE_4_1",
    "VARIANTS",
    "GlideSetup",
    "Grounding",
    "PerturbationSchedule",
    "counterfactual_data",
    "data_cache_path",
    "demonstrations",
    "evaluate_policy",
    "feasibility_for",
    "grounding_trial",
    "learn_grounding",
    "make_policy",
    "policy_table_trial",
    "policy_trial",
]
