"""GLiDE on the robosuite arms: mode grounding (thesis Table 4.2) from demos and perturbed replays.

The classifier (:func:`~steer_envs.baselines.glide.classifier.train_mode_classifier`)
sees only the features the recorded LLM response selected
(``baselines/glide/responses/robosuite_<task>.txt``, the thesis appendix), the
success labels and the feasibility matrix of the task's forward chain; it is
scored by the fraction of demonstration states whose predicted mode is the
ground truth's (:mod:`steer_envs.envs.robosuite.tasks`).

Choices, and why:

* The number of modes ``K`` is the ground truth's (3, 3, 4). The recorded Can
  response plans four steps (a separate "close the gripper" step the ground
  truth folds into transport); the thesis scores Can against three modes.
* Feasibility (:func:`manipulation_feasibility`): the public code's forward
  matrix makes every step back free, which cannot explain a replay that fails
  because the object was dropped (transport -> reach); the plan's sequential
  structure says a step back to the first mode loses the object.
* ``L_dyn`` (eq. 4.3) predicts the change of the object's position relative to
  the gripper from the same step's motion of the robot
  (:func:`dynamics_columns`; ``GlideTrainConfig.dyn_inputs``, ``dyn_input_lag=0``):
  read literally, a linear ``psi(s_t - s_{t-1})`` of the features it predicts
  fits every smooth motion with the identity in every mode, and the ground
  truth's labels then fit it no better than one mode; what tells reach from
  transport is whether the object moves with the gripper, the robot's motion
  is what moves it. The quaternions are left out (their controller jitter,
  divided by their tiny spread, would outweigh the positions).
* Failures may be explained by ending outside the final mode
  (``GlideLossWeights.unfinished_fails``): replays on an arm fail by running
  out of time or by being cut short (the early-terminated copies, now
  trained on) with every move feasible; holding the last state of every
  trajectory to the final mode (the polygons' rule) contradicts them.
* ``stride`` per task (:data:`TASK_STRIDE`): Lift's lift phase lasts ~5
  control steps (sometimes 1-2), which a stride above 1 can skip.
* Variants: ``full`` (``L_under``, eq. 4.3), ``no_dynamics`` (``L_dyn`` off),
  ``no_prediction`` (``L_succ`` and ``L_fail`` off), ``no_feature_selection``
  (every available feature), ``kmeans`` (k-means++ on the standardised selected
  features of the demos, clusters ordered in time).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.suites.glide_robosuite.suite import VARIANTS
from steer_envs.core.validation import one_of
from steer_envs.data import robosuite_replays as rr
from steer_envs.envs.robosuite.tasks import TASK_NAMES, TASKS


@cache
def recorded_plan(task: str) -> Any:
    """The thesis appendix's recorded LLM response for ``task``, parsed (:class:`GlidePlan`)."""
    from steer_envs.baselines.glide import llm_plan

    path = Path(llm_plan.__file__).resolve().parent / "responses" / f"robosuite_{task}.txt"
    return llm_plan.parse_plan_response(path.read_text())


def selected_features(task: str, variant: str) -> tuple[str, ...]:
    """The features the variant's classifier sees: the LLM's selection, or all (``no_feature_selection``)."""
    if variant == "no_feature_selection":
        return rr.feature_names(task)
    return tuple(recorded_plan(task).features)


def manipulation_feasibility(k: int) -> np.ndarray:
    """GLiDE's ``F`` for a ``k``-step pick-and-place chain.

    Staying, one step forward and a step back that keeps the object (e.g.
    hover -> transport) are free; skipping ahead costs the missing steps
    (``-(j - i - 1)``); going back to the first mode (the object lost) costs 1.

    >>> manipulation_feasibility(3).tolist()
    [[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]
    """
    i, j = np.indices((k, k))
    f = np.where(j > i + 1, -(j - i - 1), 0).astype(np.float64)
    f[1:, 0] = -1.0
    return f


