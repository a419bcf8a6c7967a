"""GLiDE on PolygonNav, end to end: demos -> counterfactual replays -> mode classifier -> policies.

* :func:`polygon_demonstrations` -- the expert's demos of one layout; they go on
  into the goal polygon for up to ``GlideSetup.demo_goal_steps`` steps (the
  expert walks to its centroid): the env ends an episode on entering the
  goal, and a demo that stops there shows the classifier nothing of the goal
  polygon but a point behind its entry edge (the perturbed replays start and
  end where their demo does).
* :func:`counterfactual_data` -- the balanced perturbation data set
  (:func:`~steer_envs.data.counterfactual_dataset.build_counterfactual_dataset`).
* :func:`learn_grounding` -- the modes learned with one variant (the full
  loss, or an ablation: no counterfactuals, a wrong feasibility matrix, no
  prediction loss, k-means++), as a :class:`Grounding`.
* :func:`make_polygon_policy` -- BC, GLiDE+BC or GLiDE+Planning trained on them
  (:mod:`~steer_envs.baselines.glide.mode_policies`);
  :func:`~steer_envs.baselines.glide.polygon_eval.evaluate_polygon_policy` runs one.

Every step is deterministic given its arguments. Data sets and trained
classifiers can be cached in ``cache_dir`` (npz / safetensors, written
atomically, named by a hash of the settings they depend on), so the
grounding study, the policy study and a second run train each classifier once.

>>> from steer_envs.baselines.glide import GlideBCConfig
>>> grounding = learn_grounding("steer_envs/PolygonNav-3Mode-v0", 0, "kmeans", 0, setup=GlideSetup(n_demos=2))
>>> policy, info = make_polygon_policy("bc", "steer_envs/PolygonNav-3Mode-v0", 0, 0,
...                                    setup=GlideSetup(n_demos=2, bc=GlideBCConfig(steps=20)))
>>> type(grounding.predictor).__name__, policy.act(grounding.demos[0].states[:2]).shape
('KMeansSegmentation', (2, 2))
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
from steer_envs.baselines.glide.classifier import GlideLossWeights, GlideTrainConfig, ModeClassifier
from steer_envs.baselines.glide.kmeans import KMeansSegmentation
from steer_envs.baselines.glide.mode_policies import GlideBCConfig, GlideBCPolicy, GlidePlanningPolicy, train_bc
from steer_envs.baselines.glide.modes import ModePredictor
from steer_envs.baselines.glide.planners import PlannerConfig
from steer_envs.baselines.glide.training import train_mode_classifier
from steer_envs.data.counterfactual_dataset import CounterfactualDataset, cached_counterfactual_dataset
from steer_envs.data.demos import Demonstration, collect_demonstrations
from steer_envs.io import CheckpointError

__all__ = [
    "POLYGON_ENV_IDS",
    "POLYGON_METHODS",
    "POLYGON_VARIANTS",
    "GlideSetup",
    "Grounding",
    "cached_classifier_info",
    "counterfactual_data",
    "data_cache_path",
    "feasibility_for",
    "learn_grounding",
    "make_polygon_policy",
    "polygon_demonstrations",
]

#: the grounding variants (thesis Fig. 4.4): the full loss, the ablations, and k-means++.
POLYGON_VARIANTS: tuple[str, ...] = (
    "full",
    "no_counterfactuals",
    "wrong_feasibility",
    "no_prediction_loss",
    "kmeans",
)
#: the policies of thesis Table 4.1.
POLYGON_METHODS: tuple[str, ...] = ("bc", "glide_bc", "glide_planning")
POLYGON_ENV_IDS: tuple[str, ...] = tuple(f"steer_envs/PolygonNav-{k}Mode-v0" for k in (3, 4, 5))


@dataclass(frozen=True)
class GlideSetup:
    """Everything a PolygonNav grounding or policy depends on besides (env, layout, variant/method, seed).

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
    #: where BC's demos start (``"uniform"`` or ``"spread"``, :func:`polygon_demonstrations`); GLiDE's keep
    #: the setup's data set's demos
    bc_demo_starts: str = "uniform"
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


# ------------------------------------------------------------------------------ helpers
def check_env_id(env_id: str) -> int:
    """The number of modes of a PolygonNav env id (:data:`POLYGON_ENV_IDS`); ValueError for another id.

    >>> check_env_id("steer_envs/PolygonNav-4Mode-v0")
    4
    """
    if env_id not in POLYGON_ENV_IDS:
        raise ValueError(f"env_id must be one of {POLYGON_ENV_IDS}, got {env_id!r}")
    return int(env_id.split("-")[1][0])


