"""GLiDE's mode grounding on the robosuite arms (thesis Table 4.2): train a mode predictor, score it on the demos.

The classifier (:func:`~steer_envs.baselines.glide.training.train_mode_classifier`)
sees only the features the recorded LLM response selected
(:func:`~steer_envs.baselines.glide.arm_plan.selected_features`), the
success labels and the feasibility matrix of the task's forward chain
(:func:`~steer_envs.baselines.glide.arm_plan.manipulation_feasibility`); it
is scored by the fraction of demonstration states whose predicted mode is the
ground truth's (:mod:`steer_envs.envs.robosuite.tasks`).

Choices, and why:

* The number of modes ``K`` is the ground truth's (3, 3, 4). The recorded Can
  response plans four steps (a separate "close the gripper" step the ground
  truth folds into transport); the thesis scores Can against three modes.
* Failures may be explained by ending outside the final mode
  (``GlideLossWeights.unfinished_fails``): replays on an arm fail by running
  out of time or by being cut short (the early-terminated copies, trained
  on) with every move feasible; holding the last state of every trajectory to
  the final mode (the polygons' rule) contradicts them.
* ``stride`` per task (:data:`~steer_envs.baselines.glide.arm_plan.TASK_STRIDE`):
  Lift's lift phase lasts ~5 control steps (sometimes 1-2), which a stride
  above 1 can skip.
* Padding (``pad_to``, off by default) applies to the classifier's training
  data only: the demo samples it is scored on, and k-means, see the
  trajectories as recorded.
* Variants (:data:`ARM_VARIANTS`): ``full`` (``L_under``, eq. 4.3),
  ``no_dynamics`` (``L_dyn`` off), ``no_prediction`` (``L_succ`` and
  ``L_fail`` off), ``no_feature_selection`` (every available feature),
  ``kmeans`` (:class:`~steer_envs.baselines.glide.kmeans.KMeansModes`).

>>> ArmGroundingSetup().stride_of("lift"), ArmGroundingSetup(stride=3).stride_of("can")
(1, 3)
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.baselines.glide.arm_plan import (
    TASK_STRIDE,
    dynamics_columns,
    manipulation_feasibility,
    num_modes,
    selected_features,
)
from steer_envs.baselines.glide.classifier import GlideLossWeights, GlideTrainConfig
from steer_envs.baselines.glide.kmeans import KMeansModes
from steer_envs.baselines.glide.training import train_mode_classifier
from steer_envs.core.validation import integer
from steer_envs.data import robosuite_replays as rr
from steer_envs.data.robosuite_replay_sets import split_demos

__all__ = [
    "ARM_VARIANTS",
    "MAX_PAD",
    "ArmGroundingSetup",
    "evaluate_arm_grounding",
    "pad_states",
    "train_arm_predictor",
]

#: the grounding variants of thesis Table 4.2 (see the module).
ARM_VARIANTS: tuple[str, ...] = ("full", "no_dynamics", "no_prediction", "no_feature_selection", "kmeans")
#: the longest padding (:attr:`ArmGroundingSetup.pad_to`)
MAX_PAD = 100_000


def pad_states(states: np.ndarray, length: int) -> np.ndarray:
    """``states`` ``(T, d)`` padded to ``length`` rows by repeating the last one (unchanged when ``T >= length``).

    >>> pad_states(np.array([[0.0], [1.0]]), 4).ravel().tolist()
    [0.0, 1.0, 1.0, 1.0]
    """
    arr = np.asarray(states)
    if arr.ndim != 2 or len(arr) == 0:
        raise ValueError(f"pad_states: states must be (T>=1, d), got shape {arr.shape}")
    return np.pad(arr, ((0, max(0, length - len(arr))), (0, 0)), mode="edge")


@dataclass(frozen=True)
class ArmGroundingSetup:
    """Data and training sizes of one grounding on an arm task.

    ``stride``: the classifier sees every ``stride``-th state (20 Hz control
    moves little per step; the losses cost time per state); 0: the task's
    (:data:`~steer_envs.baselines.glide.arm_plan.TASK_STRIDE`). ``n_heads``,
    ``best_head_weight``, ``prune_to``: the classifier's heads
    (:class:`~steer_envs.baselines.glide.classifier.GlideTrainConfig`;
    ``best_head_weight=0`` and ``prune_to >= n_heads`` train them as independent
    restarts). ``replay_demos``: the demos with replays (``seed <
    replay_demos``) are the demos the classifier trains on;
    ``train_truncated``: it trains on the replays' truncated copies too.
    ``pad_to``: every trajectory the classifier trains on shorter than this
    many states is padded to it by repeating its last state (the public GLiDE
    fork pads to 200); 0: no padding. Longer ones stay as they are.
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
    pad_to: int = 0

    def __post_init__(self) -> None:
        integer(self.pad_to, "pad_to", low=0, high=MAX_PAD, owner="ArmGroundingSetup")

    def stride_of(self, task: str) -> int:
        """The stride on ``task``: :attr:`stride`, or the task's when 0."""
        return self.stride or TASK_STRIDE[task]


