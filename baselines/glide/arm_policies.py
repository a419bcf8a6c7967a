"""GLiDE on the robosuite arms: BC and GLiDE+BC (thesis Table 4.3).

Two policies, both acting on the env's 19-D observation with the 7-D delta-OSC
action (gripper +1 closes), both trained on the successful demonstrations:

* **BC** (:class:`ArmBC`, as a policy :class:`BCArmPolicy`): one mode-agnostic
  MLP ``obs -> action``.
* **GLiDE+BC** (:class:`GlideArmPolicy`): GLiDE+BC's shared core
  (:class:`~steer_envs.baselines.glide.glide_bc.GlideBC`) with this domain's
  parts: the demos are segmented by a mode predictor, one :class:`ArmBC` per
  mode, chosen at every step by the mode predicted for the current state, each
  with a *pseudo-attractor* (:class:`ModeAttractor`) built from the LLM plan's
  goal feature of its mode. The attractor of mode ``k`` is the mean goal
  feature at the demos' transitions ``k -> k + 1`` (in the final mode: at the
  demos' last states). An absolute goal feature (``robot0_eef_pos``) is an eef
  target as it is; a relative one (``X_to_robot0_eef_pos`` = object minus eef)
  is stored relative to the object and turned into an absolute eef target at
  test time from the current object position. Far from its attractor (farther
  than the ``attractor_quantile`` of the mode's demo states are), the
  position part of the action becomes ``(1 - w) pi_k + w * clip(gain * (target - eef))``;
  rotation and gripper stay the policy's.

The mode predictor is anything with ``predict(states) -> modes`` over the
*selected* feature columns of the LLM plan
(:func:`~steer_envs.baselines.glide.arm_plan.selected_columns`),
i.e. the trained GLiDE classifier
(:func:`~steer_envs.baselines.glide.arm_grounding.train_arm_predictor`), or
:class:`~steer_envs.baselines.glide.kmeans.KMeansModes` (the k-means
baseline), or :data:`GROUND_TRUTH`: the demos' recorded modes for the
segmentation and ``info["mode"]`` at test time (a development stand-in).
:func:`~steer_envs.baselines.glide.arm_eval.evaluate_arm_policy` runs a policy.

Choices, and why (where they differ from PolygonNav's
:class:`~steer_envs.baselines.glide.mode_policies.GlideBCPolicy`):

* The number of modes is the ground truth's (3, 3, 4); plan steps map to modes
  by :data:`~steer_envs.baselines.glide.arm_plan.PLAN_STEPS`.
* The BC MLP is :class:`~steer_envs.baselines.bc.modeling.BCPolicy` behind a
  small adapter (:class:`ArmBC`): BCPolicy bounds its output by the *norm*
  (a speed limit, what PolygonNav's velocities need) or by a tanh whose
  targets must lie strictly inside the bound, neither of which fits a box
  action whose gripper targets are exactly +-1. The adapter standardises the
  inputs itself (std floored at ``std_floor``: the demos barely rotate the
  eef, and a 1e-6 floor would blow a small test-time rotation up into a huge
  input), trains the MLP linearly (``output_scale = sqrt(7)``, so the norm
  bound is never active on a box point), and clips each component to [-1, 1].
* The attractor is the plan's goal feature, not the mean entry state: the
  object moves, so a fixed eef point would be the wrong target after the
  object was pushed; and the pull is a clipped proportional command on the
  position part only (the experts' gain 10), not a full-speed step.
* The attractor acts beyond the 0.9 quantile of the mode's demo distances
  (and never within 2 cm of its target, ``min_threshold``): only where the arm
  is farther from the mode's exit than nearly every demo state is, so in
  distribution the mode's BC acts alone; a lower quantile switches the pull on
  in every unperturbed reach, whose straight line to the grasp pose is not the
  demos' approach from above.
* Every mode's MLP standardises its inputs with the statistics of *all* demo
  states (the mode-agnostic BC's): a feature nearly constant within one mode
  (the finger opening while the can is held) would otherwise be divided by
  that mode's tiny spread, and a small test-time deviation would become a
  huge input.
* A mode with no demo pairs (Lift's final mode holds only the demos' last
  state: success ends the episode) uses the nearest mode's policy below it
  (above it if there is none); PolygonNav's lets the attractor alone act.

Options for running the study the way the public GLiDE fork did: the BC
recipe (:meth:`ArmBCSettings.recipe`: ``"robomimic"``, 1024x1024 on raw
observations, tanh output, Adam 1e-4, batch 100), the attractor
(:data:`ARM_ATTRACTORS`: ``"public_code"``, the fork's first-mode pull,
:class:`~steer_envs.baselines.glide.public_attractor.PublicCodeAttractor`)
and the mode it reads (:data:`ATTRACTOR_MODES`: the predictor's, as the
thesis's text says, or the env's true mode, as the fork does).
"""

