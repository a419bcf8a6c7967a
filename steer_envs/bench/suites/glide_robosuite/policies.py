"""GLiDE on the robosuite arms: BC and GLiDE+BC, with and without perturbations (thesis Table 4.3).

Two policies, both acting on the env's 19-D observation with the 7-D delta-OSC
action (gripper +1 closes), both trained on the successful demonstrations:

* **BC** (:class:`ArmBC`): one mode-agnostic MLP ``obs -> action``.
* **GLiDE+BC** (:class:`GlideArmPolicy`, thesis §"Mode-Based Motion
  Generation"): the demos are segmented by a mode predictor, one BC policy
  per mode, chosen at every step by the mode predicted for the current state,
  each with a *pseudo-attractor* (:class:`ModeAttractor`) built from the LLM
  plan's goal feature of its mode. The attractor of mode ``k`` is the mean goal
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
(:func:`~steer_envs.bench.suites.glide_robosuite.protocol.selected_features`, ``"full"``),
i.e. the trained GLiDE classifier, or :class:`KMeansModes` (the k-means
baseline), or :data:`GROUND_TRUTH`: the demos' recorded modes for the
segmentation and ``info["mode"]`` at test time (a development stand-in).

Choices, and why:

* The number of modes is the ground truth's (3, 3, 4). Plan steps map to modes
  by :data:`PLAN_STEPS`: one step per mode where the counts agree (Lift,
  Square); Can's plan has a separate "close the gripper" step (2) that the
  ground truth folds into *transport* (the grasp is the start of transport), so
  transport takes the goal of the merged steps' last one, step 3 "move to tray 2"
  (``robot0_eef_pos``): a merged mode ends where its last step ends.
* The BC MLP is :class:`~steer_envs.baselines.bc.modeling.BCPolicy` behind a
  small adapter (:class:`ArmBC`): BCPolicy bounds its output by the *norm*
  (a speed limit) or by a tanh whose targets must lie strictly inside the
  bound, neither of which fits a box action whose gripper targets are exactly
  +-1. The adapter standardises the inputs itself (std floored at
  ``std_floor``: the demos barely rotate the eef, and a 1e-6 floor would
  blow a small test-time rotation up into a huge input), trains the MLP
  linearly (``output_scale = sqrt(7)``, so the norm bound is never active
  on a box point), and clips each component to [-1, 1].
* The attractor acts beyond the 0.9 quantile of the mode's demo distances
  (and never within 2 cm of its target): only where the arm is farther from
  the mode's exit than nearly every demo state is, so in distribution the
  mode's BC acts alone; a lower quantile switches the pull on in every
  unperturbed reach, whose straight line to the grasp pose is not the demos'
  approach from above.
* Every mode's MLP standardises its inputs with the statistics of *all* demo
  states (the mode-agnostic BC's): a feature nearly constant within one mode
  (the finger opening while the can is held) would otherwise be divided by
  that mode's tiny spread, and a small test-time deviation would become a
  huge input.
* A mode with no demo pairs (Lift's final mode holds only the demos' last
  state: success ends the episode) uses the nearest mode's policy below it
  (above it if there is none).
* Evaluation: the registered env (its TimeLimit: Lift 200, Can 400, Square 500
  steps), stopped at success; reset seeds ``first_seed + i`` (default 10_000,
  disjoint from the demo seeds), the same for every method and trial seed, so
  methods are compared on the same placements. ``violation_rate``: episodes in
  which the env reported a constraint violation (pushes are exempt by the env;
  a drop caused by a forced gripper opening counts).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

import numpy as np

from steer_envs.baselines.bc.modeling import BCConfig, BCPolicy
from steer_envs.bench.suites.glide_robosuite.protocol import KMeansModes, num_modes, selected_columns
from steer_envs.core.validation import describe, integer, one_of, real_scalar
from steer_envs.data import robosuite_replays as rr
from steer_envs.envs.robosuite.tasks import TASK_NAMES

__all__ = [
    "GROUND_TRUTH",
    "METHODS",
    "PLAN_STEPS",
    "ArmBC",
    "ArmBCSettings",
    "ArmPolicy",
    "BCArmPolicy",
    "GlideArmPolicy",
    "GlideBCSettings",
    "KMeansModes",
    "ModeAttractor",
    "ModePredictor",
    "demo_modes",
    "evaluate",
    "mode_attractors",
    "num_modes",
    "policy_trial",
    "selected_columns",
    "train_policy",
]

#: the methods of :func:`policy_trial` (thesis Table 4.3's rows, the "(p)" rows being ``perturbed=True``).
METHODS: tuple[str, ...] = ("bc", "glide_bc")
#: the stand-in predictor: the demos' recorded modes for segmentation, ``info["mode"]`` at test time.
GROUND_TRUTH = "ground_truth"
#: task -> the plan step id whose goal feature each ground-truth mode uses (see the module's choices).
PLAN_STEPS: Mapping[str, tuple[int, ...]] = {"lift": (1, 2, 3), "can": (1, 3, 4), "square": (1, 2, 3, 4)}
_EEF = "robot0_eef_pos"
_RELATIVE = "_to_robot0_eef_pos"
_ACTION_DIM = 7


class ModePredictor(Protocol):
    """Anything that labels states (rows of selected features) with mode indices."""

    def predict(self, states: np.ndarray) -> np.ndarray:
        """The mode of each state ``(N, d) -> (N,)``."""
        ...


class ArmPolicy(Protocol):
    """A policy of this study: one action ``(7,)`` from the observation, the feature vector and the mode."""

    def act(self, obs: np.ndarray, features: np.ndarray, mode: int) -> np.ndarray:
        """The action for the current state (``mode`` is ignored by mode-agnostic policies)."""
        ...


def _task(task: Any) -> str:
    return one_of(task, "task", TASK_NAMES, owner="glide_robosuite.policies")


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
        return self.feature.endswith(_RELATIVE)

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


def _goal_features(task: str, plan: Any) -> list[str]:
    """The goal feature of each ground-truth mode (:data:`PLAN_STEPS` over the plan's ``goals``)."""
    goals = dict(getattr(plan, "goals", None) or {})
    out = []
    for k, step in enumerate(PLAN_STEPS[task]):
        name = goals.get(step)
        if not isinstance(name, str) or not (name == _EEF or name.endswith(_RELATIVE)):
            raise ValueError(
                f"mode {k} of {task!r} takes plan step {step}'s goal feature, which must be {_EEF!r} or "
                f"'<object>{_RELATIVE}'; the plan's goals are {goals}"
            )
        out.append(name)
    return out


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
        from steer_envs.bench.suites.glide_robosuite.protocol import recorded_plan

        plan = recorded_plan(task)
    k_modes = num_modes(task)
    names = _goal_features(task, plan)
    eef_cols = rr.feature_columns(task, [_EEF])
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
            threshold = max(float(np.quantile(attractor.distance(states[sel]), quantile)), min_threshold)
        out.append(ModeAttractor(name, cols, eef_cols, attractor.value, threshold))
    return out


# ------------------------------------------------------------------------- GLiDE+BC
class GlideArmPolicy:
    """GLiDE+BC on an arm: one :class:`ArmBC` per mode plus its pseudo-attractor (see the module).

    Args:
        task: the task name.
        demos: the successful demos (:class:`~steer_envs.data.robosuite_replays.ArmTrajectory`).
        modes: each demo's per-state mode labels (the predictor's, or the ground truth).
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
        self.attractor_weight = real_scalar(attractor_weight, "attractor_weight", low=0.0, high=1.0, owner=who)
        self.gain = real_scalar(gain, "gain", low=0.0, owner=who)
        seed = integer(seed, "seed", low=0, owner=who)
        self.num_modes = num_modes(self.task)
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
        trained: dict[int, ArmBC] = {}
        for k in range(self.num_modes):
            sel = state_modes == k
            if sel.any():
                trained[k] = ArmBC(obs[sel], acts[sel], seed=1000 * seed + k, settings=base, standardization=stats)
        if not trained:
            raise ValueError(f"{who}: no demo pairs to train on")
        #: mode -> the mode whose BC it uses (itself, or the nearest trained one below, else above)
        self.policy_of = [self._nearest(k, trained) for k in range(self.num_modes)]
        self.policies = trained

    @staticmethod
    def _nearest(k: int, trained: Mapping[int, ArmBC]) -> int:
        below = [j for j in trained if j <= k]
        return max(below) if below else min(trained)

    def act(self, obs: np.ndarray, features: np.ndarray, mode: int) -> np.ndarray:
        """Mode ``mode``'s BC action, its position part pulled toward the attractor when far from it."""
        k = integer(mode, "mode", low=0, high=self.num_modes - 1, owner="GlideArmPolicy.act")
        action = self.policies[self.policy_of[k]].act(np.asarray(obs, dtype=np.float64))
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
            w = self.attractor_weight
            out[:3] = (1.0 - w) * out[:3] + w * pull
        return out


# ------------------------------------------------------------------------ predictors
def _check_predictor(predictor: Any) -> None:
    if predictor != GROUND_TRUTH and not callable(getattr(predictor, "predict", None)):
        raise TypeError(
            f"`predictor` must have predict(states) -> modes or be {GROUND_TRUTH!r}, got {describe(predictor)}"
        )


def demo_modes(task: str, demos: Sequence[rr.ArmTrajectory], predictor: Any) -> list[np.ndarray]:
    """Each demo's per-state modes: the recorded ground truth (:data:`GROUND_TRUTH`) or the predictor's."""
    task = _task(task)
    _check_predictor(predictor)
    if predictor == GROUND_TRUTH:
        return [np.asarray(d.modes, dtype=np.int64) for d in demos]
    cols = selected_columns(task)
    k = num_modes(task)
    out = []
    for d in demos:
        m = np.asarray(predictor.predict(np.asarray(d.features[:, cols], dtype=np.float64)), dtype=np.int64)
        if m.shape != (len(d),) or (m.size and (m.min() < 0 or m.max() >= k)):
            raise ValueError(f"the predictor must give one mode in [0, {k}) per state, got shape {m.shape}")
        out.append(m)
    return out


# ------------------------------------------------------------------ train, evaluate
@dataclass(frozen=True)
class GlideBCSettings:
    """GLiDE+BC's attractor settings (see :class:`GlideArmPolicy`)."""

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


def train_policy(
    task: str,
    method: str,
    seed: int,
    *,
    demos: Sequence[rr.ArmTrajectory],
    predictor: Any = GROUND_TRUTH,
    bc: ArmBCSettings | None = None,
    glide: GlideBCSettings | None = None,
    plan: Any = None,
) -> ArmPolicy:
    """A trained :class:`ArmPolicy`: ``"bc"`` (all demo pairs) or ``"glide_bc"`` (per predicted mode)."""
    task = _task(task)
    method = one_of(method, "method", METHODS, owner="train_policy")
    seed = integer(seed, "seed", low=0, owner="train_policy")
    demos = _check_demos(task, demos)
    if method == "bc":
        obs = np.concatenate([d.obs[:-1] for d in demos])
        acts = np.concatenate([d.actions for d in demos])
        return BCArmPolicy(ArmBC(obs, acts, seed=seed, settings=bc))
    g = glide or GlideBCSettings()
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


@dataclass
class _Tally:
    success: list[bool] = field(default_factory=list)
    violation: list[bool] = field(default_factory=list)
    length: list[int] = field(default_factory=list)
    perturbations: list[int] = field(default_factory=list)
    mode_changes: list[int] = field(default_factory=list)
    log: list[list[tuple[int, str]]] = field(default_factory=list)


def evaluate(
    task: str,
    policy: ArmPolicy,
    *,
    predictor: Any = GROUND_TRUTH,
    n_episodes: int,
    perturbed: bool,
    first_seed: int = 10_000,
    perturbation: Mapping[str, Any] | None = None,
    max_episode_steps: int | None = None,
) -> dict[str, Any]:
    """Run ``policy`` for ``n_episodes`` episodes of the registered env (with the "+p" wrapper when ``perturbed``).

    The mode passed to the policy is the predictor's on the current state's
    selected features (``info["mode"]`` for :data:`GROUND_TRUTH`).
    ``perturbation``: keyword arguments of
    :class:`~steer_envs.wrappers.arm_perturbation.ArmPerturbationWrapper`.
    ``max_episode_steps``: None (the registry's limit) or a shorter one (smoke tests).
    Returns ``success_rate``, ``violation_rate``, ``mean_length``,
    ``mean_perturbations``, ``eval_seconds`` and the per-episode lists.
    """
    import gymnasium as gym

    import steer_envs  # noqa: F401 - registers the ids
    from steer_envs.wrappers.arm_perturbation import ArmPerturbationWrapper

    task = _task(task)
    owner = "evaluate"
    n_episodes = integer(n_episodes, "n_episodes", low=0, owner=owner)
    first_seed = integer(first_seed, "first_seed", low=0, owner=owner)
    if not isinstance(perturbed, bool):
        raise TypeError(f"{owner}: `perturbed` must be a bool, got {describe(perturbed)}")
    if not callable(getattr(policy, "act", None)):
        raise TypeError(f"{owner}: `policy` must have act(obs, features, mode), got {describe(policy)}")
    _check_predictor(predictor)
    kwargs: dict[str, Any] = {}
    if max_episode_steps is not None:
        kwargs["max_episode_steps"] = integer(max_episode_steps, "max_episode_steps", low=1, owner=owner)
    env: Any = gym.make(rr.ENV_IDS[task], **kwargs)
    if perturbed:
        env = ArmPerturbationWrapper(env, **dict(perturbation or {}))
    base = env.unwrapped
    cols = selected_columns(task)
    tally = _Tally()
    start = time.perf_counter()
    try:
        for i in range(n_episodes):
            obs, info = env.reset(seed=first_seed + i)
            success = violation = False
            steps = changes = 0
            last_mode = -1
            done = False
            while not done:
                features = rr.feature_vector(base)
                if predictor == GROUND_TRUTH:
                    mode = int(info["mode"])
                else:
                    mode = int(predictor.predict(np.asarray(features[cols], dtype=np.float64)[None])[0])
                changes += int(last_mode >= 0 and mode != last_mode)
                last_mode = mode
                action = np.asarray(policy.act(obs, features, mode), dtype=np.float32)
                obs, _, terminated, truncated, info = env.step(action)
                steps += 1
                violation |= bool(info["constraint_violation"])
                success |= bool(info["success"])
                done = success or terminated or truncated
            tally.success.append(success)
            tally.violation.append(violation)
            tally.length.append(steps)
            tally.perturbations.append(int(info.get("perturbation_count", 0)))
            tally.mode_changes.append(changes)
            tally.log.append([(int(t), str(kind)) for t, kind, _ in getattr(env, "log", [])])
    finally:
        env.close()
    n = max(n_episodes, 1)
    return {
        "task": task,
        "perturbed": perturbed,
        "n_episodes": n_episodes,
        "success_rate": sum(tally.success) / n,
        "violation_rate": sum(tally.violation) / n,
        "mean_length": float(np.mean(tally.length)) if tally.length else 0.0,
        "mean_perturbations": float(np.mean(tally.perturbations)) if tally.perturbations else 0.0,
        "eval_seconds": time.perf_counter() - start,
        "episodes": {
            "seed": [first_seed + i for i in range(n_episodes)],
            "success": tally.success,
            "violation": tally.violation,
            "length": tally.length,
            "perturbations": tally.perturbations,
            "mode_changes": tally.mode_changes,
            "perturbation_log": tally.log,
        },
    }


def policy_trial(
    task: str,
    method: str,
    seed: int,
    *,
    demos: Sequence[rr.ArmTrajectory],
    predictor: Any = GROUND_TRUTH,
    n_episodes: int,
    perturbed: bool | Literal["both"],
    first_seed: int = 10_000,
    bc: ArmBCSettings | None = None,
    glide: GlideBCSettings | None = None,
    perturbation: Mapping[str, Any] | None = None,
    max_episode_steps: int | None = None,
) -> dict[str, Any]:
    """Train ``method`` (seeded by ``seed``) on ``demos`` and evaluate it: one row of thesis Table 4.3.

    ``perturbed``: False (clean episodes), True (the "+p" wrapper) or ``"both"``
    (one training, both evaluations). Returns ``train_seconds`` and
    ``eval``: condition (``"clean"`` / ``"perturbed"``) -> the :func:`evaluate`
    dict; for a single condition its keys are also at the top level.
    """
    if perturbed not in (True, False, "both") or not isinstance(perturbed, (bool, str)):
        raise ValueError(f"policy_trial: `perturbed` must be True, False or 'both', got {describe(perturbed)}")
    start = time.perf_counter()
    policy = train_policy(task, method, seed, demos=demos, predictor=predictor, bc=bc, glide=glide)
    out: dict[str, Any] = {
        "task": task,
        "method": method,
        "seed": seed,
        "n_demos": len(demos),
        "predictor": predictor if predictor == GROUND_TRUTH else type(predictor).__name__,
        "train_seconds": time.perf_counter() - start,
    }
    conditions = (False, True) if perturbed == "both" else (bool(perturbed),)
    out["eval"] = {}
    for p in conditions:
        out["eval"]["perturbed" if p else "clean"] = evaluate(
            task,
            policy,
            predictor=predictor,
            n_episodes=n_episodes,
            perturbed=p,
            first_seed=first_seed,
            perturbation=perturbation,
            max_episode_steps=max_episode_steps,
        )
    if len(conditions) == 1:
        out.update(out["eval"]["perturbed" if conditions[0] else "clean"])
    return out