#: the features whose change is the robot's own motion (Square: the peg is fixed, so the
#: peg-to-gripper vector moves with the gripper alone) and the object's relative position.
ROBOT_MOTION: dict[str, str] = {"lift": "robot0_eef_pos", "can": "robot0_eef_pos", "square": "peg_to_robot0_eef_pos"}
OBJECT_MOTION: dict[str, str] = {
    "lift": "block_to_robot0_eef_pos",
    "can": "can_to_robot0_eef_pos",
    "square": "nut_to_robot0_eef_pos",
}
#: every how many control steps the classifier sees a state. Lift: every one; its lift phase is ~5
#: steps long, and at stride 2 it can fall between kept states (the ground truth then skips a mode).
TASK_STRIDE: dict[str, int] = {"lift": 1, "can": 6, "square": 6}


def dynamics_columns(task: str, names: Sequence[str]) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """Positions among ``names`` (the classifier's input) of psi's inputs and outputs.

    Inputs: the robot's motion (:data:`ROBOT_MOTION`); outputs: the object's
    position relative to the gripper (:data:`OBJECT_MOTION`).

    >>> dynamics_columns("lift", ["block_to_robot0_eef_pos", "block_to_robot0_eef_quat", "robot0_eef_pos"])
    ((7, 8, 9), (0, 1, 2))
    """
    position = {int(c): i for i, c in enumerate(rr.feature_columns(task, names))}

    def among_names(feature: str) -> tuple[int, ...]:
        if feature not in names:
            raise ValueError(
                f"the dynamics loss of {task!r} needs the feature {feature!r}; the features are {list(names)}"
            )
        return tuple(position[int(c)] for c in rr.feature_columns(task, [feature]))

    return among_names(ROBOT_MOTION[task]), among_names(OBJECT_MOTION[task])


def num_modes(task: str) -> int:
    """The ground truth's number of modes of ``task`` (3, 3, 4)."""
    return len(TASKS[one_of(task, "task", TASK_NAMES, owner="glide_robosuite")].modes)


def selected_columns(task: str, variant: str = "full") -> np.ndarray:
    """The feature columns ``variant``'s mode predictor reads (:func:`selected_features`)."""
    return rr.feature_columns(task, list(selected_features(task, variant)))


class KMeansModes:
    """The k-means baseline as a mode predictor over the selected features: standardised, clusters in temporal order."""

    def __init__(self, task: str, demos: Sequence[rr.ArmTrajectory], *, seed: int = 0) -> None:
        from steer_envs.baselines.glide.kmeans import KMeansSegmentation

        k = num_modes(task)
        self.task = task
        cols = selected_columns(task, "kmeans")
        x = [np.asarray(d.features[:, cols], dtype=np.float64) for d in demos]
        if not x:
            raise ValueError("KMeansModes: demos must not be empty")
        stacked = np.concatenate(x)
        self.mean, self.std = stacked.mean(0), stacked.std(0) + 1e-6
        self.kmeans = KMeansSegmentation(k, seed=seed).fit([(s - self.mean) / self.std for s in x])

    def predict(self, states: np.ndarray) -> np.ndarray:
        """Mode of each row of selected features ``(N, d) -> (N,)``."""
        return self.kmeans.predict((np.asarray(states, dtype=np.float64) - self.mean) / self.std)


@dataclass(frozen=True)
class GroundingSetup:
    """Data and training sizes of one grounding trial.

    ``stride``: the classifier sees every ``stride``-th state (20 Hz control
    moves little per step; the losses cost time per state); 0: the task's
    (:data:`TASK_STRIDE`). ``n_heads``, ``best_head_weight``, ``prune_to``: the
    classifier's heads (:class:`~steer_envs.baselines.glide.classifier.GlideTrainConfig`;
    ``best_head_weight=0`` and ``prune_to >= n_heads`` train them as independent restarts).
    """

    n_demos: int = 50
    replay_demos: int = 20
    replays_per_demo: int = 10
    epochs: int = 1000
    n_heads: int = 5
    best_head_weight: float = 0.9
    prune_to: int = 2
    dyn_weight: float = 10.0
    stride: int = 0
    train_truncated: bool = True

    def stride_of(self, task: str) -> int:
        return self.stride or TASK_STRIDE[task]