from __future__ import annotations

import copy
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch

from steer_envs.baselines.bc.modeling import BCConfig, BCPolicy
from steer_envs.baselines.bc.runs import BCRun, train_run
from steer_envs.baselines.glide.arm_plan import (
    EEF_FEATURE,
    RELATIVE_SUFFIX,
    num_modes,
    plan_goal_features,
    recorded_plan,
    selected_columns,
)
from steer_envs.baselines.glide.glide_bc import GlideBC
from steer_envs.baselines.glide.modes import label_demonstrations
from steer_envs.baselines.glide.public_attractor import PublicCodeAttractor
from steer_envs.core.validation import boolean, describe, integer, one_of, real_scalar
from steer_envs.data import robosuite_replays as rr
from steer_envs.envs.robosuite.tasks import TASK_NAMES

__all__ = [
    "ARM_ATTRACTORS",
    "ARM_BC_RECIPES",
    "ARM_METHODS",
    "ATTRACTOR_MODES",
    "GROUND_TRUTH",
    "ROBOMIMIC_CPU_STEPS",
    "ROBOMIMIC_STEPS",
    "ArmBC",
    "ArmBCSettings",
    "ArmPolicy",
    "BCArmPolicy",
    "GlideArmPolicy",
    "GlideArmSettings",
    "ModeAttractor",
    "check_arm_predictor",
    "demo_modes",
    "mode_attractors",
    "train_arm_policy",
]

#: the methods of :func:`train_arm_policy` (thesis Table 4.3's rows).
ARM_METHODS: tuple[str, ...] = ("bc", "glide_bc")
#: the stand-in predictor: the demos' recorded modes for segmentation, ``info["mode"]`` at test time.
GROUND_TRUTH = "ground_truth"
#: the BC recipes of :meth:`ArmBCSettings.recipe`.
ARM_BC_RECIPES: tuple[str, ...] = ("thesis", "robomimic")
#: robomimic's BC budget (minibatch steps), and the robomimic recipe's default here: a quarter of it, about
#: 20 min of one CPU core per 1024x1024 MLP; a run continues to any larger budget from its saved state.
ROBOMIMIC_STEPS = 200_000
ROBOMIMIC_CPU_STEPS = 50_000
#: GLiDE+BC's attractors (:class:`GlideArmPolicy`): the thesis's per-mode blend, or the public fork's first-mode
#: pull (:class:`~steer_envs.baselines.glide.public_attractor.PublicCodeAttractor`).
ARM_ATTRACTORS: tuple[str, ...] = ("thesis", "public_code")
#: which mode an attractor reads: the mode predictor's (the one the policy runs on), or the env's true mode.
ATTRACTOR_MODES: tuple[str, ...] = ("classifier", "ground_truth")
_ACTION_DIM = 7
#: a tanh output's targets: +-1 (the gripper) sits on tanh's bound, which :class:`BCPolicy` refuses
_TANH_TARGET = 1.0 - 1e-6


class ArmPolicy(Protocol):
    """A policy of this study: one action ``(7,)`` from the observation, the feature vector and the mode.

    ``true_mode`` is the env's ground-truth mode (``info["mode"]``, ``None`` where it is not known): a policy
    whose attractor reads the true mode needs it.
    """

    def act(self, obs: np.ndarray, features: np.ndarray, mode: int, true_mode: int | None = None) -> np.ndarray:
        """The action for the current state (``mode`` is ignored by mode-agnostic policies)."""
        ...


def _task(task: Any) -> str:
    return one_of(task, "task", TASK_NAMES, owner="glide arm policies")


