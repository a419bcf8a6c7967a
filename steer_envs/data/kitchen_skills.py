"""Kitchen skill data: the scripted expert's skills recorded one record per skill (ITPS §2.3).

An episode (:func:`record_episode`) resets
:class:`~steer_envs.envs.robosuite.kitchen.KitchenEnv` with the episode seed
and runs the skills of :class:`~steer_envs.data.experts.kitchen.KitchenPlanner`
(seeded with the same seed) on
:class:`~steer_envs.data.experts.kitchen.KitchenSkills`, i.e. exactly what
``KitchenExpert(env, seed=seed)`` does, until the env's task (``"microwave"``:
open the door, pick the bowl, place it in the microwave, close the door;
``"sink"``: pick, place in the sink) reaches its goal or ``max_skills`` skills
ran. The same seed records the same skills. Each skill becomes a
:class:`SkillRecord`: its name in :data:`~steer_envs.envs.robosuite.kitchen.SKILLS`,
the task, the outcome, and per-step arrays (states include the skill's first one):
observations, actions, eef position, wrist yaw
(:func:`~steer_envs.control.kitchen.eef_yaw`, the
expert's), gripper command and mode.

The episode steps the *unwrapped* env, so success termination (the last
skill's end) and the TimeLimit never cut a skill short. Skill ``k``'s start is
reached again by resetting with the seed and replaying the recorded actions
of the skills before it (:func:`replay_to_start`; MuJoCo is deterministic).

*Perturbed starts* (``record_episode(..., perturbed_starts=True)``):
before each skill the end effector is pushed (``env.perturb``, as the
itps-kitchen suite's OP correction pushes it) partway toward that skill's
target (:func:`push_toward_skill`), and the expert runs the skill from the
pushed pose; the record starts there. These are the states an OP push leaves
the arm in, which the plain data (every skill starts at rest at a skill
boundary) never shows. Such an episode is not replayable from its actions
(the push is not an action).

Files (:func:`save_skills` / :func:`load_skills`) are ragged ``.npz`` archives
written atomically (:func:`steer_envs.io.atomic_write_npz`); loading checks
every array and raises :class:`~steer_envs.io.DatasetError` naming the file and the field.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.control.kitchen import KitchenScene, eef_yaw
from steer_envs.core.validation import boolean, integer, real_scalar
from steer_envs.data.experts.kitchen import KitchenPlanner, KitchenSkills
from steer_envs.data.skill_records import (
    SkillFileLayout,
    check_records,
    npz_output,
    record_skill_run,
    replay_actions,
)
from steer_envs.envs.robosuite.kitchen import (
    KITCHEN_TASKS,
    SKILLS,
    KitchenEnv,
    kitchen_task,
    push_toward,
    skill_centre,
    unwrap_kitchen,
)

__all__ = [
    "DATA_TASKS",
    "FORMAT_VERSION",
    "MODES",
    "OBS_DIM",
    "PUSH_DISTANCE",
    "PUSH_JITTER",
    "SkillRecord",
    "load_skills",
    "make_env",
    "push_toward_skill",
    "record_episode",
    "replay_to_start",
    "save_skills",
]

#: the env's observation size (eef 3, eef quat 4, fingers 2, bowl pos 3, bowl quat 4, door angle 1).
OBS_DIM = 17
#: the observation columns of the bowl's centre and of the door angle.
BOWL_COLUMNS = slice(9, 12)
DOOR_COLUMN = 16
#: the tasks the ITPS kitchen data is recorded on (thesis §2.3: task 1 and task 2).
DATA_TASKS = ("microwave", "sink")
#: the mode names :attr:`SkillRecord.modes` indexes (the same for every task).
MODES: tuple[str, ...] = tuple(kitchen_task().modes)
#: format version of :func:`save_skills` files.
FORMAT_VERSION = 1
#: the longest push (m) of a perturbed start: the itps-kitchen suite's OP push (``op_distance``).
PUSH_DISTANCE = 0.15
#: a perturbed start aims at the skill's target centre moved by up to this much (m) along each axis (uniform).
PUSH_JITTER = 0.03
_PUSH_STREAM = 18  # the push's random stream: default_rng([seed, skill index, _PUSH_STREAM])


@dataclass(frozen=True)
class SkillRecord:
    """One recorded skill.

    Attributes:
        name: the skill's name in :data:`~steer_envs.envs.robosuite.kitchen.SKILLS`.
        task: the episode's task (one of :data:`~steer_envs.envs.robosuite.kitchen.KITCHEN_TASKS`).
        success: the world shows the skill's outcome at its end (``KitchenSkills.succeeded``).
        violation: some step of the skill reported ``constraint_violation``.
        seed: the episode seed.
        index: the skill's position in its episode (0 first).
        obs: ``(T + 1, 17)`` float32 observations (the first state included).
        actions: ``(T, 7)`` float32 delta-OSC actions.
        eef: ``(T + 1, 3)`` float64 end-effector positions.
        yaw: ``(T + 1,)`` float64 wrist yaw (rad, in (-pi, pi], as the expert measures it).
        gripper: ``(T + 1,)`` float32 gripper command in force at each state (-1 open, +1 closed).
        modes: ``(T + 1,)`` int16 mode indices into :data:`MODES`.
        handle: ``(3,)`` the door handle bar's centre at the skill's start.
        hinge: ``(3,)`` a point on the door's hinge axis.
    """

    name: str
    task: str
    success: bool
    violation: bool
    seed: int
    index: int
    obs: np.ndarray
    actions: np.ndarray
    eef: np.ndarray
    yaw: np.ndarray
    gripper: np.ndarray
    modes: np.ndarray
    handle: np.ndarray
    hinge: np.ndarray

    @property
    def mode_before(self) -> str:
        """The mode at the skill's start."""
        return MODES[int(self.modes[0])]

    @property
    def mode_after(self) -> str:
        """The mode at the skill's end."""
        return MODES[int(self.modes[-1])]

    @property
    def scene(self) -> KitchenScene:
        """The state at the skill's start, as ``classify_kitchen_plan`` reads it (offline, without an env)."""
        first = self.obs[0].astype(np.float64)
        return KitchenScene(
            eef=np.array(self.eef[0], dtype=np.float64),
            bowl=first[BOWL_COLUMNS].copy(),
            held="held" in self.mode_before,
            door_angle=float(first[DOOR_COLUMN]),
            handle=np.array(self.handle, dtype=np.float64),
            hinge=np.array(self.hinge, dtype=np.float64),
        )

    def __len__(self) -> int:
        """Control steps of the skill."""
        return len(self.actions)


