"""GLiDE's plan on the robosuite arms (thesis §4.4): the recorded LLM plans and what they fix.

The recorded LLM responses (``responses/robosuite_<task>.txt``, the thesis
appendix) select the features the mode classifier sees
(:func:`selected_features`) and name each plan step's goal feature (what
GLiDE+BC's pseudo-attractors aim at, :func:`plan_goal_features`). The number
of modes is the ground truth's (:func:`num_modes`: 3, 3, 4).

Choices, and why:

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
* Plan steps map to modes by :data:`PLAN_STEPS`: one step per mode where the
  counts agree (Lift, Square); Can's plan has a separate "close the gripper"
  step (2) that the ground truth folds into *transport* (the grasp is the
  start of transport), so transport takes the goal of the merged steps' last
  one, step 3 "move to tray 2" (``robot0_eef_pos``): a merged mode ends where
  its last step ends.

>>> manipulation_feasibility(3).tolist()
[[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]
>>> num_modes("square"), TASK_STRIDE["lift"]
(4, 1)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.baselines.glide import llm_plan
from steer_envs.core.validation import one_of
from steer_envs.data import robosuite_replays as rr
from steer_envs.envs.robosuite.tasks import TASK_NAMES, TASKS

__all__ = [
    "EEF_FEATURE",
    "OBJECT_MOTION",
    "PLAN_STEPS",
    "ROBOT_MOTION",
    "TASK_STRIDE",
    "dynamics_columns",
    "manipulation_feasibility",
    "num_modes",
    "plan_goal_features",
    "recorded_plan",
    "selected_columns",
    "selected_features",
]

#: the end effector's position, an absolute goal feature.
EEF_FEATURE = "robot0_eef_pos"
#: the suffix of a relative goal feature (``<object>_to_robot0_eef_pos``: object minus eef).
RELATIVE_SUFFIX = "_to_robot0_eef_pos"
#: task -> the plan step id whose goal feature each ground-truth mode uses (see the module's choices).
PLAN_STEPS: Mapping[str, tuple[int, ...]] = {"lift": (1, 2, 3), "can": (1, 3, 4), "square": (1, 2, 3, 4)}
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


def _task(task: Any) -> str:
    return one_of(task, "task", TASK_NAMES, owner="glide arm plan")


@cache
def recorded_plan(task: str) -> llm_plan.GlidePlan:
    """The thesis appendix's recorded LLM response for ``task``, parsed.

    >>> recorded_plan("lift").features[:1]
    ('block_to_robot0_eef_pos',)
    """
    path = Path(llm_plan.__file__).resolve().parent / "responses" / f"robosuite_{task}.txt"
    return llm_plan.parse_plan_response(path.read_text())


def selected_features(task: str, variant: str) -> tuple[str, ...]:
    """The features the variant's classifier sees: the LLM's selection, or all (``no_feature_selection``)."""
    if variant == "no_feature_selection":
        return rr.feature_names(task)
    return tuple(recorded_plan(task).features)


def selected_columns(task: str, variant: str = "full") -> np.ndarray:
    """The feature columns ``variant``'s mode predictor reads (:func:`selected_features`)."""
    return rr.feature_columns(task, list(selected_features(task, variant)))


def num_modes(task: str) -> int:
    """The ground truth's number of modes of ``task`` (3, 3, 4)."""
    return len(TASKS[one_of(task, "task", TASK_NAMES, owner="glide_robosuite")].modes)


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


def plan_goal_features(task: str, plan: Any) -> list[str]:
    """The goal feature of each ground-truth mode (:data:`PLAN_STEPS` over the plan's ``goals``).

    >>> plan_goal_features("can", recorded_plan("can"))
    ['can_to_robot0_eef_pos', 'robot0_eef_pos', 'robot0_eef_pos']
    """
    task = _task(task)
    goals = dict(getattr(plan, "goals", None) or {})
    out = []
    for k, step in enumerate(PLAN_STEPS[task]):
        name = goals.get(step)
        if not isinstance(name, str) or not (name == EEF_FEATURE or name.endswith(RELATIVE_SUFFIX)):
            raise ValueError(
                f"mode {k} of {task!r} takes plan step {step}'s goal feature, which must be {EEF_FEATURE!r} or "
                f"'<object>{RELATIVE_SUFFIX}'; the plan's goals are {goals}"
            )
        out.append(name)
    return out