# ------------------------------------------------------------------------------- BC
@dataclass(frozen=True)
class ArmBCSettings:
    """Architecture and training of one :class:`ArmBC` MLP (ReLU hidden layers, Adam, minibatches with replacement).

    ``standardize``: standardise the inputs (std floored at ``std_floor``) or
    feed the raw observations; ``output``: ``"clip"``, a linear output clipped
    to [-1, 1] per component, or ``"tanh"``, squashed by tanh as robomimic's
    actor is (trained on targets within ``1 - 1e-6`` of +-1: the gripper's
    +-1 lies on tanh's bound). :meth:`recipe` gives the named recipes.

    >>> ArmBCSettings().hidden, ArmBCSettings().steps
    ((256, 256), 8000)
    >>> r = ArmBCSettings.recipe("robomimic")
    >>> r.hidden, r.lr, r.batch_size, r.standardize, r.output, r.steps
    ((1024, 1024), 0.0001, 100, False, 'tanh', 50000)
    """

    hidden: tuple[int, ...] = (256, 256)
    steps: int = 8000
    batch_size: int = 256
    lr: float = 1e-3
    std_floor: float = 0.01
    standardize: bool = True
    output: str = "clip"

    def __post_init__(self) -> None:
        owner = "ArmBCSettings"
        if not isinstance(self.hidden, tuple) or not self.hidden:
            raise TypeError(f"{owner}: `hidden` must be a non-empty tuple of ints, got {describe(self.hidden)}")
        for h in self.hidden:
            integer(h, "hidden", low=1, owner=owner)
        integer(self.steps, "steps", low=0, owner=owner)
        integer(self.batch_size, "batch_size", low=1, owner=owner)
        real_scalar(self.lr, "lr", low=0.0, low_inclusive=False, owner=owner)
        real_scalar(self.std_floor, "std_floor", low=0.0, low_inclusive=False, owner=owner)
        boolean(self.standardize, "standardize", owner=owner)
        one_of(self.output, "output", ("clip", "tanh"), owner=owner)

    @classmethod
    def recipe(cls, name: str, *, hidden: tuple[int, ...] | None = None, steps: int | None = None) -> ArmBCSettings:
        """The settings of a named recipe (:data:`ARM_BC_RECIPES`), its layers or steps replaced where given.

        ``"thesis"``: this study's BC (the defaults: 256x256, standardised
        inputs, Adam 1e-3, batch 256, 8000 steps). ``"robomimic"``: robomimic's
        BC as the public GLiDE fork trains it: 1024x1024 on raw observations,
        tanh output, Adam 1e-4, batch 100; :data:`ROBOMIMIC_CPU_STEPS` steps
        (robomimic's are :data:`ROBOMIMIC_STEPS`).
        """
        name = one_of(name, "recipe", ARM_BC_RECIPES, owner="ArmBCSettings.recipe")
        base = cls()
        if name == "robomimic":
            base = cls(
                hidden=(1024, 1024),
                steps=ROBOMIMIC_CPU_STEPS,
                batch_size=100,
                lr=1e-4,
                standardize=False,
                output="tanh",
            )
        changes: dict[str, Any] = {}
        if hidden is not None:
            changes["hidden"] = tuple(hidden)
        if steps is not None:
            changes["steps"] = steps
        return replace(base, **changes)

    def config(self, state_dim: int) -> BCConfig:
        """The :class:`BCConfig` of the MLP (``clip``: linear output in units of ``sqrt(7)``; ``tanh``: bound 1;
        inputs standardised outside, if at all)."""
        tanh = self.output == "tanh"
        return BCConfig(
            state_dim=state_dim,
            action_dim=_ACTION_DIM,
            hidden=self.hidden,
            output="tanh" if tanh else "clip",
            output_scale=1.0 if tanh else math.sqrt(_ACTION_DIM),
            standardize=False,
            lr=self.lr,
            batch_size=self.batch_size,
            epochs=None,
            steps=self.steps,
        )