def make_env(task: str) -> KitchenEnv:
    """The unwrapped env the records of ``task`` come from (no renderer, no TimeLimit, no termination)."""
    return KitchenEnv(task=task)


def push_toward_skill(
    env: Any, skill: str, rng: np.random.Generator, *, distance: float = PUSH_DISTANCE
) -> tuple[np.ndarray, dict[str, Any]]:
    """Push the end effector partway toward ``skill``'s target: the observation and info after the push.

    The aim is the target's centre as the clicking user means it
    (:func:`~steer_envs.envs.robosuite.kitchen.skill_centre`) moved by a uniform
    draw of up to :data:`PUSH_JITTER` per axis; the push is ``distance`` times a
    uniform draw in [0.5, 1] m long (less when the aim is nearer), made with
    ``env.perturb`` as the itps-kitchen suite's OP correction makes it.
    """
    owner = "push_toward_skill"
    base = unwrap_kitchen(env, owner)
    aim = skill_centre(base, skill)  # checks `skill`
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"{owner}: `rng` must be a numpy Generator, got {type(rng).__name__}")
    distance = real_scalar(distance, "distance", low=0.0, high=1.0, owner=owner)
    aim = aim + rng.uniform(-PUSH_JITTER, PUSH_JITTER, size=3)
    length = distance * float(rng.uniform(0.5, 1.0))
    info = push_toward(base, aim, length)
    if info is None:  # already at the aim: a zero push still reports the info
        info = base.perturb(np.zeros(3))
    return base._obs(), info


def record_episode(env: Any, seed: int, *, max_skills: int = 8, perturbed_starts: bool = False) -> list[SkillRecord]:
    """The expert's skills from reset seed ``seed`` on ``env``'s task until its goal (deterministic in ``seed``).

    ``env``: a :class:`KitchenEnv` or a wrapper of one; the unwrapped env is
    stepped (see the module docstring). At most ``max_skills`` skills: a skill
    that fails is recorded with ``success=False`` and the planner goes on from
    the world as it is (it tries again, or stops where no legal sequence leads to the goal).
    ``perturbed_starts``: push the end effector toward each skill's target
    before the skill (:func:`push_toward_skill`, seeded by ``seed`` and the
    skill's index); each record then starts at the pushed pose.
    """
    owner = "record_episode"
    base = unwrap_kitchen(env, owner)
    seed = integer(seed, "seed", low=0, owner=owner)
    max_skills = integer(max_skills, "max_skills", low=1, high=1000, owner=owner)
    perturbed_starts = boolean(perturbed_starts, "perturbed_starts", owner=owner)
    obs, info = base.reset(seed=seed)
    planner = KitchenPlanner(seed)
    skills = KitchenSkills(base)
    out: list[SkillRecord] = []
    for index in range(max_skills):
        skill = planner.next_skill(base)
        if skill is None:
            break
        if perturbed_starts:
            obs, info = push_toward_skill(base, skill, np.random.default_rng([seed, index, _PUSH_STREAM]))
        record, obs, info = _run_skill(base, skills, skill, obs, info, seed, index)
        out.append(record)
    return out


def _run_skill(
    base: KitchenEnv, skills: KitchenSkills, skill: str, obs: Any, info: dict[str, Any], seed: int, index: int
) -> tuple[SkillRecord, Any, dict[str, Any]]:
    """Run ``skill`` to its end from the current state; the record and the last observation and info."""

    def record(**fields: Any) -> SkillRecord:
        return SkillRecord(name=skill, task=base.kitchen_task, seed=seed, index=index, hinge=base.hinge_pos, **fields)

    def at_start() -> dict[str, Any]:
        return {"handle": np.asarray(base.handle_pos, dtype=np.float64)}

    return record_skill_run(
        base, skills, skill, obs, info, record, at_start=at_start, extras={"yaw": lambda: eef_yaw(base)}
    )


