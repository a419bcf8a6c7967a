"""Demonstrations and GLiDE counterfactual replays on the robosuite arms (thesis §4.4).

A demonstration is a scripted expert's episode (:mod:`steer_envs.data.experts.robosuite`;
or, ``demos="human_like"``, that of the human-like demonstrator wrapped around it,
:mod:`steer_envs.data.experts.human_like`) recorded as :class:`ArmTrajectory`: the
thesis appendix's *available features* at every state (:data:`FEATURES`; the LLM
selects a subset of them), the env's observations and actions (what BC learns
from), the end-effector path and the ground-truth modes (evaluation only).

A counterfactual replay (:func:`replay`) resets the env to the demo's seed and
re-runs the demo's actions with a feedback term that tracks the demo's
end-effector path (``a_t = a_demo_t + gain * (ref_t - eef_t)`` on the position
part), so an unperturbed replay retraces the demo while a perturbed one
recovers toward it afterwards. Perturbations (:func:`sample_perturbation`,
the public GLiDE robosuite facts):

* ``"kernel"`` (2 of 3): a window of >= 20 steps of the reference path is
  pulled toward a target within +-0.1 m of the path (the Gaussian kernel of
  :func:`~steer_envs.data.perturbations.kernel_perturbation`); the last 14
  steps are never perturbed.
* ``"gripper"`` (1 of 3): the gripper is forced open for 5-20 steps.

The label is the thesis's success criterion from the env's own signals: the
task succeeded by the end and no step reported a constraint violation. A
successful replay also yields an early-terminated copy (:func:`early_terminated`,
kind ``"truncated"``): the same states cut before the task was done, a failure.

Recording goes on after success until it has held for :data:`SUCCESS_HOLD_STEPS`
more steps, as robosuite's human-demonstration collection does (its
``collect_human_demonstrations.py``; robomimic's data, which the thesis used,
come from it): the final mode is then seen in more than one state.

>>> FEATURES["can"][:2]
(('can_pos', 3), ('can_quat', 4))
>>> feature_columns("lift", ["gripper_state"]).tolist()
[21, 22]
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from steer_envs.core.validation import integer, one_of, real_scalar
from steer_envs.envs.robosuite.adapter import RobosuiteEnv
from steer_envs.envs.robosuite.tasks import TASK_NAMES
from steer_envs.io import DatasetError, atomic_write_npz, npz_json, read_npz, require_arrays

__all__ = [
    "DEMO_SOURCES",
    "ENV_IDS",
    "FEATURES",
    "PERTURBATIONS",
    "SUCCESS_HOLD_STEPS",
    "ArmPerturbation",
    "ArmTrajectory",
    "demonstrator",
    "early_terminated",
    "feature_columns",
    "feature_names",
    "feature_vector",
    "load_trajectories",
    "make_arm_env",
    "record_demo",
    "replay",
    "sample_perturbation",
    "save_trajectories",
]

#: registered env id of each task.
ENV_IDS: Mapping[str, str] = {
    "lift": "steer_envs/Lift-v0",
    "can": "steer_envs/Can-v0",
    "square": "steer_envs/Square-v0",
}
#: steps a recording continues once the task succeeds while success holds (robosuite's demo collection: 10).
SUCCESS_HOLD_STEPS = 10
#: who demonstrates (:func:`record_demo`'s ``demos``): the scripted expert, or the human-like demonstrator
#: (:mod:`steer_envs.data.experts.human_like`, a sensitivity study) wrapped around it.
DEMO_SOURCES: tuple[str, ...] = ("scripted", "human_like")
#: perturbation kinds of :func:`sample_perturbation` (``"demo"``: none; ``"truncated"``: an early-terminated copy).
PERTURBATIONS: tuple[str, ...] = ("demo", "kernel", "gripper", "truncated")

_POSE = (("pos", 3), ("quat", 4), ("to_robot0_eef_pos", 3), ("to_robot0_eef_quat", 4))
_ROBOT = (("robot0_eef_pos", 3), ("robot0_eef_quat", 4), ("gripper_state", 2))


def _object_features(*names: str) -> tuple[tuple[str, int], ...]:
    return tuple((f"{n}_{suffix}", size) for n in names for suffix, size in _POSE)


#: the thesis appendix's available features of each task (name, size), in state-vector order.
#: ``X_pos`` / ``X_quat``: the pose of X (quaternions xyzw with w >= 0); ``X_to_robot0_eef_*``:
#: X's pose relative to the end effector (position in the world frame, orientation in the eef's);
#: ``gripper_state``: the two finger joint positions.
FEATURES: Mapping[str, tuple[tuple[str, int], ...]] = {
    "lift": _object_features("block") + _ROBOT,
    "can": _object_features("can") + _ROBOT,
    "square": _object_features("nut", "handle", "peg") + _ROBOT,
}


def _task(task: str) -> str:
    return one_of(task, "task", TASK_NAMES, owner="robosuite_replays")


def feature_names(task: str) -> tuple[str, ...]:
    """The available feature names of ``task`` (the LLM prompt's ``available_features``)."""
    return tuple(name for name, _ in FEATURES[_task(task)])


def feature_columns(task: str, names: Sequence[str]) -> np.ndarray:
    """Column indices of the features ``names`` in ``task``'s state vector (an unknown name is a ValueError)."""
    layout, start = {}, 0
    for name, size in FEATURES[_task(task)]:
        layout[name] = np.arange(start, start + size)
        start += size
    if isinstance(names, str) or not isinstance(names, Sequence) or not names:
        raise ValueError(f"`names` must be a non-empty sequence of feature names, got {names!r}")
    unknown = [n for n in names if n not in layout]
    if unknown:
        raise ValueError(f"unknown features {unknown} for task {task!r}; available: {list(layout)}")
    return np.concatenate([layout[n] for n in names])


def _canonical(quat_xyzw: np.ndarray) -> np.ndarray:
    q = np.asarray(quat_xyzw, dtype=np.float64)
    return -q if q[3] < 0 else q


def _object_poses(env: RobosuiteEnv) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    obs, rs = env.robosuite_obs, env.rs_env
    prefix = env.spec_task.object_prefix
    main = {"lift": "block", "can": "can", "square": "nut"}[env.task_name]
    poses = {main: (np.asarray(obs[f"{prefix}_pos"], dtype=np.float64), np.asarray(obs[f"{prefix}_quat"]))}
    if env.task_name == "square":
        sim = rs.sim
        nut = rs.nuts[rs.nut_id]
        site = sim.model.site_name2id(nut.important_sites["handle"])
        poses["handle"] = (
            np.array(sim.data.site_xpos[site]),
            _canonical(Rotation.from_matrix(np.array(sim.data.site_xmat[site]).reshape(3, 3)).as_quat()),
        )
        peg = rs.peg1_body_id
        wxyz = np.array(sim.data.body_xquat[peg])
        poses["peg"] = (np.array(sim.data.body_xpos[peg]), np.array([*wxyz[1:], wxyz[0]]))
    return poses


def feature_vector(env: RobosuiteEnv) -> np.ndarray:
    """The available features (:data:`FEATURES`) of ``env``'s current state, one float32 vector."""
    if not isinstance(env, RobosuiteEnv):
        raise TypeError(f"feature_vector: `env` must be a RobosuiteEnv, got {type(env).__name__}")
    obs = env.robosuite_obs
    eef_pos = np.asarray(obs["robot0_eef_pos"], dtype=np.float64)
    eef_quat = _canonical(obs["robot0_eef_quat"])
    eef_inv = Rotation.from_quat(eef_quat).inv()
    parts: list[np.ndarray] = []
    for pos, quat in _object_poses(env).values():
        q = _canonical(quat)
        parts += [pos, q, pos - eef_pos, _canonical((eef_inv * Rotation.from_quat(q)).as_quat())]
    parts += [eef_pos, eef_quat, np.asarray(obs["robot0_gripper_qpos"], dtype=np.float64)]
    return np.concatenate(parts).astype(np.float32)


# ------------------------------------------------------------------------------ records
@dataclass(frozen=True)
class ArmPerturbation:
    """One perturbation of a replay: ``kind`` over the demo steps ``window = (s, e)`` (inclusive).

    ``target`` is the kernel's target position Z (m; NaN for the other kinds).
    """

    kind: str
    window: tuple[int, int] = (-1, -1)
    target: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))


