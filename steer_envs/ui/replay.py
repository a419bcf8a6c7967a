"""Replay a recorded steer-ui session to the same frames (:mod:`steer_envs.ui.recording` says what is recorded).

:func:`replay` opens a fresh :class:`~steer_envs.ui.session.Session` or
:class:`~steer_envs.ui.push_session.PushSession` as the recording's was
(:func:`open_recorded`), runs its events again in order and compares every
frame with the recorded digest: :class:`Replayed` says where they differ.
Its own module because it opens sessions, which record themselves.

>>> from steer_envs.ui.recording import Recording
>>> replayed = replay(Recording("soup-scoop", 1, {"kind": "push"}, ({"op": "step"},)))
>>> replayed.identical, len(replayed.frames)
(True, 2)
>>> replayed.session.close()
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.ui.recording import Recording, RecordingError, frame_digest

__all__ = ["Replayed", "open_recorded", "replay"]


def open_recorded(recording: Recording, controller_options: Mapping[str, Any] | None = None) -> Any:
    """A fresh session opened as ``recording``'s was (``controller_options`` add to / override the recorded ones)."""
    from steer_envs.ui.push_session import PushSession
    from steer_envs.ui.session import Session
    from steer_envs.ui.settings import SteerSettings

    opened = dict(recording.session)
    try:
        if opened["kind"] == "push":
            given = dict(controller_options or {})
            missing = [name for name in opened.get("unrecorded_options") or [] if name not in given]
            if missing:
                raise RecordingError(
                    f"the recording's controller options {missing} are not JSON: "
                    "pass them to replay (controller_options)"
                )
            options = {**(opened.get("controller_options") or {}), **given}
            return PushSession(
                recording.domain, seed=recording.seed, env_kwargs=opened.get("env_kwargs"), controller_options=options
            )
        settings = opened.get("settings")
        return Session(
            recording.domain,
            env=opened.get("env"),
            env_kwargs=opened.get("env_kwargs"),
            policy=opened.get("policy"),
            checkpoint=opened.get("checkpoint"),
            accelerate=opened.get("accelerate", "fastest"),
            settings=None if settings is None else SteerSettings(**settings),
            seed=recording.seed,
        )
    except TypeError as exc:
        raise RecordingError(f"the recording's 'session' cannot open a session: {exc}") from None


@dataclass
class Replayed:
    """What a replay produced: the frame after opening and after each event, and where frames differed.

    Attributes:
        frames: ``len(events) + 1`` frames (the first: after opening).
        outcomes: per event, what the call returned (a steering outcome, a step outcome, an info dict, ...).
        mismatches: indices of events whose frame differs from the recorded digest (``-1``: the opening's).
        session: the replayed session, still open (close it).
    """

    frames: list[np.ndarray]
    outcomes: list[Any]
    mismatches: list[int]
    session: Any

    @property
    def identical(self) -> bool:
        """Every recorded frame digest matched."""
        return not self.mismatches


def _apply(session: Any, event: Mapping[str, Any]) -> Any:
    """Run one logged call on ``session``."""
    from steer_envs.core.interaction import Point, Sketch

    op = event["op"]
    if op == "reset":
        return session.reset(seed=event["seed"])
    if op == "configure":
        return session.configure(**event["knobs"])
    if op == "step":
        return session.execute()
    if op == "nudge":
        return session.nudge(event["to"])
    if op == "push":
        return session.push(event["to"])
    interaction = event["interaction"]
    if interaction is None:
        return session.steer(None)
    kind = interaction.get("kind")
    if kind == "point":
        return session.steer(Point(interaction["target"]))
    if kind == "sketch":
        return session.steer(Sketch(interaction["points"]))
    raise RecordingError(f"a 'steer' event's interaction kind must be 'point' or 'sketch', got {kind!r}")


def replay(
    recording: Recording,
    *,
    controller_options: Mapping[str, Any] | None = None,
    on_event: Any = None,
) -> Replayed:
    """Open a session as ``recording``'s was and run its events; compare each frame with the recorded digest.

    ``on_event(index, event, session, outcome)`` is called after each event (e.g. to draw a video frame).
    A call the session refuses raises ``RecordingError`` naming the event.
    """
    from steer_envs.ui.views import SessionError

    session = open_recorded(recording, controller_options)
    try:
        frames = [session.frame()]
        mismatches = [-1] if recording.start_frame not in (None, frame_digest(frames[0])) else []
        outcomes: list[Any] = []
        for i, event in enumerate(recording.events):
            try:
                outcome = _apply(session, event)
            except (SessionError, ValueError, TypeError) as exc:
                raise RecordingError(f"events[{i}] ({event['op']!r}) cannot be replayed: {exc}") from None
            outcomes.append(outcome)
            if on_event is not None:
                on_event(i, event, session, outcome)
            frames.append(session.frame())
            if "frame" in event and event["frame"] != frame_digest(frames[-1]):
                mismatches.append(i)
    except BaseException:
        session.close()
        raise
    return Replayed(frames, outcomes, mismatches, session)