class ArmBC:
    """BC for a box action: (optionally) standardised inputs, a :class:`BCPolicy` MLP, each action component in [-1, 1].

    Trained by :func:`~steer_envs.baselines.bc.runs.train_run`: with ``cache_dir``
    the run is kept under ``<cache_dir>/<run key>`` (its state at
    ``keep_steps`` and at ``settings.steps``, and every two minutes the
    latest), so the same training (settings but the steps, seed, data) is
    read instead of trained, a killed one continues from its last saved
    step, and a larger budget continues a smaller one's run.

    Args:
        states: ``(N, d)`` training inputs; actions: ``(N, 7)`` targets in [-1, 1].
        seed: seeds the weights and the minibatches.
        settings: the MLP and its training.
        standardization: ``(mean, std)`` of the inputs (``(d,)`` each) to use instead of
            the statistics of ``states`` (the std is floored at ``settings.std_floor`` either way);
            ignored with ``settings.standardize`` off (raw inputs).
        cache_dir: the folder of the cached runs (``None``: train in memory only).
        keep_steps: steps (``1 .. settings.steps``) whose weights :meth:`at_step` gives (a learning curve).

    >>> import numpy as np
    >>> x = np.random.default_rng(0).normal(size=(40, 3))
    >>> a = np.clip(np.c_[x, x, x[:, :1]], -1, 1)
    >>> bc = ArmBC(x, a, settings=ArmBCSettings(hidden=(16,), steps=10), keep_steps=(5,))
    >>> bc.act(10 * x).shape, bool(np.all(np.abs(bc.act(10 * x)) <= 1)), bc.at_step(5).steps
    ((40, 7), True, 5)
    """

    def __init__(
        self,
        states: np.ndarray,
        actions: np.ndarray,
        *,
        seed: int = 0,
        settings: ArmBCSettings | None = None,
        standardization: tuple[np.ndarray, np.ndarray] | None = None,
        cache_dir: str | os.PathLike[str] | None = None,
        keep_steps: Sequence[int] = (),
    ) -> None:
        s = np.asarray(states, dtype=np.float64)
        a = np.asarray(actions, dtype=np.float64)
        if s.ndim != 2 or a.shape != (len(s), _ACTION_DIM) or len(s) == 0:
            raise ValueError(f"ArmBC: states (N>=1, d) and actions (N, 7) needed, got {s.shape} and {a.shape}")
        if cache_dir is not None and not isinstance(cache_dir, (str, os.PathLike)):
            raise TypeError(f"ArmBC: `cache_dir` must be a path or None, got {describe(cache_dir)}")
        self.settings = settings or ArmBCSettings()
        if not self.settings.standardize:
            mean, std = np.zeros(s.shape[1]), np.ones(s.shape[1])
        else:
            mean, std = (s.mean(0), s.std(0)) if standardization is None else standardization
        self.mean = np.asarray(mean, dtype=np.float64).reshape(s.shape[1])
        self.scale = np.maximum(np.asarray(std, dtype=np.float64).reshape(s.shape[1]), self.settings.std_floor)
        self.policy = BCPolicy(self.settings.config(s.shape[1]), seed=integer(seed, "seed", low=0, owner="ArmBC"))
        bound = _TANH_TARGET if self.settings.output == "tanh" else 1.0
        run = BCRun(self.policy, self._standardized(s), np.clip(a, -bound, bound))
        folder = None if cache_dir is None else Path(cache_dir) / run.key
        steps = self.settings.steps
        #: step -> the weights at that step (:meth:`at_step`)
        self.snapshots: dict[int, dict[str, torch.Tensor]] = {}
        if steps:
            self.snapshots = train_run(run, steps, folder=folder, keep=tuple(keep_steps))
        elif keep_steps:
            raise ValueError(f"ArmBC: `keep_steps` must lie in [1, steps], got {list(keep_steps)} with steps=0")
        #: ``[[step, mean loss], ...]`` of the run; the steps trained in this process (the rest were read)
        self.losses = run.losses
        self.trained_steps = run.steps_trained
        self.run_folder = folder

    @property
    def steps(self) -> int:
        """The training steps of the weights :meth:`act` uses."""
        return self.policy.trained_for

    def at_step(self, step: int) -> ArmBC:
        """This BC with its weights at ``step`` (one of the ``keep_steps``, or ``settings.steps``)."""
        if step not in self.snapshots:
            raise ValueError(f"ArmBC.at_step: no weights kept at step {step!r}; kept: {sorted(self.snapshots)}")
        out = copy.copy(self)
        out.policy = BCPolicy(self.policy.config, seed=self.policy.seed)
        out.policy.net.load_state_dict(self.snapshots[step])
        out.policy.trained_for = step
        return out

    def _standardized(self, s: np.ndarray) -> np.ndarray:
        return (np.asarray(s, dtype=np.float64) - self.mean) / self.scale

    def act(self, states: np.ndarray) -> np.ndarray:
        """Actions for states ``(N, d) -> (N, 7)`` (``(d,) -> (7,)``), each component in [-1, 1]."""
        return np.clip(self.policy(self._standardized(states)), -1.0, 1.0)


