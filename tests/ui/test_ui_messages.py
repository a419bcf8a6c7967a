"""The steer-ui wire protocol refuses every malformed message with a MessageError, never anything else."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from steer_envs.ui.messages import MAX_MESSAGE_CHARS, MESSAGE_TYPES, MessageError, parse_message


def test_valid_messages_parse() -> None:
    msg = parse_message(json.dumps({"type": "steer", "kind": "sketch", "points": [[1, 2], [3.5, 4]]}))
    assert msg.type == "steer" and msg.fields["points"] == [[1, 2], [3.5, 4]]
    assert parse_message('{"type": "configure", "sampler": "GD", "guide_ratio": null}').fields["guide_ratio"] is None
    for kind in MESSAGE_TYPES:
        if kind not in ("steer", "nudge", "push"):
            assert parse_message(json.dumps({"type": kind})).type == kind


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("{bad", "malformed JSON"),
        ("[1, 2]", "JSON object"),
        ('{"kind": "sketch"}', "'type' must be one of"),
        ('{"type": "launch"}', "'type' must be one of"),
        ('{"type": 3}', "'type' must be one of"),
        ('{"type": "steer"}', "needs \\['kind'\\]"),
        ('{"type": "steer", "kind": "sketch", "points": [[NaN, 1]]}', "finite"),
        ('{"type": "steer", "kind": "sketch", "points": [[Infinity, 1]]}', "finite"),
        ('{"type": "steer", "kind": "sketch", "colour": "red"}', "unknown \\['colour'\\]"),
        ('{"type": "configure", "batch": true}', "boolean"),
        ('{"type": "nudge", "to": {"u": 1}}', "object"),
        ('{"type": "steer", "kind": "sketch", "points": [[[[[[1]]]]]]}', "nested too deeply"),
        ("x" * (MAX_MESSAGE_CHARS + 1), "too long"),
        (b'{"type": "hello"}', "JSON text"),
        ("[" * 100_000, "malformed JSON"),
    ],
)
def test_malformed_messages(text: object, match: str) -> None:
    with pytest.raises(MessageError, match=match):
        parse_message(text)


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=20,
)


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.text(max_size=200), JSON_VALUES.map(json.dumps)))
def test_any_text_parses_or_gives_a_message_error(text: str) -> None:
    try:
        parse_message(text)
    except MessageError:
        pass
