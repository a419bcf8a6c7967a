"""Record a steer-ui session and replay it to the same frames: what was opened, then every interaction, in order.

A :class:`~steer_envs.ui.session.Session` or
:class:`~steer_envs.ui.push_session.PushSession` logs each call that changes
it (``reset``, ``configure``, ``steer``, ``step``, ``nudge``, ``push``) in
world coordinates, and the SHA-256 of each frame rendered after one. A
:class:`Recording` is that log plus how the session was opened (domain, env,
policy, settings, seed); :func:`save_recording` writes it as JSON (atomically,
with a ``format`` number), :func:`load_recording` reads it back and checks it,
and :func:`~steer_envs.ui.replay.replay` opens a fresh session, runs the log
again and reports the first event whose frame differs from the recorded one.

Replays are bit-for-bit on the machine and inference backend that recorded
them: the env, the sampler's noise (seeded at every reset) and a network run on
one thread are deterministic. Another machine or backend (OpenVINO's bfloat16
on a CPU with AMX, ONNX Runtime without) may round the network's output
differently, so plans then agree only within float tolerance and a long
rollout may drift; the frame check says where.

>>> Recording("soup-scoop", 1, {"kind": "push"}, ({"op": "step"},)).as_dict()["format"]
1
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.core.validation import describe

__all__ = [
    "MAX_EVENTS",
    "OPS",
    "RECORDING_FORMAT",
    "Recording",
    "RecordingError",
    "SessionLog",
    "frame_digest",
    "interaction_json",
    "json_options",
    "load_recording",
    "recording_json",
    "recording_of",
    "save_recording",
]

#: the version of the recording's JSON layout (a reader refuses others)
RECORDING_FORMAT = 1
#: the most calls a session logs (an hour of play at a few ticks a second); beyond it the log stops
MAX_EVENTS = 20_000
#: the logged calls and the fields each carries (besides ``op`` and an optional ``frame`` digest)
OPS: dict[str, frozenset[str]] = {
    "reset": frozenset({"seed"}),
    "configure": frozenset({"knobs"}),
    "steer": frozenset({"interaction"}),
    "step": frozenset(),
    "nudge": frozenset({"to"}),
    "push": frozenset({"to"}),
}


class RecordingError(ValueError):
    """A recording file that cannot be read or replayed (the message names the file and the field)."""


def frame_digest(image: np.ndarray) -> str:
    """SHA-256 of a frame's shape and bytes (what a replay compares)."""
    arr = np.ascontiguousarray(image)
    return hashlib.sha256(f"{arr.shape}{arr.dtype}".encode() + arr.tobytes()).hexdigest()