class BCArmPolicy:
    """The mode-agnostic BC baseline as an :class:`ArmPolicy` (observation in, features and modes ignored)."""

    def __init__(self, bc: ArmBC) -> None:
        self.bc = bc

    def act(self, obs: np.ndarray, features: np.ndarray, mode: int, true_mode: int | None = None) -> np.ndarray:
        """BC's action for ``obs``."""
        return self.bc.act(np.asarray(obs, dtype=np.float64))

    def at_step(self, step: int) -> BCArmPolicy:
        """The policy with BC's weights at ``step`` (:meth:`ArmBC.at_step`)."""
        return BCArmPolicy(self.bc.at_step(step))

    @property
    def trained_steps(self) -> int:
        """The BC steps trained in this process (the rest were read from the run cache)."""
        return self.bc.trained_steps


# ----------------------------------------------------------------------- attractors
@dataclass(frozen=True)
class ModeAttractor:
    """One mode's pseudo-attractor in the terms of its goal feature.

    Attributes:
        feature: the goal feature (``robot0_eef_pos`` or ``<object>_to_robot0_eef_pos``).
        columns: its 3 columns in the task's feature vector.
        eef_columns: the columns of ``robot0_eef_pos``.
        value: the mean goal feature at the mode's exits (absolute: an eef position;
            relative: object minus eef, m).
        threshold: the attractor acts when the eef is farther than this from its target (m).
    """

    feature: str
    columns: np.ndarray
    eef_columns: np.ndarray
    value: np.ndarray
    threshold: float = math.inf

    @property
    def relative(self) -> bool:
        """The goal feature is object-relative (its target follows the object)."""
        return self.feature.endswith(RELATIVE_SUFFIX)

    def target(self, features: np.ndarray) -> np.ndarray:
        """The eef target ``(3,)`` (or ``(N, 3)``) for feature vectors ``(D,)`` / ``(N, D)``.

        Relative: the object is at ``eef + f``, the target keeps it at ``value``
        from the eef, so ``target = eef + f - value``; absolute: ``value``.
        """
        f = np.asarray(features, dtype=np.float64)
        if not self.relative:
            return np.broadcast_to(self.value, (*f.shape[:-1], 3)).copy()
        return f[..., self.eef_columns] + f[..., self.columns] - self.value

    def distance(self, features: np.ndarray) -> np.ndarray:
        """``|target - eef|`` for feature vectors ``(D,)`` / ``(N, D)``."""
        f = np.asarray(features, dtype=np.float64)
        return np.asarray(np.linalg.norm(self.target(f) - f[..., self.eef_columns], axis=-1))


def mode_attractors(
    task: str,
    features: Sequence[np.ndarray],
    modes: Sequence[np.ndarray],
    *,
    plan: Any = None,
    quantile: float = 0.9,
    min_threshold: float = 0.0,
) -> list[ModeAttractor]:
    """The pseudo-attractor of every mode from labelled demos (feature rows ``(T_i, D)``, modes ``(T_i,)``).

    Mode ``k < K - 1``: the mean goal feature of the first state after each
    ``k -> k + 1`` transition in the labels; the final mode, or a mode the labels
    never leave forward: the mean goal feature of the demos' last states. The
    threshold is the ``quantile`` of ``|target - eef|`` over the mode's labelled
    states, at least ``min_threshold`` (inf for a mode with none). ``plan``: a parsed LLM plan with
    ``goals`` (default: the recorded plan of ``task``).
    """
    task = _task(task)
    quantile = real_scalar(quantile, "quantile", low=0.0, high=1.0, owner="mode_attractors")
    min_threshold = real_scalar(min_threshold, "min_threshold", low=0.0, owner="mode_attractors")
    if len(features) == 0 or len(features) != len(modes):
        raise ValueError(f"features and modes must be non-empty and of equal length, got {len(features)}, {len(modes)}")
    if plan is None:
        plan = recorded_plan(task)
    k_modes = num_modes(task)
    names = plan_goal_features(task, plan)
    eef_cols = rr.feature_columns(task, [EEF_FEATURE])
    f_all = [np.asarray(f, dtype=np.float64) for f in features]
    m_all = [np.asarray(m, dtype=np.int64) for m in modes]
    for f, m in zip(f_all, m_all, strict=True):
        if f.ndim != 2 or m.shape != (len(f),):
            raise ValueError(f"each demo needs features (T, D) and modes (T,), got {f.shape} and {m.shape}")
    states, labels = np.concatenate(f_all), np.concatenate(m_all)
    out = []
    for k, name in enumerate(names):
        cols = rr.feature_columns(task, [name])
        exits = [f[1:][(m[:-1] == k) & (m[1:] == k + 1)] for f, m in zip(f_all, m_all, strict=True)]
        at = np.concatenate(exits)[:, cols] if k + 1 < k_modes else np.zeros((0, 3))
        if len(at) == 0:
            at = np.stack([f[-1, cols] for f in f_all])
        attractor = ModeAttractor(name, cols, eef_cols, at.mean(0))
        sel = labels == k
        threshold = math.inf
        if sel.any():
            threshold = GlideBC.threshold(attractor.distance(states[sel]), quantile, min_threshold)
        out.append(ModeAttractor(name, cols, eef_cols, attractor.value, threshold))
    return out