@dataclass(frozen=True)
class ArmTrajectory:
    """A recorded episode (demo or replay) on a robosuite arm.

    Attributes:
        task: ``"lift"``, ``"can"`` or ``"square"``.
        seed: the reset seed (a replay uses its demo's).
        features: ``(T, D)`` available features (:data:`FEATURES`) of every state, the start included.
        obs: ``(T, 19)`` the env's observations.
        actions: ``(T - 1, 7)`` the actions taken.
        eef: ``(T, 3)`` end-effector positions.
        modes: ``(T,)`` ground-truth modes (evaluation only).
        success: the task succeeded and no step reported a constraint violation.
        violation_step: index of the first state after an invalid transition, -1 if none.
        perturbation: what was done to the demo (kind ``"demo"`` for a demo or a plain replay).
        source: index of the demo it replays (-1 for a demo).
        success_from: index of the first state of the success the recording ends in (-1: it ends without success).
    """

    task: str
    seed: int
    features: np.ndarray
    obs: np.ndarray
    actions: np.ndarray
    eef: np.ndarray
    modes: np.ndarray
    success: bool
    violation_step: int
    perturbation: ArmPerturbation
    source: int = -1
    success_from: int = -1

    def __len__(self) -> int:
        return len(self.features)


class _Recorder:
    """Records an episode; ``done`` once success has held for ``success_hold`` steps after the first success step."""

    def __init__(self, env: RobosuiteEnv, obs: np.ndarray, info: Mapping[str, Any], success_hold: int) -> None:
        self.env = env
        self.success_hold = success_hold
        self.features = [feature_vector(env)]
        self.obs = [np.asarray(obs, dtype=np.float32)]
        self.eef = [env.state]
        self.modes = [int(info["mode"])]
        self.actions: list[np.ndarray] = []
        self.violation = -1
        self.success = bool(info["success"])
        self.success_from = 0 if self.success else -1
        self.done = self.success and success_hold == 0

    def step(self, action: np.ndarray) -> None:
        obs, _, _, _, info = self.env.step(action)
        self.actions.append(np.asarray(action, dtype=np.float32))
        self.features.append(feature_vector(self.env))
        self.obs.append(np.asarray(obs, dtype=np.float32))
        self.eef.append(self.env.state)
        self.modes.append(int(info["mode"]))
        if info["constraint_violation"] and self.violation < 0:
            self.violation = len(self.modes) - 1
        self.success = bool(info["success"])
        last = len(self.modes) - 1
        if not self.success:
            self.success_from = -1
        elif self.success_from < 0:
            self.success_from = last
        self.done = self.success and last - self.success_from >= self.success_hold

    def result(self, seed: int, perturbation: ArmPerturbation, source: int) -> ArmTrajectory:
        success = self.success and self.violation < 0
        return ArmTrajectory(
            task=self.env.task_name,
            seed=seed,
            features=np.stack(self.features),
            obs=np.stack(self.obs),
            actions=np.stack(self.actions) if self.actions else np.zeros((0, 7), np.float32),
            eef=np.stack(self.eef),
            modes=np.asarray(self.modes, dtype=np.int16),
            success=success,
            violation_step=self.violation,
            perturbation=perturbation,
            source=source,
            success_from=self.success_from,
        )