def _weights(setup: ArmGroundingSetup, variant: str) -> GlideLossWeights:
    base = GlideLossWeights(dyn=setup.dyn_weight, unfinished_fails=1.0)
    if variant == "no_dynamics":
        return base.without("dyn")
    if variant == "no_prediction":
        return base.without("succ", "fail")
    return base


def _train_classifier(
    task: str,
    variant: str,
    demos: Sequence[rr.ArmTrajectory],
    replays: Sequence[rr.ArmTrajectory],
    seed: int,
    setup: ArmGroundingSetup,
    info: dict[str, Any],
) -> Any:
    """The GLiDE classifier of ``variant`` (its training numbers added to ``info``)."""
    names = selected_features(task, variant)
    cols = rr.feature_columns(task, names)
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
    states = [t.features[:, cols] for t in train]
    if setup.pad_to:
        info["padded"] = sum(len(x) < setup.pad_to for x in states)
        info["longer_than_pad"] = sum(len(x) > setup.pad_to for x in states)
        states = [pad_states(x, setup.pad_to) for x in states]
    result = train_mode_classifier(
        states,
        [t.success for t in train],
        manipulation_feasibility(num_modes(task)),
        weights=_weights(setup, variant),
        config=config,
    )
    info["head_losses"] = result.head_losses
    info["n_train"] = len(train)
    info["raw_success_rate"] = float(np.mean([t.success for t in replays])) if replays else None
    return result.classifier


def train_arm_predictor(
    task: str,
    variant: str,
    trajectories: Sequence[rr.ArmTrajectory],
    *,
    seed: int = 0,
    setup: ArmGroundingSetup | None = None,
) -> tuple[Any, dict[str, Any]]:
    """Fit ``variant``'s mode predictor on ``trajectories`` (demos + replays of one task).

    Returns the predictor (``predict(features[:, cols])`` with ``cols`` the
    variant's :func:`~steer_envs.baselines.glide.arm_plan.selected_features`)
    and a record (training time, counts, head losses).
    """
    if variant not in ARM_VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; expected one of {ARM_VARIANTS}")
    setup = setup or ArmGroundingSetup()
    demos, replays = split_demos(trajectories)
    if not demos:
        raise ValueError(f"no successful demonstration of {task!r} among the {len(trajectories)} trajectories")
    start = time.perf_counter()
    info: dict[str, Any] = {"n_demos": len(demos), "n_replays": len(replays)}
    predictor: Any
    if variant == "kmeans":
        predictor = KMeansModes(task, demos, seed=seed)
    else:
        predictor = _train_classifier(task, variant, demos, replays, seed, setup, info)
    info["train_seconds"] = time.perf_counter() - start
    return predictor, info


def evaluate_arm_grounding(
    task: str,
    variant: str,
    trajectories: Sequence[rr.ArmTrajectory],
    *,
    seed: int = 0,
    setup: ArmGroundingSetup | None = None,
    keep: int = 0,
) -> dict[str, Any]:
    """Train ``variant`` on ``trajectories`` (demos + replays of one task) and score it on the demos.

    Returns ``accuracy`` (all demo samples), ``accuracy_per_mode``, ``train_seconds``,
    counts, and with ``keep > 0`` the predicted and true modes of the first ``keep`` demos.
    """
    predictor, out = train_arm_predictor(task, variant, trajectories, seed=seed, setup=setup)
    k = num_modes(task)
    cols = rr.feature_columns(task, selected_features(task, variant))
    demos, _ = split_demos(trajectories)
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