def replay_to_start(env: Any, records: Sequence[SkillRecord], index: int) -> tuple[np.ndarray, dict[str, Any]]:
    """Reset ``env`` with the episode's seed and step the recorded actions of the skills before ``index``.

    ``records``: one episode's records in order (:func:`record_episode`), ``env``
    of the same task. Returns the observation and info at skill ``index``'s start;
    ``RuntimeError`` if the state reached is not the recorded one (checked on the observation).
    """
    owner = "replay_to_start"
    base = unwrap_kitchen(env, owner)
    if isinstance(records, (str, bytes)) or not isinstance(records, Sequence):
        raise TypeError(f"{owner}: `records` must be a sequence of SkillRecord, got {type(records).__name__}")
    index = integer(index, "index", low=0, high=len(records) - 1, owner=owner)
    for i, r in enumerate(records[: index + 1]):
        if not isinstance(r, SkillRecord):
            raise TypeError(f"{owner}: `records[{i}]` must be a SkillRecord, got {type(r).__name__}")
        if r.index != i or r.seed != records[0].seed or r.task != records[0].task:
            raise ValueError(f"{owner}: `records` must be one episode's skills in order; records[{i}] is not")
    if base.kitchen_task != records[0].task:
        raise ValueError(f"{owner}: `env` has task {base.kitchen_task!r}, the records {records[0].task!r}")
    obs, info = base.reset(seed=records[0].seed)
    obs, info = replay_actions(base, records[:index], obs, info)
    if not np.array_equal(np.asarray(obs, dtype=np.float32), records[index].obs[0]):
        raise RuntimeError(f"{owner}: replaying seed {records[0].seed} did not reach skill {index}'s start state")
    return obs, info


# ------------------------------------------------------------------------------ files
_LAYOUT = SkillFileLayout(
    domain="Kitchen",
    version=FORMAT_VERSION,
    obs_dim=OBS_DIM,
    states={"obs": np.float32, "eef": np.float64, "yaw": np.float64, "gripper": np.float32, "modes": np.int16},
    specs={"yaw": ("f", 1), "handle": ("f", 2), "hinge": ("f", 2), "task": ("iu", 1)},
    per_skill=("handle", "hinge", "task"),
    widths={"handle": 3, "hinge": 3},
    vocabularies={"skills": SKILLS, "tasks": KITCHEN_TASKS, "modes": MODES},
    ids={"skill": SKILLS, "task": KITCHEN_TASKS, "modes": MODES},
)


def save_skills(
    path: str | os.PathLike[str], records: Sequence[SkillRecord], meta: Mapping[str, Any] | None = None
) -> Path:
    """Write ``records`` to ``path`` (``.npz``) atomically (temp file, fsync, rename); returns the path.

    Ragged layout: states (obs, eef, yaw, gripper, modes) of skill ``i`` are rows
    ``offsets[i]:offsets[i+1]``, its actions rows ``offsets[i] - i : offsets[i+1] - i - 1``.
    ``meta`` (JSON-serializable) is stored beside the format version.
    """
    owner = "save_skills"
    out = npz_output(path, owner)

    def check(i: int, r: SkillRecord) -> None:
        if r.name not in SKILLS or r.task not in KITCHEN_TASKS:
            raise ValueError(f"{owner}: `records[{i}]` has skill {r.name!r} and task {r.task!r}")

    recs = check_records(records, SkillRecord, owner, check)
    arrays: dict[str, np.ndarray] = {
        "handle": np.array([r.handle for r in recs], dtype=np.float64).reshape(-1, 3),
        "hinge": np.array([r.hinge for r in recs], dtype=np.float64).reshape(-1, 3),
        "skill": np.array([SKILLS.index(r.name) for r in recs], dtype=np.int16),
        "task": np.array([KITCHEN_TASKS.index(r.task) for r in recs], dtype=np.int16),
    }
    return _LAYOUT.write(out, recs, arrays, meta)


def load_skills(path: str | os.PathLike[str]) -> tuple[list[SkillRecord], dict[str, Any]]:
    """Read a :func:`save_skills` file: the records and the meta dict.

    :class:`~steer_envs.io.DatasetError` naming the file and the field for a
    missing or unreadable file, another format version or vocabulary, an array
    of the wrong dtype, axes or width, NaN/inf, or inconsistent offsets, skill, task or mode ids.
    """
    _, a, meta, off = _LAYOUT.read(path)
    out = [
        SkillRecord(
            name=SKILLS[int(a["skill"][i])],
            task=KITCHEN_TASKS[int(a["task"][i])],
            **_LAYOUT.fields(a, off, i),
            handle=np.array(a["handle"][i], dtype=np.float64),
            hinge=np.array(a["hinge"][i], dtype=np.float64),
        )
        for i in range(len(off) - 1)
    ]
    return out, meta