def check_count(name: str, value: Any, low: int = 0) -> int:
    """``value`` as an int, if it is an integer >= ``low`` (ValueError otherwise)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name} must be an int >= {low}, got {value!r}")
    return int(value)


def polygon_demonstrations(
    env_id: str, layout_seed: int, n: int, seed: int, *, goal_steps: int = 0, demo_starts: str = "uniform"
) -> list[Demonstration]:
    """``n`` expert demos of one layout; demo start states are drawn from ``seed``.

    ``goal_steps > 0``: each demo goes on for up to that many steps after entering the goal
    polygon, the expert walking to the polygon's centroid (see ``GlideSetup.demo_goal_steps``).
    ``demo_starts``: where the demos start (:mod:`steer_envs.data.demo_starts`: ``"uniform"`` in free
    space, the env's reset; ``"spread"`` evenly around the workspace edge, as the public code's demos).
    """
    goal_steps = check_count("goal_steps", goal_steps)
    return collect_demonstrations(
        env_id,
        n,
        seed=1000 * int(seed),
        steps_after_success=goal_steps,
        expert_kwargs={"final_target": "centroid"} if goal_steps else None,
        demo_starts=demo_starts,
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
    return cached_counterfactual_dataset(
        data_cache_path(env_id, layout_seed, seed, setup, cache_dir),
        env_id,
        [d.states for d in demos],
        n_success=setup.n_success,
        n_failure=setup.n_failure,
        kind=setup.kind,
        execution=setup.execution,
        seed=int(seed),
        layout_seed=int(layout_seed),
    )


def feasibility_for(env_id: str, layout_seed: int, variant: str, convention: str) -> np.ndarray:
    """The feasibility matrix a variant trains with (``wrong_feasibility``: a plan one mode short)."""
    env = gym.make(env_id, layout_seed=int(layout_seed))
    try:
        feas = env.unwrapped.task.feasibility_matrix(convention)  # type: ignore[attr-defined]
    finally:
        env.close()
    return feas[:-1, :-1] if variant == "wrong_feasibility" else feas


# ---------------------------------------------------------------------------- grounding
@dataclass
class Grounding:
    """A learned grounding (classifier or baseline), the demos it came with, and how it was made."""

    predictor: ModePredictor
    demos: list[Demonstration]
    info: dict[str, Any]


def cached_classifier_info(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The training info stored with a cached classifier (:meth:`ModeClassifier.save`'s ``extra``)."""
    from safetensors import safe_open

    with safe_open(str(path), framework="pt") as fh:
        meta = json.loads((fh.metadata() or {})["glide_classifier"])
    return dict(meta.get("extra", {}))


def _cached_grounding(cache: Path | None, demos: list[Demonstration], info: dict[str, Any]) -> Grounding | None:
    """The grounding of a readable cached classifier (None: no cache, no file, or a corrupt one)."""
    if cache is None or not cache.exists():
        return None
    try:
        clf = ModeClassifier.load(cache)
        meta = cached_classifier_info(cache)
    except CheckpointError as err:  # a corrupt cache entry is a miss: retrain and overwrite it
        warnings.warn(f"retraining the cached classifier: {err}", RuntimeWarning, stacklevel=3)
        return None
    return Grounding(clf, demos, {**info, **meta, "cached": True})


def _training_data(
    env_id: str,
    layout_seed: int,
    variant: str,
    seed: int,
    setup: GlideSetup,
    demos: list[Demonstration],
    cache_dir: str | os.PathLike[str] | None,
    info: dict[str, Any],
) -> tuple[list[np.ndarray], np.ndarray]:
    """The classifier's trajectories and success labels: the demos alone, or with the counterfactual replays."""
    if variant == "no_counterfactuals":
        return [d.states for d in demos], np.ones(len(demos), dtype=bool)
    cached_data = data_cache_path(env_id, layout_seed, seed, setup, cache_dir)
    info["data_cached"] = cached_data is not None and cached_data.exists()
    start = time.perf_counter()
    data = counterfactual_data(env_id, layout_seed, seed, setup, demos, cache_dir)
    info["data_seconds"] = time.perf_counter() - start
    info["raw_success_rate"] = data.meta.get("raw_success_rate")
    return data.trajectories(), data.success


def learn_grounding(
    env_id: str,
    layout_seed: int,
    variant: str,
    seed: int,
    *,
    setup: GlideSetup | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
) -> Grounding:
    """Demos -> (perturbation data) -> classifier of one variant (:data:`POLYGON_VARIANTS`), cached in ``cache_dir``."""
    k = check_env_id(env_id)
    if variant not in POLYGON_VARIANTS:
        raise ValueError(f"variant must be one of {POLYGON_VARIANTS}, got {variant!r}")
    layout_seed, seed = check_count("layout_seed", layout_seed), check_count("seed", seed)
    setup = setup or GlideSetup()
    demos = polygon_demonstrations(env_id, layout_seed, setup.n_demos, seed, goal_steps=setup.demo_goal_steps)
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
    cached = _cached_grounding(cache, demos, info)
    if cached is not None:
        return cached
    trajectories, labels = _training_data(env_id, layout_seed, variant, seed, setup, demos, cache_dir, info)
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


# ----------------------------------------------------------------------------- policies
def make_polygon_policy(
    method: str,
    env_id: str,
    layout_seed: int,
    seed: int,
    *,
    setup: GlideSetup | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
) -> tuple[Any, dict[str, Any]]:
    """A trained policy (:data:`POLYGON_METHODS`: BC, GLiDE+BC or GLiDE+Planning) and its training info.

    BC fits every demo pair; the GLiDE methods use the full loss's grounding (:func:`learn_grounding`).
    """
    if method not in POLYGON_METHODS:
        raise ValueError(f"method must be one of {POLYGON_METHODS}, got {method!r}")
    setup = setup or GlideSetup()
    k = check_env_id(env_id)
    env = gym.make(env_id, layout_seed=int(layout_seed))
    base = env.unwrapped
    max_speed, low, high = float(base.max_speed * base.dt), base.model.low, base.model.high  # type: ignore[attr-defined]
    env.close()
    policy: Any
    if method == "bc":
        demos = polygon_demonstrations(
            env_id, layout_seed, setup.n_demos, seed, goal_steps=setup.demo_goal_steps, demo_starts=setup.bc_demo_starts
        )
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