# ------------------------------------------------------------------------- GLiDE+BC
class GlideArmPolicy(GlideBC[ArmBC]):
    """GLiDE+BC on an arm: one :class:`ArmBC` per mode plus an attractor (see the module).

    Args:
        task: the task name.
        demos: the successful demos (:class:`~steer_envs.data.robosuite_replays.ArmTrajectory`).
        modes: each demo's per-state mode labels (the predictor's, or the ground truth; :func:`demo_modes`).
        plan: the parsed LLM plan (default: the recorded one).
        attractor_weight: ``w``, in [0, 1].
        attractor_quantile: the attractor acts beyond this quantile of the mode's demo distances ...
        min_threshold: ... and never within this distance of its target (m): in a mode whose demo
            states all sit on the attractor (Lift's grasped cube) the quantile is ~0, and the term
            would halve every command of the mode.
        gain: the proportional gain of the attractor's position command (the experts' 10).
        seed: seeds the BC training (mode ``k``'s MLP gets ``1000 * seed + k``).
        settings: the BC MLPs (each mode's MLP trains as many steps as the mode-agnostic BC).
        attractor: ``"thesis"`` (the per-mode :class:`ModeAttractor` blend; the four
            arguments above) or ``"public_code"`` (the fork's first-mode pull).
        attractor_mode: the mode the attractor reads: ``"classifier"``, the one the
            policy runs on (``mode`` of :meth:`act`), or ``"ground_truth"``, the env's
            (``true_mode``); the attractor is built from the same labels (``modes``, or
            the demos' recorded ones).
        cache_dir, keep_steps: each mode's :class:`ArmBC` run cache and kept steps.
    """

    def __init__(
        self,
        task: str,
        demos: Sequence[rr.ArmTrajectory],
        modes: Sequence[np.ndarray],
        *,
        plan: Any = None,
        attractor_weight: float = 0.5,
        attractor_quantile: float = 0.9,
        min_threshold: float = 0.02,
        gain: float = 10.0,
        seed: int = 0,
        settings: ArmBCSettings | None = None,
        attractor: str = "thesis",
        attractor_mode: str = "classifier",
        cache_dir: str | os.PathLike[str] | None = None,
        keep_steps: Sequence[int] = (),
    ) -> None:
        who = "GlideArmPolicy"
        self.task = _task(task)
        if len(demos) == 0 or len(demos) != len(modes):
            raise ValueError(f"{who}: demos and modes must be non-empty and of equal length")
        super().__init__(num_modes(self.task), attractor_weight=attractor_weight, owner=who)
        self.gain = real_scalar(gain, "gain", low=0.0, owner=who)
        self.attractor = one_of(attractor, "attractor", ARM_ATTRACTORS, owner=who)
        self.attractor_mode = one_of(attractor_mode, "attractor_mode", ATTRACTOR_MODES, owner=who)
        seed = integer(seed, "seed", low=0, owner=who)
        labels = [np.asarray(m, dtype=np.int64) for m in modes]
        for m in labels:
            if m.size and (m.min() < 0 or m.max() >= self.num_modes):
                raise ValueError(f"{who}: mode labels must lie in [0, {self.num_modes}), got {np.unique(m).tolist()}")
        by = labels if self.attractor_mode == "classifier" else [np.asarray(d.modes, dtype=np.int64) for d in demos]
        features = [d.features for d in demos]
        self.attractors = mode_attractors(
            self.task, features, by, plan=plan, quantile=attractor_quantile, min_threshold=min_threshold
        )
        #: the fork's first-mode pull (with ``attractor="public_code"``)
        self.public = PublicCodeAttractor.from_demos(self.task, features, by) if attractor == "public_code" else None
        obs = np.concatenate([d.obs[:-1] for d in demos]).astype(np.float64)
        acts = np.concatenate([d.actions for d in demos]).astype(np.float64)
        state_modes = np.concatenate([m[:-1] for m in labels])
        if len(obs) != len(acts) or len(state_modes) != len(obs):
            raise ValueError(f"{who}: every demo needs T - 1 actions and T mode labels for its T states")
        base = settings or ArmBCSettings()
        stats = (obs.mean(0), obs.std(0))  # every mode's inputs scaled as the mode-agnostic BC's are

        def fit(s: np.ndarray, a: np.ndarray, k: int) -> ArmBC | None:
            if not len(s):
                return None
            return ArmBC(
                s,
                a,
                seed=1000 * seed + k,
                settings=base,
                standardization=stats,
                cache_dir=cache_dir,
                keep_steps=keep_steps,
            )

        self.fit_modes(obs, acts, state_modes, fit)
        trained = [k for k, p in enumerate(self.policies) if p is not None]
        if not trained:
            raise ValueError(f"{who}: no demo pairs to train on")
        #: mode -> the mode whose BC it uses (itself, or the nearest trained one below, else above)
        self.policy_of = [self._nearest(k, trained) for k in range(self.num_modes)]

    @staticmethod
    def _nearest(k: int, trained: Sequence[int]) -> int:
        below = [j for j in trained if j <= k]
        return max(below) if below else min(trained)

    @property
    def trained_steps(self) -> int:
        """The BC steps trained in this process over every mode (the rest were read from the run cache)."""
        return sum(p.trained_steps for p in self.policies if p is not None)

    def at_step(self, step: int) -> GlideArmPolicy:
        """The policy with every mode's BC weights at ``step`` (:meth:`ArmBC.at_step`)."""
        out = copy.copy(self)
        out.policies = [None if p is None else p.at_step(step) for p in self.policies]
        return out

    def act(self, obs: np.ndarray, features: np.ndarray, mode: int, true_mode: int | None = None) -> np.ndarray:
        """Mode ``mode``'s BC action, with the attractor of the mode it reads (``mode``, or ``true_mode``)."""
        k = integer(mode, "mode", low=0, high=self.num_modes - 1, owner="GlideArmPolicy.act")
        policy = self.policies[self.policy_of[k]]
        assert policy is not None  # policy_of names trained modes only
        action = policy.act(np.asarray(obs, dtype=np.float64))
        if self.attractor_mode == "ground_truth":
            if true_mode is None:
                raise ValueError("GlideArmPolicy.act: its attractor reads the true mode; pass `true_mode`")
            k = integer(true_mode, "true_mode", low=0, high=self.num_modes - 1, owner="GlideArmPolicy.act")
        return self.attract(action, features, k)

    def attract(self, action: np.ndarray, features: np.ndarray, mode: int) -> np.ndarray:
        """``action`` with the attractor term of ``mode`` applied.

        Thesis: mixed into the position part when far enough from the mode's
        attractor; public code: the first mode's pull (:class:`PublicCodeAttractor`).
        """
        if self.public is not None:
            return self.public.apply(action, features) if mode == 0 else np.array(action, dtype=np.float64)
        out = np.array(action, dtype=np.float64, copy=True)
        attractor = self.attractors[mode]
        f = np.asarray(features, dtype=np.float64)
        eef = f[attractor.eef_columns]
        target = attractor.target(f)
        if float(np.linalg.norm(target - eef)) > attractor.threshold:
            pull = np.clip(self.gain * (target - eef), -1.0, 1.0)
            out[:3] = self.blend(out[:3], pull)
        return out