def _weights(setup: GroundingSetup, variant: str) -> Any:
    from steer_envs.baselines.glide.classifier import GlideLossWeights

    base = GlideLossWeights(dyn=setup.dyn_weight, unfinished_fails=1.0)
    if variant == "no_dynamics":
        return base.without("dyn")
    if variant == "no_prediction":
        return base.without("succ", "fail")
    return base


def train_predictor(
    task: str,
    variant: str,
    trajectories: Sequence[rr.ArmTrajectory],
    *,
    seed: int = 0,
    setup: GroundingSetup | None = None,
) -> tuple[Any, dict[str, Any]]:
    """Fit ``variant``'s mode predictor on ``trajectories`` (demos + replays of one task).

    Returns the predictor (``predict(features[:, cols])`` with ``cols`` the
    variant's :func:`selected_features`) and a record (training time, counts,
    head losses).
    """
    from steer_envs.baselines.glide.classifier import GlideTrainConfig, train_mode_classifier
    from steer_envs.bench.suites.glide_robosuite.data import split

    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; expected one of {VARIANTS}")
    setup = setup or GroundingSetup()
    k = num_modes(task)
    names = selected_features(task, variant)
    cols = rr.feature_columns(task, names)
    demos, replays = split(trajectories)
    if not demos:
        raise ValueError(f"no successful demonstration of {task!r} among the {len(trajectories)} trajectories")
    start = time.perf_counter()
    info: dict[str, Any] = {"n_demos": len(demos), "n_replays": len(replays)}
    predictor: Any
    if variant == "kmeans":
        predictor = KMeansModes(task, demos, seed=seed)
    else:
        train_demos = [d for d in demos if d.seed < setup.replay_demos]
        train = train_demos + [r for r in replays if setup.train_truncated or r.perturbation.kind != "truncated"]
        dyn_inputs, dyn_outputs = dynamics_columns(task, names)
        config = GlideTrainConfig(
            epochs=setup.epochs,
            n_heads=setup.n_heads,
            best_head_weight=setup.best_head_weight,
            prune_to=setup.prune_to,
            stride=setup.stride_of(task),
            seed=seed,
            dyn_columns=dyn_outputs,
            dyn_inputs=dyn_inputs,
            dyn_input_lag=0,
        )
        result = train_mode_classifier(
            [t.features[:, cols] for t in train],
            [t.success for t in train],
            manipulation_feasibility(k),
            weights=_weights(setup, variant),
            config=config,
        )
        predictor = result.classifier
        info["head_losses"] = result.head_losses
        info["n_train"] = len(train)
        info["raw_success_rate"] = float(np.mean([t.success for t in replays])) if replays else None
    info["train_seconds"] = time.perf_counter() - start
    return predictor, info


def grounding(
    task: str,
    variant: str,
    trajectories: Sequence[rr.ArmTrajectory],
    *,
    seed: int = 0,
    setup: GroundingSetup | None = None,
    keep: int = 0,
) -> dict[str, Any]:
    """Train ``variant`` on ``trajectories`` (demos + replays of one task) and score it on the demos.

    Returns ``accuracy`` (all demo samples), ``accuracy_per_mode``, ``train_seconds``,
    counts, and with ``keep > 0`` the predicted and true modes of the first ``keep`` demos.
    """
    from steer_envs.bench.suites.glide_robosuite.data import split

    predictor, out = train_predictor(task, variant, trajectories, seed=seed, setup=setup)
    k = num_modes(task)
    cols = rr.feature_columns(task, selected_features(task, variant))
    demos, _ = split(trajectories)
    pred = [np.asarray(predictor.predict(d.features[:, cols])) for d in demos]
    truth = [d.modes.astype(int) for d in demos]
    p, t = np.concatenate(pred), np.concatenate(truth)
    out["accuracy"] = float(np.mean(p == t))
    out["accuracy_per_mode"] = [float(np.mean(p[t == m] == m)) if np.any(t == m) else None for m in range(k)]
    if keep:
        out["labels"] = [
            {"pred": a.tolist(), "true": b.tolist()} for a, b in zip(pred[:keep], truth[:keep], strict=True)
        ]
    return out
