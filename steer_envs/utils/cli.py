"""Small command-line helpers shared by ``steer-bench`` and the training CLI."""

from __future__ import annotations

import json
from typing import Any

__all__ = ["parse_key_value"]


def parse_key_value(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` with VALUE parsed as JSON when it is JSON (``3``, ``0.5``, ``true``, ``[1, 2]``), else a string.

    ``ValueError`` when ``text`` has no ``=`` or an empty key.

    >>> parse_key_value("down_dims=[32, 64, 128]")
    ('down_dims', [32, 64, 128])
    >>> parse_key_value("start=first_mode")
    ('start', 'first_mode')
    """
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise ValueError(f"expected KEY=VALUE, got {text!r}")
    try:
        parsed: Any = json.loads(value)
    except json.JSONDecodeError:
        parsed = value
    return key.strip(), parsed