# ------------------------------------------------------------------------ predictors
def check_arm_predictor(predictor: Any) -> None:
    """Raise TypeError unless ``predictor`` has ``predict(states)`` or is :data:`GROUND_TRUTH`."""
    if predictor != GROUND_TRUTH and not callable(getattr(predictor, "predict", None)):
        raise TypeError(
            f"`predictor` must have predict(states) -> modes or be {GROUND_TRUTH!r}, got {describe(predictor)}"
        )


def demo_modes(task: str, demos: Sequence[rr.ArmTrajectory], predictor: Any) -> list[np.ndarray]:
    """Each demo's per-state modes: the recorded ground truth (:data:`GROUND_TRUTH`) or the predictor's.

    A predictor reads the selected feature columns
    (:func:`~steer_envs.baselines.glide.arm_plan.selected_columns`) of every state.
    """
    task = _task(task)
    check_arm_predictor(predictor)
    if predictor == GROUND_TRUTH:
        return [np.asarray(d.modes, dtype=np.int64) for d in demos]
    cols = selected_columns(task)
    out = label_demonstrations(predictor, [d.features[:, cols] for d in demos], num_modes(task))
    for d, m in zip(demos, out, strict=True):
        if m.shape != (len(d),):
            raise ValueError(f"the predictor must give one mode per state ({len(d)}), got shape {m.shape}")
    return out