def make_arm_env(task: str, variant: str = "thesis") -> RobosuiteEnv:
    """The unwrapped env of ``task`` in ``variant`` (no renderer; steps counted by the callers, not a TimeLimit)."""
    return RobosuiteEnv(_task(task), variant=variant)


def _max_steps(task: str) -> int:
    from steer_envs.envs.registry import entry

    steps = entry(ENV_IDS[task].split("/", 1)[1]).max_episode_steps
    return int(steps) if steps is not None else 500


def demonstrator(env: RobosuiteEnv, seed: int, demos: str = "scripted") -> Any:
    """Who demonstrates ``env``'s task: its scripted expert, or that expert in the human-like wrapper.

    ``demos``: one of :data:`DEMO_SOURCES`. ``seed`` seeds both (the public-code
    Lift's xy walk; :class:`~steer_envs.data.experts.human_like.HumanLikeDemonstrator`'s draws).
    """
    from steer_envs.data.experts.human_like import HumanLikeDemonstrator
    from steer_envs.data.experts.robosuite import CanExpert, LiftExpert, SquareExpert

    if not isinstance(env, RobosuiteEnv):
        raise TypeError(f"demonstrator: `env` must be a RobosuiteEnv, got {type(env).__name__}")
    demos = one_of(demos, "demos", DEMO_SOURCES, owner="demonstrator")
    expert: Any = (
        LiftExpert(env, seed=seed)
        if env.task_name == "lift"
        else {"can": CanExpert, "square": SquareExpert}[env.task_name](env)
    )
    return HumanLikeDemonstrator(expert, seed=seed) if demos == "human_like" else expert


