"""GLiDE (thesis ch. 4): grounding modes from success labels, and policies that use the learned modes.

* :mod:`.classifier` -- the mode classifier, its loss and training
  (:func:`train_mode_classifier`), :func:`label_demonstrations` and the
  grounding metrics;
* :mod:`.mode_policies` -- GLiDE+BC (:class:`GlideBCPolicy`), GLiDE+Planning
  (:class:`GlidePlanningPolicy`) and the BC baseline's settings (:class:`GlideBCConfig`);
* :mod:`.planners` -- the learned mode map and costmap paths, RRT, the potential field;
* :mod:`.llm_plan` -- the LLM prompt and the parsing of its plan and feasibility;
* :mod:`.kmeans` -- the trajectory-segmentation baseline (k-means++).

The names below are loaded on first use, so ``import steer_envs.baselines.glide.llm_plan``
needs no torch.

>>> from steer_envs.baselines.glide import GlideTrainConfig, PlannerConfig
>>> GlideTrainConfig().n_heads, PlannerConfig().free_space_planner
(5, 'costmap')
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from steer_envs.baselines.glide.classifier import (
        LOSS_TERMS,
        ForwardModel,
        GlideLossWeights,
        GlideTrainConfig,
        GlideTrainResult,
        ModeClassifier,
        ModePredictor,
        PackedTrajectories,
        glide_losses,
        label_demonstrations,
        mode_iou,
        mode_overlap,
        pack_trajectories,
        train_mode_classifier,
        workspace_grid,
    )
    from steer_envs.baselines.glide.kmeans import KMeansSegmentation
    from steer_envs.baselines.glide.llm_plan import (
        SYSTEM_PROMPT,
        GlidePlan,
        LLMProvider,
        PlanStep,
        RecordedProvider,
        build_prompt,
        extract_tag,
        parse_plan_response,
        request_plan,
    )
    from steer_envs.baselines.glide.mode_policies import (
        GlideBCConfig,
        GlideBCPolicy,
        GlidePlanningPolicy,
        mean_end_state,
        mode_entry_points,
        train_bc,
    )
    from steer_envs.baselines.glide.planners import (
        FREE_SPACE_PLANNERS,
        LearnedModeMap,
        PlannerConfig,
        potential_field,
        rrt,
    )

#: public name -> the submodule that defines it
_EXPORTS: dict[str, str] = {
    "FREE_SPACE_PLANNERS": "planners",
    "ForwardModel": "classifier",
    "GlideBCConfig": "mode_policies",
    "GlideBCPolicy": "mode_policies",
    "GlideLossWeights": "classifier",
    "GlidePlan": "llm_plan",
    "GlidePlanningPolicy": "mode_policies",
    "GlideTrainConfig": "classifier",
    "GlideTrainResult": "classifier",
    "KMeansSegmentation": "kmeans",
    "LLMProvider": "llm_plan",
    "LOSS_TERMS": "classifier",
    "LearnedModeMap": "planners",
    "ModeClassifier": "classifier",
    "ModePredictor": "classifier",
    "PackedTrajectories": "classifier",
    "PlanStep": "llm_plan",
    "PlannerConfig": "planners",
    "RecordedProvider": "llm_plan",
    "SYSTEM_PROMPT": "llm_plan",
    "build_prompt": "llm_plan",
    "extract_tag": "llm_plan",
    "glide_losses": "classifier",
    "label_demonstrations": "classifier",
    "mean_end_state": "mode_policies",
    "mode_entry_points": "mode_policies",
    "mode_iou": "classifier",
    "mode_overlap": "classifier",
    "pack_trajectories": "classifier",
    "parse_plan_response": "llm_plan",
    "potential_field": "planners",
    "request_plan": "llm_plan",
    "rrt": "planners",
    "train_bc": "mode_policies",
    "train_mode_classifier": "classifier",
    "workspace_grid": "classifier",
}

__all__ = [
    "FREE_SPACE_PLANNERS",
    "LOSS_TERMS",
    "SYSTEM_PROMPT",
    "ForwardModel",
    "GlideBCConfig",
    "GlideBCPolicy",
    "GlideLossWeights",
    "GlidePlan",
    "GlidePlanningPolicy",
    "GlideTrainConfig",
    "GlideTrainResult",
    "KMeansSegmentation",
    "LLMProvider",
    "LearnedModeMap",
    "ModeClassifier",
    "ModePredictor",
    "PackedTrajectories",
    "PlanStep",
    "PlannerConfig",
    "RecordedProvider",
    "build_prompt",
    "extract_tag",
    "glide_losses",
    "label_demonstrations",
    "mean_end_state",
    "mode_entry_points",
    "mode_iou",
    "mode_overlap",
    "pack_trajectories",
    "parse_plan_response",
    "potential_field",
    "request_plan",
    "rrt",
    "train_bc",
    "train_mode_classifier",
    "workspace_grid",
]


def __getattr__(name: str) -> Any:
    """Import the submodule that defines ``name`` on first access."""
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