def _json_value(value: Any, where: str) -> Any:
    """``value`` as plain JSON (numpy numbers and arrays become lists), or ``RecordingError`` naming ``where``."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, bool | int | float | str):
        return value
    if isinstance(value, Mapping):
        return {str(k): _json_value(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_value(v, where) for v in value]
    raise RecordingError(f"{where} is {describe(value)}, which a recording (JSON) cannot hold")


class SessionLog:
    """What a session logs: its calls in order, each with the digest of the first frame rendered after it."""

    def __init__(self) -> None:
        self.events: list[dict[str, Any]] = []
        self.start_frame: str | None = None
        #: more than :data:`MAX_EVENTS` calls were made: the log is incomplete and cannot be replayed
        self.overflowed = False

    def add(self, op: str, **fields: Any) -> None:
        """Log call ``op`` (one of :data:`OPS`) with its ``fields`` (made plain JSON)."""
        if len(self.events) >= MAX_EVENTS:
            self.overflowed = True
            return
        self.events.append({"op": op, **{k: _json_value(v, f"`{k}`") for k, v in fields.items()}})

    def frame(self, image: np.ndarray) -> None:
        """A frame was rendered: the digest of the first one after each call (or after the opening) is kept."""
        if not self.events:
            if self.start_frame is None:
                self.start_frame = frame_digest(image)
        elif "frame" not in self.events[-1]:
            self.events[-1]["frame"] = frame_digest(image)

    def clear(self) -> None:
        """Forget the calls (the session was reset to a new start)."""
        self.events = []


@dataclass(frozen=True)
class Recording:
    """A session's opening and its logged calls.

    Attributes:
        domain: the :data:`~steer_envs.ui.domains.DOMAINS` name.
        seed: the seed the session was opened with.
        session: how it was opened: ``kind`` (``"steer"`` or ``"push"``) and the constructor's arguments
            (``env``, ``env_kwargs``, ``policy``, ``checkpoint``, ``accelerate``, ``settings``;
            ``controller_options``), plain JSON.
        events: the calls, in order (:data:`OPS`), each maybe with the ``frame`` digest seen after it.
        start_frame: the digest of the first frame after opening (``None``: none rendered).
    """

    domain: str
    seed: int
    session: Mapping[str, Any]
    events: tuple[Mapping[str, Any], ...]
    start_frame: str | None = None
    format: int = RECORDING_FORMAT
    meta: Mapping[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "format": self.format,
            "domain": self.domain,
            "seed": self.seed,
            "session": dict(self.session),
            "start_frame": self.start_frame,
            "events": [dict(e) for e in self.events],
            "meta": dict(self.meta),
        }

    @classmethod
    def from_dict(cls, data: Any, source: str = "the recording") -> Recording:
        """Check ``data`` (a parsed recording) and build it; ``RecordingError`` naming ``source`` and the field."""
        from steer_envs.ui.domains import DOMAINS

        def bad(what: str) -> RecordingError:
            return RecordingError(f"{source}: {what}")

        if not isinstance(data, dict):
            raise bad(f"a recording is a JSON object, got {type(data).__name__}")
        fmt = data.get("format")
        if fmt != RECORDING_FORMAT:
            raise bad(f"'format' is {fmt!r}; this steer-envs reads format {RECORDING_FORMAT} recordings")
        missing = sorted({"domain", "seed", "session", "events"} - set(data))
        if missing:
            raise bad(f"missing {missing}")
        domain, seed, session, events = data["domain"], data["seed"], data["session"], data["events"]
        if domain not in DOMAINS:
            raise bad(f"'domain' is {domain!r}; known: {sorted(DOMAINS)}")
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**31:
            raise bad(f"'seed' must be an int in [0, 2**31), got {seed!r}")
        if not isinstance(session, dict) or session.get("kind") not in ("steer", "push"):
            raise bad("'session' must be an object with 'kind' 'steer' or 'push'")
        if session["kind"] != DOMAINS[domain].session:
            raise bad(
                f"'session.kind' is {session['kind']!r}, but the {domain!r} domain is a {DOMAINS[domain].session!r} one"
            )
        if not isinstance(events, list):
            raise bad(f"'events' must be a list, got {type(events).__name__}")
        for i, event in enumerate(events):
            if not isinstance(event, dict) or event.get("op") not in OPS:
                raise bad(f"events[{i}] must be an object whose 'op' is one of {sorted(OPS)}, got {str(event)[:80]}")
            extra = sorted(set(event) - OPS[event["op"]] - {"op", "frame"})
            lacking = sorted(OPS[event["op"]] - set(event))
            if extra or lacking:
                raise bad(f"events[{i}] ({event['op']!r}) has unknown {extra} / lacks {lacking}")
        start = data.get("start_frame")
        if start is not None and not isinstance(start, str):
            raise bad("'start_frame' must be a digest string or null")
        meta = data.get("meta", {})
        return cls(
            domain, seed, dict(session), tuple(events), start, RECORDING_FORMAT, meta if isinstance(meta, dict) else {}
        )


def save_recording(recording: Recording, path: str | os.PathLike[str]) -> Path:
    """Write ``recording`` as JSON to ``path`` atomically; returns the path."""
    from steer_envs.io import atomic_write_text

    if not isinstance(recording, Recording):
        raise TypeError(f"save_recording: `recording` must be a Recording, got {describe(recording)}")
    target = Path(path)
    atomic_write_text(target, recording_json(recording))
    return target


def recording_json(recording: Recording) -> str:
    """``recording`` as the text :func:`save_recording` writes: the header indented, one event a line."""
    data = recording.as_dict()
    events = data.pop("events")
    head = json.dumps(data, indent=1, allow_nan=False)[:-2]  # without the closing newline and brace
    lines = ",\n  ".join(json.dumps(e, allow_nan=False) for e in events)
    return f'{head},\n "events": [\n  {lines}\n ]\n}}\n' if events else f'{head},\n "events": []\n}}\n'


def load_recording(path: str | os.PathLike[str]) -> Recording:
    """Read and check a recording written by :func:`save_recording`; ``RecordingError`` naming the file otherwise."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{source}: cannot read the recording ({exc})") from None
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise RecordingError(f"{source}: not a JSON recording ({exc})") from None
    return Recording.from_dict(data, source)


def interaction_json(interaction: Any) -> dict[str, Any] | None:
    """A :class:`~steer_envs.core.interaction.Point` / ``Sketch`` (or ``None``) as a steer event's ``interaction``."""
    if interaction is None:
        return None
    target = getattr(interaction, "target", None)
    if target is not None:
        return {"kind": "point", "target": np.asarray(target, dtype=np.float64).tolist()}
    return {"kind": "sketch", "points": np.asarray(interaction.points, dtype=np.float64).tolist()}


def recording_of(
    session: Any, opened: Mapping[str, Any], log: SessionLog, meta: Mapping[str, Any] | None = None
) -> Recording:
    """The :class:`Recording` of a session opened with ``opened`` (its kind and arguments) that logged ``log``.

    ``RecordingError`` when the log overflowed (more than :data:`MAX_EVENTS` calls).
    """
    import steer_envs

    if log.overflowed:
        raise RecordingError(f"the session made more than {MAX_EVENTS} calls: too long to record (reset and re-open)")
    meta = {"steer_envs": str(getattr(steer_envs, "__version__", "")), **(meta or {})}
    return Recording(
        session.name,
        int(opened["seed"]),
        {k: v for k, v in opened.items() if k != "seed"},
        tuple(dict(e) for e in log.events),
        log.start_frame,
        meta=meta,
    )


def json_options(options: Mapping[str, Any] | None) -> tuple[dict[str, Any], list[str]]:
    """``options`` split into the plain-JSON ones and the names of the others (a recording cannot hold them)."""
    kept: dict[str, Any] = {}
    dropped: list[str] = []
    for name, value in (options or {}).items():
        try:
            kept[name] = _json_value(value, name)
        except RecordingError:
            dropped.append(name)
    return kept, dropped