def record_demo(
    env: RobosuiteEnv,
    seed: int,
    *,
    max_steps: int | None = None,
    success_hold: int = SUCCESS_HOLD_STEPS,
    demos: str = "scripted",
) -> ArmTrajectory:
    """One episode of ``env``'s demonstrator (:func:`demonstrator`, ``demos``) from reset seed ``seed``.

    It ends when success has held for ``success_hold`` steps (0: at the first
    success) or after ``max_steps`` steps (the env's step limit by default).
    """
    if not isinstance(env, RobosuiteEnv):
        raise TypeError(f"record_demo: `env` must be a RobosuiteEnv, got {type(env).__name__}")
    seed = integer(seed, "seed", low=0, owner="record_demo")
    limit = _max_steps(env.task_name) if max_steps is None else integer(max_steps, "max_steps", low=1)
    hold = integer(success_hold, "success_hold", low=0, owner="record_demo")
    expert = demonstrator(env, seed, demos)
    obs, info = env.reset(seed=seed)
    expert.reset(obs, info)
    rec = _Recorder(env, obs, info, hold)
    for _ in range(limit):
        rec.step(expert.act(rec.obs[-1], {}))
        if rec.done:
            break
    return rec.result(seed, ArmPerturbation("demo"), -1)


# ------------------------------------------------------------------------ perturbations
def sample_perturbation(
    demo: ArmTrajectory,
    rng: np.random.Generator,
    *,
    kernel_fraction: float = 2 / 3,
    min_window: int = 20,
    keep_last: int = 14,
    max_offset: float = 0.1,
    gripper_steps: tuple[int, int] = (5, 20),
) -> ArmPerturbation:
    """Draw one perturbation of ``demo`` (kernel with probability ``kernel_fraction``, else gripper).

    Kernel: a window ``[s, e]`` of at least ``min_window`` steps ending before the
    last ``keep_last`` steps, target = the path at the window's centre plus a
    uniform offset in ``[-max_offset, max_offset]^3``. Gripper: ``gripper_steps``
    (inclusive range) steps, forced open, also ending before the last ``keep_last``.
    """
    owner = "sample_perturbation"
    kernel_fraction = real_scalar(kernel_fraction, "kernel_fraction", low=0.0, high=1.0, owner=owner)
    n = len(demo.actions)
    last = n - integer(keep_last, "keep_last", low=0, owner=owner)  # steps [0, last) may be perturbed
    if rng.random() < kernel_fraction:
        width = integer(min_window, "min_window", low=2, owner=owner)
        if last < width:
            raise ValueError(
                f"{owner}: the demo has {n} steps, too short for a {width}-step window before the last {keep_last}"
            )
        length = int(rng.integers(width, last + 1))
        s = int(rng.integers(0, last - length + 1))
        e = s + length - 1
        centre = demo.eef[(s + e) // 2 + 1]
        offset = real_scalar(max_offset, "max_offset", low=0.0, owner=owner)
        return ArmPerturbation("kernel", (s, e), centre + rng.uniform(-offset, offset, 3))
    lo, hi = (integer(v, "gripper_steps", low=1, owner=owner) for v in gripper_steps)
    if last < lo or hi < lo:
        raise ValueError(f"{owner}: cannot fit a gripper window of {gripper_steps} steps in a {n}-step demo")
    length = int(rng.integers(lo, min(hi, last) + 1))
    s = int(rng.integers(0, last - length + 1))
    return ArmPerturbation("gripper", (s, s + length - 1))


def _reference(demo: ArmTrajectory, p: ArmPerturbation) -> np.ndarray:
    """The eef positions the replay tracks: the demo's path after each step, kernel-displaced in the window."""
    ref = demo.eef[1:].copy()
    if p.kind == "kernel":
        s, e = p.window
        c = 0.5 * (s + e)
        t = np.arange(s, e + 1)
        w = np.exp(-5.0 * (t - c) ** 2 / max((s - c) ** 2, 1e-9))
        ref[s : e + 1] += (p.target - ref[s : e + 1]) * w[:, None]
    return ref


def replay(
    env: RobosuiteEnv,
    demo: ArmTrajectory,
    perturbation: ArmPerturbation,
    *,
    source: int = 0,
    gain: float = 10.0,
    extra_steps: int = 40,
    success_hold: int = SUCCESS_HOLD_STEPS,
) -> ArmTrajectory:
    """Replay ``demo`` in ``env`` under ``perturbation`` with the tracking controller.

    The replay ends once success has held for ``success_hold`` steps (as
    :func:`record_demo`). After the demo's steps, up to ``extra_steps`` more
    hold the demo's last position and gripper command (a perturbed replay may
    finish later than its demo).
    """
    owner = "replay"
    if not isinstance(env, RobosuiteEnv) or env.task_name != demo.task:
        raise ValueError(f"{owner}: `env` must be the RobosuiteEnv of task {demo.task!r}")
    if perturbation.kind not in ("demo", "kernel", "gripper"):
        raise ValueError(f"{owner}: perturbation kind must be demo, kernel or gripper, got {perturbation.kind!r}")
    gain = real_scalar(gain, "gain", low=0.0, owner=owner)
    hold = integer(success_hold, "success_hold", low=0, owner=owner)
    ref = _reference(demo, perturbation)
    obs, info = env.reset(seed=demo.seed)
    rec = _Recorder(env, obs, info, hold)
    s, e = perturbation.window
    n = len(demo.actions)
    for t in range(n + integer(extra_steps, "extra_steps", low=0, owner=owner)):
        if t < n:
            action = demo.actions[t].astype(np.float64)
            target = ref[t - 1] if t > 0 else demo.eef[0]
        else:
            action = np.zeros(7)
            action[6] = demo.actions[-1][6]
            target = ref[-1]
        action[:3] = np.clip(action[:3] + gain * (target - env.state), -1.0, 1.0)
        if perturbation.kind == "gripper" and s <= t <= e:
            action[6] = -1.0
        rec.step(action)
        if rec.done or (t >= n and rec.violation >= 0):
            break
    return rec.result(demo.seed, perturbation, source)


def early_terminated(trajectory: ArmTrajectory, rng: np.random.Generator, *, min_cut: float = 0.3) -> ArmTrajectory:
    """A failure copy of a successful ``trajectory``: its first states, cut before the task was done.

    The copy keeps the states before index ``cut``, uniform in ``[min_cut * S, S]``
    where ``S`` is the first state of the final success (``success_from``; ``T - 1``
    when unknown): no state of the copy has succeeded. It keeps the perturbation's
    window and gets kind ``"truncated"``.
    """
    n = len(trajectory)
    first = trajectory.success_from if 0 < trajectory.success_from < n else n - 1
    lo = max(2, int(min_cut * first))
    cut = int(rng.integers(lo, first + 1)) if first > lo else max(1, first)
    p = replace(trajectory.perturbation, kind="truncated")
    return replace(
        trajectory,
        features=trajectory.features[:cut],
        obs=trajectory.obs[:cut],
        actions=trajectory.actions[: cut - 1],
        eef=trajectory.eef[:cut],
        modes=trajectory.modes[:cut],
        success=False,
        violation_step=-1,
        perturbation=p,
        success_from=-1,
    )


# ------------------------------------------------------------------------------ files
#: format version of :func:`save_trajectories` files (2: ``success_from``).
FORMAT_VERSION = 2
_FILE_SPECS: dict[str, tuple[str, int]] = {
    "features": ("f", 2),
    "obs": ("f", 2),
    "eef": ("f", 2),
    "modes": ("iu", 1),
    "offsets": ("iu", 1),
    "actions": ("f", 2),
    "seed": ("iu", 1),
    "success": ("b", 1),
    "violation_step": ("iu", 1),
    "kind": ("iu", 1),
    "window": ("iu", 2),
    "target": ("f", 2),
    "source": ("iu", 1),
    "success_from": ("iu", 1),
}


_PER_TRAJECTORY = ("seed", "violation_step", "kind", "window", "target", "source", "success_from")


def save_trajectories(
    path: str | os.PathLike[str], trajectories: Sequence[ArmTrajectory], meta: Mapping[str, Any] | None = None
) -> Path:
    """Write ``trajectories`` (one task) to ``path`` (``.npz``) atomically: ragged arrays plus offsets.

    States (features, obs, eef, modes) of trajectory ``i`` are rows
    ``offsets[i]:offsets[i+1]``; its actions are rows ``offsets[i] - i : offsets[i+1] - i - 1``.
    """
    path = Path(path)
    if path.suffix != ".npz":
        raise ValueError(f"save_trajectories: `path` must end in .npz, got {str(path)!r}")
    trajs = list(trajectories)
    if not trajs:
        raise ValueError("save_trajectories: `trajectories` must not be empty")
    tasks = {t.task for t in trajs}
    if len(tasks) != 1:
        raise ValueError(f"save_trajectories: all trajectories must be of one task, got {sorted(tasks)}")
    lengths = np.array([len(t) for t in trajs])
    arrays = {
        "features": np.concatenate([t.features for t in trajs]).astype(np.float32),
        "obs": np.concatenate([t.obs for t in trajs]).astype(np.float32),
        "eef": np.concatenate([t.eef for t in trajs]).astype(np.float64),
        "modes": np.concatenate([t.modes for t in trajs]).astype(np.int16),
        "offsets": np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
        "actions": np.concatenate([t.actions for t in trajs]).astype(np.float32).reshape(-1, 7),
        "seed": np.array([t.seed for t in trajs], dtype=np.int64),
        "success": np.array([t.success for t in trajs], dtype=bool),
        "violation_step": np.array([t.violation_step for t in trajs], dtype=np.int32),
        "kind": np.array([PERTURBATIONS.index(t.perturbation.kind) for t in trajs], dtype=np.int8),
        "window": np.array([t.perturbation.window for t in trajs], dtype=np.int32),
        "target": np.array([t.perturbation.target for t in trajs], dtype=np.float64),
        "source": np.array([t.source for t in trajs], dtype=np.int32),
        "success_from": np.array([t.success_from for t in trajs], dtype=np.int32),
    }
    info = {**dict(meta or {}), "task": trajs[0].task, "format_version": FORMAT_VERSION, "kinds": list(PERTURBATIONS)}
    return atomic_write_npz(path, {**arrays, "meta": np.array(json.dumps(info, sort_keys=True))})


def load_trajectories(path: str | os.PathLike[str]) -> tuple[list[ArmTrajectory], dict[str, Any]]:
    """Read a :func:`save_trajectories` file: the trajectories and the meta dict (``DatasetError`` naming the file)."""
    src = Path(path)
    arrays = read_npz(src)
    meta = npz_json(src, arrays, "meta")
    if meta.get("format_version") != FORMAT_VERSION:
        raise DatasetError(f"{src}: unsupported format_version {meta.get('format_version')!r}")
    task = meta.get("task")
    if task not in TASK_NAMES:
        raise DatasetError(f"{src}: unknown task {task!r}")
    require_arrays(src, arrays, _FILE_SPECS, finite=False)
    for name in ("features", "obs", "eef", "actions"):
        if not np.all(np.isfinite(arrays[name])):
            raise DatasetError(f"{src}: {name!r} holds NaN or infinite values")
    off = arrays["offsets"].astype(np.int64)
    n = len(arrays["success"])
    dim = sum(size for _, size in FEATURES[task])
    rows = len(arrays["features"])
    if (
        off.shape != (n + 1,)
        or off[0] != 0
        or off[-1] != rows
        or np.any(np.diff(off) < 1)
        or arrays["features"].shape[1] != dim
        or any(len(arrays[k]) != rows for k in ("obs", "eef", "modes"))
        or arrays["actions"].shape != (rows - n, 7)
        or any(len(arrays[k]) != n for k in _PER_TRAJECTORY)
        or arrays["window"].shape[1:] != (2,)
        or arrays["target"].shape[1:] != (3,)
        or np.any((arrays["kind"] < 0) | (arrays["kind"] >= len(PERTURBATIONS)))
    ):
        raise DatasetError(f"{src}: inconsistent arrays (offsets, lengths, widths or kinds)")
    out = []
    for i in range(n):
        a, b = int(off[i]), int(off[i + 1])
        perturbation = ArmPerturbation(
            PERTURBATIONS[int(arrays["kind"][i])],
            (int(arrays["window"][i, 0]), int(arrays["window"][i, 1])),
            np.array(arrays["target"][i], dtype=np.float64),
        )
        out.append(
            ArmTrajectory(
                task=task,
                seed=int(arrays["seed"][i]),
                features=arrays["features"][a:b],
                obs=arrays["obs"][a:b],
                actions=arrays["actions"][a - i : b - i - 1],
                eef=arrays["eef"][a:b],
                modes=arrays["modes"][a:b].astype(np.int16),
                success=bool(arrays["success"][i]),
                violation_step=int(arrays["violation_step"][i]),
                perturbation=perturbation,
                source=int(arrays["source"][i]),
                success_from=int(arrays["success_from"][i]),
            )
        )
    return out, meta
