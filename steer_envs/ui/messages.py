"""The steer-ui wire protocol: JSON messages from the page, validated before anything runs.

Page -> server (one JSON object per WebSocket text message, ``type`` first):

=============  ==========================================================================
``hello``      ask for the current settings and view (sent once on connect)
``configure``  ``sampler``, ``batch``, ``guide_ratio``, ``mcmc_steps``, ``execute`` (any subset; ``null``: default)
``reset``      ``seed`` (optional int): new start state and noise
``steer``      ``kind``: ``"sketch"`` | ``"point"`` | ``"none"``; ``points``: ``[[u, v], ...]`` image pixels
``step``       execute the chosen plan of the last steer (unsteered if none)
``play``       keep steering with the last interaction and executing, at the policy's rate
``pause``      stop playing
``nudge``      ``to``: ``[u, v]``: move the agent there (a physical correction; steered domains)
``push``       ``to``: ``[u, v]``: drag the agent there; the controller recovers (push domains)
``save``       send the session's recording (interactions, seeds, settings) as a download
``export``     ``format``: ``"mp4"`` (default) | ``"gif"``: replay the session and send the video
=============  ==========================================================================

Server -> page: ``ready`` (the domain's declaration: its interactions and
overlays; settings, image size, samplers, frame), ``plans`` (a steering result
in pixels), ``frame`` (a PNG of the view after a step / nudge / push / reset,
with the domain's ``overlays`` and ``panel`` rows, and a ``notice``), ``settings``,
``playing``, ``download`` (``name``, ``mime``, base64 ``data``: a saved recording or
an exported video), ``error`` (``message``: what was wrong). A bad message only ever produces an
``error`` reply.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

__all__ = ["MAX_MESSAGE_CHARS", "MESSAGE_TYPES", "Message", "MessageError", "parse_message"]

#: the longest text message accepted (a 4096-point sketch is ~90 kB)
MAX_MESSAGE_CHARS = 262_144
#: message type -> the keys it may carry besides ``type``
MESSAGE_TYPES: dict[str, frozenset[str]] = {
    "hello": frozenset(),
    "configure": frozenset({"sampler", "batch", "guide_ratio", "mcmc_steps", "execute"}),
    "reset": frozenset({"seed"}),
    "steer": frozenset({"kind", "points"}),
    "step": frozenset(),
    "play": frozenset(),
    "pause": frozenset(),
    "nudge": frozenset({"to"}),
    "push": frozenset({"to"}),
    "save": frozenset(),
    "export": frozenset({"format"}),
}
#: the fields ``type`` requires
_REQUIRED: dict[str, frozenset[str]] = {
    "steer": frozenset({"kind"}),
    "nudge": frozenset({"to"}),
    "push": frozenset({"to"}),
}


class MessageError(ValueError):
    """A message that is not valid JSON or not a valid steer-ui request."""


@dataclass(frozen=True)
class Message:
    """A parsed request: its ``type`` and its fields (shapes checked later by the session)."""

    type: str
    fields: dict[str, Any]


def _reject_constant(name: str) -> Any:
    raise MessageError(f"numbers must be finite; the message holds {name}")


def _check_numbers(value: Any, where: str, depth: int = 0) -> None:
    """Reject booleans where numbers go, non-finite floats and over-deep nesting (cheap, before any work)."""
    if depth > 4:
        raise MessageError(f"{where} is nested too deeply")
    if isinstance(value, float) and not math.isfinite(value):
        raise MessageError(f"{where} must be finite, got {value!r}")
    if isinstance(value, list):
        for item in value:
            _check_numbers(item, where, depth + 1)
    elif isinstance(value, dict):
        raise MessageError(f"{where} must not hold an object")


def parse_message(text: Any) -> Message:
    """Parse one text message; ``MessageError`` says what is wrong (size, JSON, type, unknown or missing keys)."""
    if not isinstance(text, str):
        raise MessageError(f"messages must be JSON text, got {type(text).__name__}")
    if len(text) > MAX_MESSAGE_CHARS:
        raise MessageError(f"message too long: {len(text)} characters, the limit is {MAX_MESSAGE_CHARS}")
    try:
        data = json.loads(text, parse_constant=_reject_constant)
    except MessageError:
        raise
    except (ValueError, RecursionError) as exc:
        raise MessageError(f"malformed JSON: {exc}") from None
    if not isinstance(data, dict):
        raise MessageError(f"a message must be a JSON object with a 'type', got {type(data).__name__}")
    kind = data.get("type")
    if not isinstance(kind, str) or kind not in MESSAGE_TYPES:
        raise MessageError(f"'type' must be one of {sorted(MESSAGE_TYPES)}, got {kind!r}"[:300])
    fields = {k: v for k, v in data.items() if k != "type"}
    unknown = sorted(set(fields) - MESSAGE_TYPES[kind])
    if unknown:
        raise MessageError(f"a {kind!r} message takes {sorted(MESSAGE_TYPES[kind])}, got unknown {unknown}"[:300])
    missing = sorted(_REQUIRED.get(kind, frozenset()) - set(fields))
    if missing:
        raise MessageError(f"a {kind!r} message needs {missing}")
    for key, value in fields.items():
        _check_numbers(value, f"'{key}'")
        if isinstance(value, bool):
            raise MessageError(f"'{key}' must not be a boolean, got {value!r}")
    return Message(kind, fields)
