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
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from steer_envs.baselines.bc.modeling import BCConfig, BCPolicy
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
from steer_envs.core.validation import describe, integer, one_of, real_scalar
from steer_envs.data import robosuite_replays as rr
from steer_envs.envs.robosuite.tasks import TASK_NAMES

__all__ = [
    "ARM_METHODS",
    "GROUND_TRUTH",
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
_ACTION_DIM = 7


class ArmPolicy(Protocol):
    """A policy of this study: one action ``(7,)`` from the observation, the feature vector and the mode."""

    def act(self, obs: np.ndarray, features: np.ndarray, mode: int) -> np.ndarray:
        """The action for the current state (``mode`` is ignored by mode-agnostic policies)."""
        ...


def _task(task: Any) -> str:
    return one_of(task, "task", TASK_NAMES, owner="glide arm policies")


# ------------------------------------------------------------------------------- BC
@dataclass(frozen=True)
class ArmBCSettings:
    """Architecture and training of one :class:`ArmBC` MLP (ReLU hidden layers, Adam, minibatches with replacement).

    >>> ArmBCSettings().hidden, ArmBCSettings().steps
    ((256, 256), 8000)
    """

    hidden: tuple[int, ...] = (256, 256)
    steps: int = 8000
    batch_size: int = 256
    lr: float = 1e-3
    std_floor: float = 0.01

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

    def config(self, state_dim: int) -> BCConfig:
        """The :class:`BCConfig` of the MLP (linear output in units of ``sqrt(7)``, inputs standardised outside)."""
        return BCConfig(
            state_dim=state_dim,
            action_dim=_ACTION_DIM,
            hidden=self.hidden,
            output="clip",
            output_scale=math.sqrt(_ACTION_DIM),
            standardize=False,
            lr=self.lr,
            batch_size=self.batch_size,
            epochs=None,
            steps=self.steps,
        )


class ArmBC:
    """BC for a box action: standardised inputs, a :class:`BCPolicy` MLP, each action component clipped to [-1, 1].

    Args:
        states: ``(N, d)`` training inputs; actions: ``(N, 7)`` targets in [-1, 1].
        seed: seeds the weights and the minibatches.
        settings: the MLP and its training.
        standardization: ``(mean, std)`` of the inputs (``(d,)`` each) to use instead of
            the statistics of ``states`` (the std is floored at ``settings.std_floor`` either way).

    >>> import numpy as np
    >>> x = np.random.default_rng(0).normal(size=(40, 3))
    >>> a = np.clip(np.c_[x, x, x[:, :1]], -1, 1)
    >>> bc = ArmBC(x, a, settings=ArmBCSettings(hidden=(16,), steps=10))
    >>> bc.act(10 * x).shape, bool(np.all(np.abs(bc.act(10 * x)) <= 1))
    ((40, 7), True)
    """

    def __init__(
        self,
        states: np.ndarray,
        actions: np.ndarray,
        *,
        seed: int = 0,
        settings: ArmBCSettings | None = None,
        standardization: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        s = np.asarray(states, dtype=np.float64)
        a = np.asarray(actions, dtype=np.float64)
        if s.ndim != 2 or a.shape != (len(s), _ACTION_DIM) or len(s) == 0:
            raise ValueError(f"ArmBC: states (N>=1, d) and actions (N, 7) needed, got {s.shape} and {a.shape}")
        self.settings = settings or ArmBCSettings()
        mean, std = (s.mean(0), s.std(0)) if standardization is None else standardization
        self.mean = np.asarray(mean, dtype=np.float64).reshape(s.shape[1])
        self.scale = np.maximum(np.asarray(std, dtype=np.float64).reshape(s.shape[1]), self.settings.std_floor)
        self.policy = BCPolicy(self.settings.config(s.shape[1]), seed=integer(seed, "seed", low=0, owner="ArmBC"))
        self.losses = self.policy.fit(self._standardized(s), np.clip(a, -1.0, 1.0))

    def _standardized(self, s: np.ndarray) -> np.ndarray:
        return (np.asarray(s, dtype=np.float64) - self.mean) / self.scale

    def act(self, states: np.ndarray) -> np.ndarray:
        """Actions for states ``(N, d) -> (N, 7)`` (``(d,) -> (7,)``), each component in [-1, 1]."""
        return np.clip(self.policy(self._standardized(states)), -1.0, 1.0)


class BCArmPolicy:
    """The mode-agnostic BC baseline as an :class:`ArmPolicy` (observation in, features and mode ignored)."""

    def __init__(self, bc: ArmBC) -> None:
        self.bc = bc

    def act(self, obs: np.ndarray, features: np.ndarray, mode: int) -> np.ndarray:
        """BC's action for ``obs``."""
        return self.bc.act(np.asarray(obs, dtype=np.float64))


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
    """GLiDE+BC on an arm: one :class:`ArmBC` per mode plus its pseudo-attractor (see the module).

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
    ) -> None:
        who = "GlideArmPolicy"
        self.task = _task(task)
        if len(demos) == 0 or len(demos) != len(modes):
            raise ValueError(f"{who}: demos and modes must be non-empty and of equal length")
        super().__init__(num_modes(self.task), attractor_weight=attractor_weight, owner=who)
        self.gain = real_scalar(gain, "gain", low=0.0, owner=who)
        seed = integer(seed, "seed", low=0, owner=who)
        labels = [np.asarray(m, dtype=np.int64) for m in modes]
        for m in labels:
            if m.size and (m.min() < 0 or m.max() >= self.num_modes):
                raise ValueError(f"{who}: mode labels must lie in [0, {self.num_modes}), got {np.unique(m).tolist()}")
        self.attractors = mode_attractors(
            self.task,
            [d.features for d in demos],
            labels,
            plan=plan,
            quantile=attractor_quantile,
            min_threshold=min_threshold,
        )
        obs = np.concatenate([d.obs[:-1] for d in demos]).astype(np.float64)
        acts = np.concatenate([d.actions for d in demos]).astype(np.float64)
        state_modes = np.concatenate([m[:-1] for m in labels])
        if len(obs) != len(acts) or len(state_modes) != len(obs):
            raise ValueError(f"{who}: every demo needs T - 1 actions and T mode labels for its T states")
        base = settings or ArmBCSettings()
        stats = (obs.mean(0), obs.std(0))  # every mode's inputs scaled as the mode-agnostic BC's are

        def fit(s: np.ndarray, a: np.ndarray, k: int) -> ArmBC | None:
            return ArmBC(s, a, seed=1000 * seed + k, settings=base, standardization=stats) if len(s) else None

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

    def act(self, obs: np.ndarray, features: np.ndarray, mode: int) -> np.ndarray:
        """Mode ``mode``'s BC action, its position part pulled toward the attractor when far from it."""
        k = integer(mode, "mode", low=0, high=self.num_modes - 1, owner="GlideArmPolicy.act")
        policy = self.policies[self.policy_of[k]]
        assert policy is not None  # policy_of names trained modes only
        action = policy.act(np.asarray(obs, dtype=np.float64))
        return self.attract(action, features, k)

    def attract(self, action: np.ndarray, features: np.ndarray, mode: int) -> np.ndarray:
        """``action`` with the attractor term of ``mode`` mixed into its position part (when far enough)."""
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

    >>> GlideArmSettings().attractor_quantile, GlideArmSettings().min_threshold
    (0.9, 0.02)
    """

    attractor_weight: float = 0.5
    attractor_quantile: float = 0.9
    min_threshold: float = 0.02
    gain: float = 10.0


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
) -> ArmPolicy:
    """A trained :class:`ArmPolicy`: ``"bc"`` (all demo pairs) or ``"glide_bc"`` (per predicted mode).

    ``predictor`` labels the demos for GLiDE+BC (:func:`demo_modes`); ``bc``
    sets every BC MLP, ``glide`` the attractors, ``plan`` the LLM plan
    (default: the recorded one).
    """
    task = _task(task)
    method = one_of(method, "method", ARM_METHODS, owner="train_arm_policy")
    seed = integer(seed, "seed", low=0, owner="train_arm_policy")
    demos = _check_demos(task, demos)
    if method == "bc":
        obs = np.concatenate([d.obs[:-1] for d in demos])
        acts = np.concatenate([d.actions for d in demos])
        return BCArmPolicy(ArmBC(obs, acts, seed=seed, settings=bc))
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
    )
