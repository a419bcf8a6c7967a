"""GLiDE (thesis ch. 4): grounding modes from success labels, and policies that use the learned modes.

Method (both domains):

* :mod:`.modes` -- :class:`ModePredictor` (anything with ``predict(states) -> modes``),
  :func:`label_demonstrations` and the grid metrics;
* :mod:`.classifier` -- the mode classifier, its loss weights and settings
  (:class:`ModeClassifier`, :class:`GlideLossWeights`, :class:`GlideTrainConfig`); :mod:`.losses` -- its loss
  (:func:`glide_losses`); :mod:`.packing` -- its training data (:func:`pack_trajectories`);
  :mod:`.training` -- :func:`train_mode_classifier`;
* :mod:`.glide_bc` -- GLiDE+BC's shared core (:class:`GlideBC`: per-mode policies, pseudo-attractors);
* :mod:`.kmeans` -- the trajectory-segmentation baseline (k-means++);
* :mod:`.planners` -- the learned mode map and costmap paths, RRT, the potential field;
* :mod:`.llm_plan` -- the LLM prompt and the parsing of its plan and feasibility.

PolygonNav (thesis Table 4.1, Fig. 4.4):

* :mod:`.mode_policies` -- GLiDE+BC (:class:`GlideBCPolicy`), GLiDE+Planning
  (:class:`GlidePlanningPolicy`) and the BC baseline (:func:`train_bc`, :class:`GlideBCConfig`);
* :mod:`.polygon` -- demos, counterfactual data, :func:`learn_grounding`, :func:`make_polygon_policy`;
* :mod:`.polygon_eval` -- :func:`evaluate_polygon_policy` (teleport perturbations), :func:`grounding_scores`.

The robosuite arms (thesis Tables 4.2 and 4.3):

* :mod:`.arm_plan` -- the recorded LLM plans: selected features, feasibility, goal features;
* :mod:`.arm_grounding` -- :func:`train_arm_predictor`, :func:`evaluate_arm_grounding`;
* :mod:`.arm_policies` -- BC (:class:`ArmBC`) and GLiDE+BC (:class:`GlideArmPolicy`), :func:`train_arm_policy`;
* :mod:`.public_attractor` -- the public GLiDE fork's first-mode pull (:class:`PublicCodeAttractor`);
* :mod:`.arm_eval` -- :func:`evaluate_arm_policy`.

GLiDE+BC on PolygonNav, from expert demos (the classifier trains for a minute or two)::

    from steer_envs.baselines.glide import evaluate_polygon_policy, make_polygon_policy

    env_id = "steer_envs/PolygonNav-3Mode-v0"
    policy, info = make_polygon_policy("glide_bc", env_id, layout_seed=0, seed=0)
    print(evaluate_polygon_policy(policy, env_id, 0, n_rollouts=100, perturbed=True, seed=0)["success_rate"])

GLiDE+BC on Lift, from expert demos and their perturbed replays::

    import gymnasium as gym

    from steer_envs.baselines.glide import evaluate_arm_policy, train_arm_policy, train_arm_predictor
    from steer_envs.data.robosuite_replay_sets import replay_set, split_demos

    trajectories = replay_set("lift", n_demos=20, replays_per_demo=10)  # demos + perturbed replays
    demos, _ = split_demos(trajectories)
    classifier, _ = train_arm_predictor("lift", "full", trajectories)
    policy = train_arm_policy("lift", "glide_bc", 0, demos=demos, predictor=classifier)
    env = gym.make("steer_envs/Lift-v0")  # wrap it in ArmPerturbationWrapper for the "+p" column
    print(evaluate_arm_policy(env, policy, predictor=classifier, n_episodes=20)["success_rate"])
    env.close()

The names below are loaded on first use, so ``import steer_envs.baselines.glide.llm_plan``
needs no torch.

>>> from steer_envs.baselines.glide import GlideTrainConfig, PlannerConfig
>>> GlideTrainConfig().n_heads, PlannerConfig().free_space_planner
(5, 'costmap')
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from steer_envs.core.lazy import lazy_exports

if TYPE_CHECKING:
    from steer_envs.baselines.glide.arm_eval import (
        evaluate_arm_policy,
    )
    from steer_envs.baselines.glide.arm_grounding import (
        ARM_VARIANTS,
        ArmGroundingSetup,
        evaluate_arm_grounding,
        train_arm_predictor,
    )
    from steer_envs.baselines.glide.arm_plan import (
        EEF_FEATURE,
        OBJECT_MOTION,
        PLAN_STEPS,
        ROBOT_MOTION,
        TASK_STRIDE,
        dynamics_columns,
        manipulation_feasibility,
        num_modes,
        plan_goal_features,
        recorded_plan,
        selected_columns,
        selected_features,
    )
    from steer_envs.baselines.glide.arm_policies import (
        ARM_ATTRACTORS,
        ARM_BC_RECIPES,
        ARM_METHODS,
        ATTRACTOR_MODES,
        GROUND_TRUTH,
        ROBOMIMIC_CPU_STEPS,
        ROBOMIMIC_STEPS,
        ArmBC,
        ArmBCSettings,
        ArmPolicy,
        BCArmPolicy,
        GlideArmPolicy,
        GlideArmSettings,
        ModeAttractor,
        check_arm_predictor,
        demo_modes,
        mode_attractors,
        train_arm_policy,
    )
    from steer_envs.baselines.glide.classifier import (
        LOSS_TERMS,
        ForwardModel,
        GlideLossWeights,
        GlideTrainConfig,
        ModeClassifier,
    )
    from steer_envs.baselines.glide.glide_bc import (
        GlideBC,
    )
    from steer_envs.baselines.glide.kmeans import (
        KMeansModes,
        KMeansSegmentation,
    )
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
    from steer_envs.baselines.glide.losses import glide_losses
    from steer_envs.baselines.glide.mode_policies import (
        GlideBCConfig,
        GlideBCPolicy,
        GlidePlanningPolicy,
        mean_end_state,
        mode_entry_points,
        train_bc,
    )
    from steer_envs.baselines.glide.modes import (
        ModePredictor,
        label_demonstrations,
        mode_iou,
        mode_overlap,
        workspace_grid,
    )
    from steer_envs.baselines.glide.packing import PackedTrajectories, pack_trajectories
    from steer_envs.baselines.glide.planners import (
        FREE_SPACE_PLANNERS,
        LearnedModeMap,
        PlannerConfig,
        potential_field,
        rrt,
    )
    from steer_envs.baselines.glide.polygon import (
        POLYGON_ENV_IDS,
        POLYGON_METHODS,
        POLYGON_VARIANTS,
        GlideSetup,
        Grounding,
        cached_classifier_info,
        counterfactual_data,
        data_cache_path,
        feasibility_for,
        learn_grounding,
        make_polygon_policy,
        polygon_demonstrations,
    )
    from steer_envs.baselines.glide.polygon_eval import (
        EVAL_STARTS,
        PerturbationSchedule,
        evaluate_polygon_policy,
        grounding_scores,
    )
    from steer_envs.baselines.glide.public_attractor import PublicCodeAttractor
    from steer_envs.baselines.glide.training import (
        GlideTrainResult,
        train_mode_classifier,
    )

#: public name -> the submodule that defines it
_EXPORTS: dict[str, str] = {
    "ARM_ATTRACTORS": "arm_policies",
    "ARM_BC_RECIPES": "arm_policies",
    "ARM_METHODS": "arm_policies",
    "ARM_VARIANTS": "arm_grounding",
    "ATTRACTOR_MODES": "arm_policies",
    "ArmBC": "arm_policies",
    "ArmBCSettings": "arm_policies",
    "ArmGroundingSetup": "arm_grounding",
    "ArmPolicy": "arm_policies",
    "BCArmPolicy": "arm_policies",
    "EEF_FEATURE": "arm_plan",
    "EVAL_STARTS": "polygon_eval",
    "FREE_SPACE_PLANNERS": "planners",
    "ForwardModel": "classifier",
    "GROUND_TRUTH": "arm_policies",
    "GlideArmPolicy": "arm_policies",
    "GlideArmSettings": "arm_policies",
    "GlideBC": "glide_bc",
    "GlideBCConfig": "mode_policies",
    "GlideBCPolicy": "mode_policies",
    "GlideLossWeights": "classifier",
    "GlidePlan": "llm_plan",
    "GlidePlanningPolicy": "mode_policies",
    "GlideSetup": "polygon",
    "GlideTrainConfig": "classifier",
    "GlideTrainResult": "training",
    "Grounding": "polygon",
    "KMeansModes": "kmeans",
    "KMeansSegmentation": "kmeans",
    "LLMProvider": "llm_plan",
    "LOSS_TERMS": "classifier",
    "LearnedModeMap": "planners",
    "ModeAttractor": "arm_policies",
    "ModeClassifier": "classifier",
    "ModePredictor": "modes",
    "OBJECT_MOTION": "arm_plan",
    "PLAN_STEPS": "arm_plan",
    "POLYGON_ENV_IDS": "polygon",
    "POLYGON_METHODS": "polygon",
    "POLYGON_VARIANTS": "polygon",
    "PackedTrajectories": "packing",
    "PerturbationSchedule": "polygon_eval",
    "PlanStep": "llm_plan",
    "PlannerConfig": "planners",
    "PublicCodeAttractor": "public_attractor",
    "ROBOMIMIC_CPU_STEPS": "arm_policies",
    "ROBOMIMIC_STEPS": "arm_policies",
    "ROBOT_MOTION": "arm_plan",
    "RecordedProvider": "llm_plan",
    "SYSTEM_PROMPT": "llm_plan",
    "TASK_STRIDE": "arm_plan",
    "build_prompt": "llm_plan",
    "cached_classifier_info": "polygon",
    "check_arm_predictor": "arm_policies",
    "counterfactual_data": "polygon",
    "data_cache_path": "polygon",
    "demo_modes": "arm_policies",
    "dynamics_columns": "arm_plan",
    "evaluate_arm_grounding": "arm_grounding",
    "evaluate_arm_policy": "arm_eval",
    "evaluate_polygon_policy": "polygon_eval",
    "extract_tag": "llm_plan",
    "feasibility_for": "polygon",
    "glide_losses": "losses",
    "grounding_scores": "polygon_eval",
    "label_demonstrations": "modes",
    "learn_grounding": "polygon",
    "make_polygon_policy": "polygon",
    "manipulation_feasibility": "arm_plan",
    "mean_end_state": "mode_policies",
    "mode_attractors": "arm_policies",
    "mode_entry_points": "mode_policies",
    "mode_iou": "modes",
    "mode_overlap": "modes",
    "num_modes": "arm_plan",
    "pack_trajectories": "packing",
    "parse_plan_response": "llm_plan",
    "plan_goal_features": "arm_plan",
    "polygon_demonstrations": "polygon",
    "potential_field": "planners",
    "recorded_plan": "arm_plan",
    "request_plan": "llm_plan",
    "rrt": "planners",
    "selected_columns": "arm_plan",
    "selected_features": "arm_plan",
    "train_arm_policy": "arm_policies",
    "train_arm_predictor": "arm_grounding",
    "train_bc": "mode_policies",
    "train_mode_classifier": "training",
    "workspace_grid": "modes",
}

__all__ = [
    "ARM_ATTRACTORS",
    "ARM_BC_RECIPES",
    "ARM_METHODS",
    "ARM_VARIANTS",
    "ATTRACTOR_MODES",
    "EEF_FEATURE",
    "EVAL_STARTS",
    "FREE_SPACE_PLANNERS",
    "GROUND_TRUTH",
    "LOSS_TERMS",
    "OBJECT_MOTION",
    "PLAN_STEPS",
    "POLYGON_ENV_IDS",
    "POLYGON_METHODS",
    "POLYGON_VARIANTS",
    "ROBOMIMIC_CPU_STEPS",
    "ROBOMIMIC_STEPS",
    "ROBOT_MOTION",
    "SYSTEM_PROMPT",
    "TASK_STRIDE",
    "ArmBC",
    "ArmBCSettings",
    "ArmGroundingSetup",
    "ArmPolicy",
    "BCArmPolicy",
    "ForwardModel",
    "GlideArmPolicy",
    "GlideArmSettings",
    "GlideBC",
    "GlideBCConfig",
    "GlideBCPolicy",
    "GlideLossWeights",
    "GlidePlan",
    "GlidePlanningPolicy",
    "GlideSetup",
    "GlideTrainConfig",
    "GlideTrainResult",
    "Grounding",
    "KMeansModes",
    "KMeansSegmentation",
    "LLMProvider",
    "LearnedModeMap",
    "ModeAttractor",
    "ModeClassifier",
    "ModePredictor",
    "PackedTrajectories",
    "PerturbationSchedule",
    "PlanStep",
    "PlannerConfig",
    "PublicCodeAttractor",
    "RecordedProvider",
    "build_prompt",
    "cached_classifier_info",
    "check_arm_predictor",
    "counterfactual_data",
    "data_cache_path",
    "demo_modes",
    "dynamics_columns",
    "evaluate_arm_grounding",
    "evaluate_arm_policy",
    "evaluate_polygon_policy",
    "extract_tag",
    "feasibility_for",
    "glide_losses",
    "grounding_scores",
    "label_demonstrations",
    "learn_grounding",
    "make_polygon_policy",
    "manipulation_feasibility",
    "mean_end_state",
    "mode_attractors",
    "mode_entry_points",
    "mode_iou",
    "mode_overlap",
    "num_modes",
    "pack_trajectories",
    "parse_plan_response",
    "plan_goal_features",
    "polygon_demonstrations",
    "potential_field",
    "recorded_plan",
    "request_plan",
    "rrt",
    "selected_columns",
    "selected_features",
    "train_arm_policy",
    "train_arm_predictor",
    "train_bc",
    "train_mode_classifier",
    "workspace_grid",
]


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
