"""What BlockStack and Kitchen skill data share: running one scripted skill step by step, replaying
recorded actions, and the ragged ``.npz`` layout of many skills in one file.

:mod:`~steer_envs.data.blockstack_skills` and :mod:`~steer_envs.data.kitchen_skills`
record one :class:`SkillRecord`-like object per skill of a scripted expert:
per-state arrays (observations, end-effector position, gripper command, mode,
and domain extras such as the Kitchen wrist yaw) with the skill's first state
included, and per-step 7-D delta-OSC actions. :func:`run_skill` steps one
skill to its end and returns those arrays (:class:`SteppedSkill`);
:func:`record_skill_run` starts a skill, runs it and builds its record.

Files keep many skills in one ragged archive: the states of skill ``i`` are
rows ``offsets[i]:offsets[i+1]`` of every per-state array, its actions rows
``offsets[i] - i : offsets[i+1] - i - 1`` of ``actions``; per-skill fields
have one entry per skill. A domain describes its file once
(:class:`SkillFileLayout`: its own arrays beyond :data:`COMMON_SPECS`, its
vocabularies); the layout writes the records, checks a file on load (raising
:class:`~steer_envs.io.DatasetError` naming the file and the field) and slices
skill ``i`` back out (:meth:`SkillFileLayout.fields`, with :func:`state_rows`
/ :func:`action_rows`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from steer_envs.io import DatasetError, atomic_write_npz, npz_json, read_npz, require_arrays

__all__ = [
    "ACTION_DIM",
    "COMMON_SPECS",
    "SkillFileLayout",
    "SteppedSkill",
    "action_rows",
    "check_records",
    "npz_output",
    "record_skill_run",
    "replay_actions",
    "run_skill",
    "state_rows",
]

#: the delta-OSC action size of both arms (xyz, rotation, gripper).
ACTION_DIM = 7

R = TypeVar("R")


@dataclass(frozen=True)
class SteppedSkill:
    """The arrays of one skill run to its end (:func:`run_skill`): states include the skill's first one.

    Attributes:
        obs: ``(T + 1, obs_dim)`` float32 observations.
        actions: ``(T, 7)`` float32 actions.
        eef: ``(T + 1, 3)`` float64 end-effector positions.
        gripper: ``(T + 1,)`` float32 gripper command in force at each state.
        modes: ``(T + 1,)`` int16 mode indices (``info["mode"]``).
        violation: some step reported ``constraint_violation``.
        extras: ``(T + 1,)`` float64 arrays of the extra per-state probes, by name.
    """

    obs: np.ndarray
    actions: np.ndarray
    eef: np.ndarray
    gripper: np.ndarray
    modes: np.ndarray
    violation: bool
    extras: dict[str, np.ndarray] = field(default_factory=dict)

    def record_fields(self) -> dict[str, Any]:
        """The fields a skill record copies from the run: the per-state arrays (extras too), actions, violation."""
        arrays = {"obs": self.obs, "actions": self.actions, "eef": self.eef, "gripper": self.gripper}
        return {**arrays, "modes": self.modes, **self.extras, "violation": self.violation}


def run_skill(
    base: Any,
    skills: Any,
    obs: Any,
    info: Mapping[str, Any],
    extras: Mapping[str, Callable[[], Any]] | None = None,
) -> tuple[SteppedSkill, Any, dict[str, Any]]:
    """Step ``skills`` (a started scripted skill runner) on ``base`` until it is done; the arrays, last obs and info.

    ``base``: the unwrapped env (``step``, ``state``, ``_gripper``); ``obs`` /
    ``info``: the current state's. ``extras``: more per-state probes (name ->
    function of no argument), read at every state.
    """
    probes = dict(extras or {})
    states = [np.asarray(obs, dtype=np.float32)]
    eef, grip, modes = [base.state], [base._gripper], [int(info["mode"])]
    more: dict[str, list[Any]] = {name: [probe()] for name, probe in probes.items()}
    actions: list[np.ndarray] = []
    violation = False
    while not skills.done:
        action = skills.act()  # stepped also when it ends the skill (as the experts do)
        obs, _, _, _, info = base.step(action)
        actions.append(np.asarray(action, dtype=np.float32))
        states.append(np.asarray(obs, dtype=np.float32))
        eef.append(base.state)
        for name, probe in probes.items():
            more[name].append(probe())
        grip.append(base._gripper)
        modes.append(int(info["mode"]))
        violation |= bool(info["constraint_violation"])
    stepped = SteppedSkill(
        obs=np.stack(states),
        actions=np.stack(actions) if actions else np.zeros((0, ACTION_DIM), np.float32),
        eef=np.stack(eef).astype(np.float64),
        gripper=np.asarray(grip, dtype=np.float32),
        modes=np.asarray(modes, dtype=np.int16),
        violation=violation,
        extras={name: np.asarray(values, dtype=np.float64) for name, values in more.items()},
    )
    return stepped, obs, dict(info)


def record_skill_run(
    base: Any,
    skills: Any,
    skill: Any,
    obs: Any,
    info: Mapping[str, Any],
    record: Callable[..., R],
    *,
    at_start: Callable[[], Mapping[str, Any]],
    extras: Mapping[str, Callable[[], Any]] | None = None,
) -> tuple[R, Any, dict[str, Any]]:
    """Start ``skill`` on ``skills``, run it to its end (:func:`run_skill`); its record, the last obs and info.

    ``at_start()``: the record's fields read once the skill has started (e.g.
    its target); ``record(**those, success=..., **the run's fields)`` builds
    the record after the run, so what it reads of ``base`` is the end state.
    """
    skills.start(skill)
    start = at_start()
    steps, obs, info = run_skill(base, skills, obs, info, extras)
    return record(**start, success=skills.succeeded(), **steps.record_fields()), obs, info


def replay_actions(base: Any, records: Sequence[Any], obs: Any, info: Any) -> tuple[Any, Any]:
    """Step every recorded action of ``records`` (in order) on ``base``; the last observation and info.

    With ``base`` just reset by the episode's seed, this reaches the start of
    the skill after ``records`` again (MuJoCo is deterministic).
    """
    for rec in records:
        for action in rec.actions:
            obs, _, _, _, info = base.step(action)
    return obs, info


def check_records(records: Any, kind: type, owner: str, check: Callable[[int, Any], None] | None = None) -> list[Any]:
    """``records`` as a non-empty list of ``kind`` with one more state than actions each (errors name ``owner``).

    ``check(i, record)``: the domain's own check of each record, before its lengths.
    """
    if isinstance(records, (str, bytes)) or not isinstance(records, Sequence):
        raise TypeError(f"{owner}: `records` must be a sequence of SkillRecord, got {type(records).__name__}")
    recs: list[Any] = list(records)
    if not recs:
        raise ValueError(f"{owner}: `records` must not be empty")
    for i, item in enumerate(recs):
        if not isinstance(item, kind):
            raise TypeError(f"{owner}: `records[{i}]` must be a SkillRecord, got {type(item).__name__}")
        r: Any = item
        if check is not None:
            check(i, r)
        if len(r.obs) != len(r.actions) + 1:
            raise ValueError(f"{owner}: `records[{i}]` has {len(r.obs)} states for {len(r.actions)} actions")
    return recs


#: the arrays of every skill file besides its domain's own (:attr:`SkillFileLayout.specs`): dtype kinds and axes
COMMON_SPECS: dict[str, tuple[str, int]] = {
    "obs": ("f", 2),
    "eef": ("f", 2),
    "gripper": ("f", 1),
    "actions": ("f", 2),
    "modes": ("iu", 1),
    "offsets": ("iu", 1),
    "skill": ("iu", 1),
    "success": ("b", 1),
    "violation": ("b", 1),
    "seed": ("iu", 1),
    "index": ("iu", 1),
}
#: the per-skill outcome fields every record has and every file ends with, and their dtypes in a file
_OUTCOMES: dict[str, type] = {"success": bool, "violation": bool, "seed": np.int64, "index": np.int32}


@dataclass(frozen=True)
class SkillFileLayout:
    """One domain's ragged skill file: its vocabulary and the arrays it holds beyond :data:`COMMON_SPECS`.

    Every file holds the per-state arrays of :attr:`states` and the actions
    (ragged, with ``offsets``), the skill ids, the domain's per-skill arrays
    and the outcomes (``success``, ``violation``, ``seed``, ``index``), and a
    JSON ``meta`` with the format version and the vocabularies.

    Attributes:
        domain: the env's name in error messages (``"BlockStack"``).
        version: the format version the meta records and loading requires.
        obs_dim: the width of ``obs``.
        states: the per-state arrays besides ``actions``, ``obs`` first (record attribute -> dtype).
        specs: the domain's own arrays (dtype kinds and axes, as :func:`~steer_envs.io.require_arrays` takes them).
        per_skill: the domain's arrays with one entry per skill.
        widths: the second axis of the domain's 2-D arrays.
        vocabularies: the lists the meta holds (key -> values).
        ids: the arrays of indices into a vocabulary (array -> vocabulary).
    """

    domain: str
    version: int
    obs_dim: int
    states: Mapping[str, type[np.generic]]
    specs: Mapping[str, tuple[str, int]]
    per_skill: tuple[str, ...]
    widths: Mapping[str, int]
    vocabularies: Mapping[str, Sequence[str]]
    ids: Mapping[str, Sequence[str]]

    def write(
        self, path: Path, records: Sequence[Any], arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any] | None
    ) -> Path:
        """Write ``records`` (checked by :func:`check_records`) with the domain's per-skill ``arrays`` atomically.

        ``meta`` is stored as JSON beside the format version and the
        vocabularies; ``TypeError`` (naming ``save_skills``) when it is not JSON-serializable.
        """
        info = {**dict(meta or {}), "format_version": self.version}
        info.update((key, list(values)) for key, values in self.vocabularies.items())
        try:
            text = json.dumps(info, sort_keys=True)
        except (TypeError, ValueError) as err:
            raise TypeError(f"save_skills: `meta` must be JSON-serializable ({err})") from None
        lengths = np.array([len(r.obs) for r in records])
        packed = {
            name: np.concatenate([getattr(r, name) for r in records]).astype(t) for name, t in self.states.items()
        }
        packed["actions"] = np.concatenate([r.actions for r in records]).astype(np.float32).reshape(-1, ACTION_DIM)
        packed["offsets"] = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
        packed.update(arrays)
        packed.update((name, np.array([getattr(r, name) for r in records], dtype=t)) for name, t in _OUTCOMES.items())
        return atomic_write_npz(path, {**packed, "meta": np.array(text)})

    def read(self, path: str | os.PathLike[str]) -> tuple[Path, dict[str, np.ndarray], dict[str, Any], np.ndarray]:
        """The source path, arrays, meta dict and offsets of a file written by :meth:`write`, all checked.

        ``DatasetError`` naming the file and the field for a missing or
        unreadable file, another format version or vocabulary, an array of the
        wrong dtype, axes or width, NaN/inf, inconsistent offsets or lengths, or ids out of range.
        """
        src = Path(path)
        arrays = read_npz(src)
        meta = npz_json(src, arrays, "meta")
        if meta.get("format_version") != self.version:
            raise DatasetError(
                f"{src}: field 'format_version' is {meta.get('format_version')!r}, expected {self.version}"
            )
        for key, values in self.vocabularies.items():
            if meta.get(key) != list(values):
                raise DatasetError(f"{src}: field {key!r} does not list this version's {self.domain} {key}")
        require_arrays(src, arrays, {**COMMON_SPECS, **self.specs}, finite=True)
        return src, arrays, meta, self._offsets(src, arrays)

    def _offsets(self, src: Path, arrays: Mapping[str, np.ndarray]) -> np.ndarray:
        """The offsets of a ragged archive, its shapes and ids checked (``DatasetError`` naming ``src``)."""
        n = len(arrays["skill"])
        off = arrays["offsets"].astype(np.int64)
        rows = len(arrays["obs"])
        for name, width in {"obs": self.obs_dim, "eef": 3, "actions": ACTION_DIM, **self.widths}.items():
            if arrays[name].shape[1] != width:
                raise DatasetError(f"{src}: array {name!r} has width {arrays[name].shape[1]}, expected {width}")
        if n == 0:
            raise DatasetError(f"{src}: array 'skill' is empty")
        if off.shape != (n + 1,) or off[0] != 0 or off[-1] != rows or np.any(np.diff(off) < 1):
            raise DatasetError(f"{src}: array 'offsets' does not split the {rows} states into {n} skills")
        for name in self.states:
            if len(arrays[name]) != rows:
                raise DatasetError(
                    f"{src}: array {name!r} has {len(arrays[name])} rows, expected {rows} (one per state)"
                )
        if len(arrays["actions"]) != rows - n:
            raise DatasetError(f"{src}: array 'actions' has {len(arrays['actions'])} rows, expected {rows - n}")
        for name in (*self.per_skill, *_OUTCOMES):
            if len(arrays[name]) != n:
                raise DatasetError(
                    f"{src}: array {name!r} has {len(arrays[name])} entries, expected {n} (one per skill)"
                )
        for name, vocab in self.ids.items():
            if np.any((arrays[name] < 0) | (arrays[name] >= len(vocab))):
                raise DatasetError(f"{src}: array {name!r} holds ids outside 0..{len(vocab) - 1}")
        return off

    def fields(self, arrays: Mapping[str, np.ndarray], offsets: np.ndarray, i: int) -> dict[str, Any]:
        """Skill ``i``'s per-state arrays, actions and outcomes, as keyword arguments of its record."""
        rows, steps = state_rows(offsets, i), action_rows(offsets, i)
        out: dict[str, Any] = {name: arrays[name][i].item() for name in _OUTCOMES}  # Python bools and ints
        out["actions"] = arrays["actions"][steps].astype(np.float32)
        out.update((name, arrays[name][rows].astype(dtype)) for name, dtype in self.states.items())
        return out


def npz_output(path: str | os.PathLike[str], owner: str) -> Path:
    """``path`` as a :class:`~pathlib.Path`; ``ValueError`` naming ``owner`` unless it ends in ``.npz``."""
    out = Path(path)
    if out.suffix != ".npz":
        raise ValueError(f"{owner}: `path` must end in .npz, got {str(out)!r}")
    return out


def state_rows(offsets: np.ndarray, i: int) -> slice:
    """The rows of skill ``i``'s states in a ragged archive."""
    return slice(int(offsets[i]), int(offsets[i + 1]))


def action_rows(offsets: np.ndarray, i: int) -> slice:
    """The rows of skill ``i``'s actions in a ragged archive (one fewer than its states)."""
    return slice(int(offsets[i]) - i, int(offsets[i + 1]) - i - 1)