# ---------------------------------------------------------------------------- train
@dataclass(frozen=True)
class GlideArmSettings:
    """GLiDE+BC's attractor settings on the arms (see :class:`GlideArmPolicy`).

    >>> GlideArmSettings().attractor_quantile, GlideArmSettings().min_threshold, GlideArmSettings().attractor
    (0.9, 0.02, 'thesis')
    """

    attractor_weight: float = 0.5
    attractor_quantile: float = 0.9
    min_threshold: float = 0.02
    gain: float = 10.0
    attractor: str = "thesis"
    attractor_mode: str = "classifier"


def _check_demos(task: str, demos: Any) -> list[rr.ArmTrajectory]:
    if not isinstance(demos, Sequence) or len(demos) == 0:
        raise ValueError(f"`demos` must be a non-empty sequence of ArmTrajectory, got {describe(demos)}")
    for d in demos:
        if not isinstance(d, rr.ArmTrajectory) or d.task != task or len(d.actions) == 0:
            raise ValueError(f"`demos` must hold ArmTrajectory demos of task {task!r} with at least one action")
    return list(demos)


def train_arm_policy(
    task: str,
    method: str,
    seed: int,
    *,
    demos: Sequence[rr.ArmTrajectory],
    predictor: Any = GROUND_TRUTH,
    bc: ArmBCSettings | None = None,
    glide: GlideArmSettings | None = None,
    plan: Any = None,
    cache_dir: str | os.PathLike[str] | None = None,
    keep_steps: Sequence[int] = (),
) -> BCArmPolicy | GlideArmPolicy:
    """A trained :class:`ArmPolicy`: ``"bc"`` (all demo pairs) or ``"glide_bc"`` (per predicted mode).

    ``predictor`` labels the demos for GLiDE+BC (:func:`demo_modes`); ``bc``
    sets every BC MLP, ``glide`` the attractors, ``plan`` the LLM plan
    (default: the recorded one). ``cache_dir``: where every BC run is kept
    (read instead of trained when it is there; see :class:`ArmBC`);
    ``keep_steps``: the steps whose weights the policy's ``at_step`` gives.
    """
    task = _task(task)
    method = one_of(method, "method", ARM_METHODS, owner="train_arm_policy")
    seed = integer(seed, "seed", low=0, owner="train_arm_policy")
    demos = _check_demos(task, demos)
    if method == "bc":
        obs = np.concatenate([d.obs[:-1] for d in demos])
        acts = np.concatenate([d.actions for d in demos])
        return BCArmPolicy(ArmBC(obs, acts, seed=seed, settings=bc, cache_dir=cache_dir, keep_steps=keep_steps))
    g = glide or GlideArmSettings()
    return GlideArmPolicy(
        task,
        demos,
        demo_modes(task, demos, predictor),
        plan=plan,
        attractor_weight=g.attractor_weight,
        attractor_quantile=g.attractor_quantile,
        min_threshold=g.min_threshold,
        gain=g.gain,
        seed=seed,
        settings=bc,
        attractor=g.attractor,
        attractor_mode=g.attractor_mode,
        cache_dir=cache_dir,
        keep_steps=keep_steps,
    )
