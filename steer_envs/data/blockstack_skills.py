"""BlockStack skill data: the random planner's pick / place skills recorded one record per skill.

An episode (:func:`record_episode`) resets :class:`~steer_envs.envs.robosuite.blockstack.BlockStackEnv`
with the episode seed and runs ``n_skills`` skills of
:class:`~steer_envs.data.experts.blockstack.RandomTowerPlanner` (seeded with the
same seed) on :class:`~steer_envs.data.experts.blockstack.BlockStackSkills`, so
the same seed records the same skills. Each skill becomes a :class:`SkillRecord`:
its name in :data:`~steer_envs.envs.robosuite.blockstack.SKILLS`, the cube, the
target, the outcome, and per-step arrays (states include the skill's first one).

The episode steps the *unwrapped* env: under ``gymnasium.make`` a 4-high tower
terminates the episode (success) and the TimeLimit cuts it at 2000 steps, either
of which would end a data episode early without saying so. Here a tower is just
another world state: the planner goes on (it never places on a full tower), and
every episode has exactly ``n_skills`` skills.

Files (:func:`save_skills` / :func:`load_skills`) are ragged ``.npz`` archives
written atomically (:func:`steer_envs.io.atomic_write_npz`); loading checks
every array and raises :class:`~steer_envs.io.DatasetError` naming the file and
the field. :func:`to_trajectory_dataset` turns the skills into the generic
:class:`~steer_envs.data.trajectories.TrajectoryDataset` (one trajectory per skill).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.control.blockstack import Skill, free_table_spot, towers
from steer_envs.core.validation import boolean, integer
from steer_envs.data.experts.blockstack import BlockStackSkills, RandomTowerPlanner
from steer_envs.data.skill_records import (
    SkillFileLayout,
    check_records,
    npz_output,
    record_skill_run,
    replay_actions,
)
from steer_envs.data.trajectories import TrajectoryDataset
from steer_envs.envs.robosuite.blockstack import CUBE_HALF, NUM_CUBES, SKILLS, BlockStackEnv, unwrap_blockstack
from steer_envs.io import DatasetError

__all__ = [
    "FORMAT_VERSION",
    "OBS_DIM",
    "ONTO_NONE",
    "ONTO_TABLE",
    "SkillRecord",
    "alternative_skills",
    "load_skills",
    "make_env",
    "record_branches",
    "record_episode",
    "record_skill",
    "save_skills",
    "to_trajectory_dataset",
]

#: the env's observation size (eef 3, gripper qpos 2, four cube poses of 7).
OBS_DIM = 3 + 2 + 7 * NUM_CUBES
#: :attr:`SkillRecord.onto` of a place on the table.
ONTO_TABLE = -1
#: :attr:`SkillRecord.onto` of a pick (no support).
ONTO_NONE = -2
#: format version of :func:`save_skills` files.
FORMAT_VERSION = 1


@dataclass(frozen=True)
class SkillRecord:
    """One recorded skill.

    Attributes:
        name: the skill's name in :data:`SKILLS` (``pick_2``, ``place_2_on_table``, ``place_2_on_0``).
        cube: the cube picked or placed.
        onto: the cube placed on, :data:`ONTO_TABLE` or :data:`ONTO_NONE` (a pick).
        target: ``(3,)`` world point the skill aims at (m): a pick's cube centre at the
            skill's start; a place's goal centre of the cube (the table spot, or the top of ``onto``).
        success: the world shows the skill's outcome at its end (``BlockStackSkills.succeeded``).
        violation: some step of the skill reported ``constraint_violation`` (a drop, a tower falling).
        seed: the episode seed.
        index: the skill's position in its episode (0 first).
        obs: ``(T + 1, 33)`` float32 observations (the first state included).
        actions: ``(T, 7)`` float32 delta-OSC actions.
        eef: ``(T + 1, 3)`` float64 end-effector positions.
        gripper: ``(T + 1,)`` float32 gripper command in force at each state (-1 open, +1 closed).
        modes: ``(T + 1,)`` int16 mode indices (``free``, ``holding_0..3``).
    """

    name: str
    cube: int
    onto: int
    target: np.ndarray
    success: bool
    violation: bool
    seed: int
    index: int
    obs: np.ndarray
    actions: np.ndarray
    eef: np.ndarray
    gripper: np.ndarray
    modes: np.ndarray

    @property
    def kind(self) -> str:
        """``"pick"`` or ``"place"``."""
        return "pick" if self.onto == ONTO_NONE else "place"

    def __len__(self) -> int:
        """Control steps of the skill."""
        return len(self.actions)


def make_env() -> BlockStackEnv:
    """The unwrapped env the records come from (no renderer, no TimeLimit, no termination)."""
    return BlockStackEnv()


def _target(env: BlockStackEnv, skill: Skill) -> np.ndarray:
    """:attr:`SkillRecord.target` of ``skill`` started now (float64)."""
    if skill.kind == "pick":
        target = env.cube_pos[skill.cube]
    elif skill.onto is None:
        assert skill.xy is not None
        target = np.array([skill.xy[0], skill.xy[1], env.table_z + CUBE_HALF])
    else:
        target = env.cube_pos[skill.onto] + np.array([0.0, 0.0, 2 * CUBE_HALF])
    return np.asarray(target, dtype=np.float64)


def record_episode(env: Any, seed: int, n_skills: int) -> list[SkillRecord]:
    """``n_skills`` random-planner skills from reset seed ``seed`` (deterministic in ``seed``).

    ``env``: a :class:`BlockStackEnv` or a wrapper of one; the unwrapped env is
    stepped, so neither success termination nor a TimeLimit cuts the episode
    (see the module docstring). A skill that fails (a phase ran out of steps,
    or the outcome is not there) is recorded with ``success=False`` and the
    planner goes on from the world as it is.
    """
    owner = "record_episode"
    base = unwrap_blockstack(env, owner)
    seed = integer(seed, "seed", low=0, owner=owner)
    n_skills = integer(n_skills, "n_skills", low=1, high=10_000, owner=owner)
    obs, info = base.reset(seed=seed)
    planner = RandomTowerPlanner(seed)
    skills = BlockStackSkills(base)
    out: list[SkillRecord] = []
    for index in range(n_skills):
        record, obs, info = record_skill(base, skills, planner.next_skill(base), obs, info, seed, index)
        out.append(record)
    return out


def record_skill(
    base: BlockStackEnv, skills: BlockStackSkills, skill: Skill, obs: Any, info: dict[str, Any], seed: int, index: int
) -> tuple[SkillRecord, Any, dict[str, Any]]:
    """Run ``skill`` to its end from the current state; the record and the last observation and info."""
    onto = ONTO_NONE if skill.kind == "pick" else (ONTO_TABLE if skill.onto is None else skill.onto)
    record = partial(SkillRecord, name=skill.name, cube=skill.cube, onto=onto, seed=seed, index=index)
    target = partial(_target, base, skill)
    return record_skill_run(base, skills, skill, obs, info, record, at_start=lambda: {"target": target()})


def alternative_skills(env: Any, skill: Skill, rng: np.random.Generator) -> list[Skill]:
    """The other skills the random planner could have chosen instead of ``skill`` here, in random order.

    Free hand: a pick of every other tower top. Holding: a place on every other
    tower top (towers lower than 4 without the held cube) and, unless ``skill``
    is one, a place on the table at a free spot.
    """
    base = unwrap_blockstack(env, "alternative_skills")
    stacks = towers(base)
    held = base.held_cube
    if held is None:
        tops = [t[-1] for t in stacks] or list(range(NUM_CUBES))
        out = [Skill("pick", c) for c in tops if c != skill.cube]
    else:
        out = [Skill("place", held, t[-1]) for t in stacks if held not in t and len(t) < NUM_CUBES]
        out = [s for s in out if s.onto != skill.onto or skill.onto is None]
        if skill.onto is not None:
            xy = free_table_spot(base, rng, exclude=held)
            out.append(Skill("place", held, None, (float(xy[0]), float(xy[1]))))
    return [out[int(i)] for i in rng.permutation(len(out))]


def record_branches(env: Any, seed: int, n_skills: int, branches: int) -> list[SkillRecord]:
    """The episode of :func:`record_episode` plus up to ``branches`` other skills from each skill's start.

    Several skills from the *same* state are what a multimodal skill policy
    learns from (a random-planner episode holds one skill per state). The main
    episode is exactly :func:`record_episode`'s; the alternatives of each start
    (:func:`alternative_skills`, their own seeded generator) are chosen while it
    runs. Skill ``k``'s start is reached again by resetting with ``seed`` and
    replaying the main episode's actions (MuJoCo is deterministic: the state is
    the same, checked on the observation); each alternative then runs to its end
    and is recorded with ``index=k``. The main skills come first, then the branches.
    """
    owner = "record_branches"
    base = unwrap_blockstack(env, owner)
    seed = integer(seed, "seed", low=0, owner=owner)
    n_skills = integer(n_skills, "n_skills", low=1, high=10_000, owner=owner)
    branches = integer(branches, "branches", low=0, high=100, owner=owner)
    rng = np.random.default_rng([seed, 1])
    obs, info = base.reset(seed=seed)
    planner = RandomTowerPlanner(seed)
    skills = BlockStackSkills(base)
    main: list[SkillRecord] = []
    others: list[list[Skill]] = []
    for index in range(n_skills):
        skill = planner.next_skill(base)
        others.append(alternative_skills(base, skill, rng)[:branches])
        record, obs, info = record_skill(base, skills, skill, obs, info, seed, index)
        main.append(record)
    out = list(main)
    for k, alternatives in enumerate(others):
        for skill in alternatives:
            obs, info, replayed = _replay(base, seed, main[:k])
            if not np.array_equal(np.asarray(obs, dtype=np.float32), main[k].obs[0]):
                raise RuntimeError(f"{owner}: replaying seed {seed} did not reach skill {k}'s start state")
            out.append(record_skill(base, replayed, skill, obs, info, seed, k)[0])
    return out


def _replay(
    base: BlockStackEnv, seed: int, done: Sequence[SkillRecord]
) -> tuple[Any, dict[str, Any], BlockStackSkills]:
    """Reset with ``seed`` and step the recorded actions of ``done``; the skills runner made at reset."""
    obs, info = base.reset(seed=seed)
    skills = BlockStackSkills(base)  # made at reset, as in the main episode (its home yaw)
    obs, info = replay_actions(base, done, obs, info)
    return obs, info, skills


# ------------------------------------------------------------------------------ files
_LAYOUT = SkillFileLayout(
    domain="BlockStack",
    version=FORMAT_VERSION,
    obs_dim=OBS_DIM,
    states={"obs": np.float32, "eef": np.float64, "gripper": np.float32, "modes": np.int16},
    specs={"target": ("f", 2), "cube": ("iu", 1), "onto": ("i", 1)},
    per_skill=("target", "cube", "onto"),
    widths={"target": 3},
    vocabularies={"skills": SKILLS},
    ids={"skill": SKILLS},
)


def _name_parts(name: str) -> tuple[int, int]:
    """(cube, onto) of a skill name."""
    parts = name.split("_")
    if parts[0] == "pick":
        return int(parts[1]), ONTO_NONE
    return int(parts[1]), ONTO_TABLE if parts[3] == "table" else int(parts[3])


def save_skills(
    path: str | os.PathLike[str], records: Sequence[SkillRecord], meta: Mapping[str, Any] | None = None
) -> Path:
    """Write ``records`` to ``path`` (``.npz``) atomically (temp file, fsync, rename); returns the path.

    Ragged layout: states (obs, eef, gripper, modes) of skill ``i`` are rows
    ``offsets[i]:offsets[i+1]``, its actions rows ``offsets[i] - i : offsets[i+1] - i - 1``.
    ``meta`` (JSON-serializable) is stored beside the format version.
    """
    owner = "save_skills"
    out = npz_output(path, owner)

    def check(i: int, r: SkillRecord) -> None:
        if r.name not in SKILLS or _name_parts(r.name) != (r.cube, r.onto):
            raise ValueError(f"{owner}: `records[{i}]` has name {r.name!r}, cube {r.cube} and onto {r.onto}")

    recs = check_records(records, SkillRecord, owner, check)
    arrays: dict[str, np.ndarray] = {
        "target": np.array([r.target for r in recs], dtype=np.float64).reshape(-1, 3),
        "skill": np.array([SKILLS.index(r.name) for r in recs], dtype=np.int16),
        "cube": np.array([r.cube for r in recs], dtype=np.int8),
        "onto": np.array([r.onto for r in recs], dtype=np.int8),
    }
    return _LAYOUT.write(out, recs, arrays, meta)


def load_skills(path: str | os.PathLike[str]) -> tuple[list[SkillRecord], dict[str, Any]]:
    """Read a :func:`save_skills` file: the records and the meta dict.

    :class:`~steer_envs.io.DatasetError` naming the file and the field for a
    missing or unreadable file, another format version, an array of the wrong
    dtype, axes or width, NaN/inf, or inconsistent offsets, skill ids, cubes or targets.
    """
    src, a, meta, off = _LAYOUT.read(path)
    names = [SKILLS[int(k)] for k in a["skill"]]
    for i, name in enumerate(names):
        if _name_parts(name) != (int(a["cube"][i]), int(a["onto"][i])):
            raise DatasetError(f"{src}: arrays 'cube'/'onto' of skill {i} do not match its name {name!r}")
    out = [
        SkillRecord(
            name=name,
            cube=int(a["cube"][i]),
            onto=int(a["onto"][i]),
            target=np.array(a["target"][i], dtype=np.float64),
            **_LAYOUT.fields(a, off, i),
        )
        for i, name in enumerate(names)
    ]
    return out, meta


# ------------------------------------------------------------------------ conversion
def to_trajectory_dataset(
    records: Sequence[SkillRecord],
    *,
    successful_only: bool = True,
    gripper: bool = True,
    meta: Mapping[str, Any] | None = None,
) -> TrajectoryDataset:
    """One trajectory per skill, for a pick-or-place Diffusion Policy (one skill per plan).

    Observation at step t: the env's 33-D observation of state t (eef, gripper
    fingers, the four cube poses): the scene a skill is planned from, with no
    skill label, so the policy is multimodal over which cube / target (what
    the user steers). Action at step t: the end-effector trajectory, i.e. the
    next eef position ``eef[t + 1]`` (a position target, not the OSC delta,
    so that plans live in the world frame a 3D sketch is drawn in) and, with
    ``gripper``, the gripper command (4-D). Without the gripper the actions
    declare ``action_obs_indices=(0, 1, 2)`` (they set the eef entries of the
    observation; statistics pooled). ``successful_only`` drops skills that
    failed or reported a violation. ``meta`` is stored with the skill names.
    """
    owner = "to_trajectory_dataset"
    successful_only = boolean(successful_only, "successful_only", owner=owner)
    gripper = boolean(gripper, "gripper", owner=owner)
    if isinstance(records, (str, bytes)) or not isinstance(records, Sequence):
        raise TypeError(f"{owner}: `records` must be a sequence of SkillRecord, got {type(records).__name__}")
    for i, r in enumerate(records):
        if not isinstance(r, SkillRecord):
            raise TypeError(f"{owner}: `records[{i}]` must be a SkillRecord, got {type(r).__name__}")
    keep = [r for r in records if len(r) > 0 and (not successful_only or (r.success and not r.violation))]
    if not keep:
        raise ValueError(f"{owner}: `records` holds no non-empty skill to keep (of {len(records)})")
    obs = np.concatenate([r.obs[:-1] for r in keep]).astype(np.float32)
    parts = [r.eef[1:].astype(np.float32) for r in keep]
    if gripper:
        parts = [np.concatenate([p, r.gripper[1:, None]], axis=1) for p, r in zip(parts, keep, strict=True)]
    starts = np.concatenate([[0], np.cumsum([len(r) for r in keep])[:-1]]).astype(np.int64)
    info = {
        **dict(meta or {}),
        "source": "blockstack_skills",
        "action": "eef_pos+gripper" if gripper else "eef_pos",
        "skills": [r.name for r in keep],
        "episode_seeds": [r.seed for r in keep],
    }
    return TrajectoryDataset(
        obs,
        np.concatenate(parts),
        starts,
        action_obs_indices=None if gripper else (0, 1, 2),
        meta=info,
    )
