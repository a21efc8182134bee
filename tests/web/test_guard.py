"""The WebSocket command parser under hostile input: an error, never a crash."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.web.guard import (
    Chat,
    Command,
    CommandError,
    GuardConfig,
    json_depth,
    origin_allowed,
    parse_command,
)

CONFIG = GuardConfig()
_json = st.recursive(
    st.none() | st.booleans() | st.floats(allow_nan=True) | st.integers() | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=30,
)
_TYPES = ["book", "leave", "ping", "stop", "goto", "exhibit", "tour", "around", "chat", "say"]
_commands = st.fixed_dictionaries(
    {"type": st.sampled_from([*_TYPES, "x"])},
    optional={
        "x": _json,
        "y": st.floats() | st.integers() | st.text(max_size=5),
        "theta": st.floats(),
        "exhibit": _json,
        "tour": st.text(max_size=80),
        "text": st.text(max_size=320),
    },
)


def test_deep_nesting_is_refused_without_recursion() -> None:
    for raw in ("[" * 1000 + "]" * 1000, '{"a":' * 300 + "1" + "}" * 300):
        with pytest.raises(CommandError, match="nested deeper"):
            parse_command(raw, CONFIG)
    assert json_depth('{"type": "say", "text": "[[[[[[[[[[[[["}') == 1  # brackets in strings


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.text(max_size=3000), st.binary(max_size=3000)))
def test_any_text_or_bytes_gives_a_command_or_a_command_error(raw: str | bytes) -> None:
    message = ""
    try:
        parse_command(raw, CONFIG)
    except CommandError as exc:
        message = str(exc)
    assert len(message) < 200  # says what is wrong, never repeats the message


@settings(max_examples=400, deadline=None)
@given(st.one_of(_json, _commands), st.integers(0, 40))
def test_any_json_gives_a_command_or_a_command_error(data: object, wrap: int) -> None:
    raw = "[" * wrap + json.dumps(data) + "]" * wrap
    try:
        command = parse_command(raw, CONFIG)
    except CommandError:
        return
    assert wrap == 0  # a command is never found inside an array
    assert command.type in _TYPES
    if isinstance(command, Chat):
        assert 1 <= len(command.text) <= 300
    assert isinstance(command, Command.__origin__.__args__)  # type: ignore[attr-defined]


def _depth(data: object) -> int:
    if isinstance(data, list):
        return 1 + max(map(_depth, data), default=0)
    if isinstance(data, dict):
        return 1 + max(map(_depth, data.values()), default=0)
    return 0


@given(_json)
def test_json_depth_agrees_with_the_parsed_structure(data: object) -> None:
    """The scan (no parsing) sees the nesting of the parsed value, strings with quotes, backslashes
    and brackets included."""
    assert json_depth(json.dumps(data)) == _depth(data)


def test_origins_differ_by_port_and_scheme() -> None:
    assert origin_allowed("http://127.0.0.1:8000", "127.0.0.1:8000")
    assert not origin_allowed("http://127.0.0.1:8899", "127.0.0.1:8000")
    assert not origin_allowed("https://127.0.0.1:8000", "127.0.0.1:8000", scheme="http")
    assert origin_allowed("https://127.0.0.1:8000", "127.0.0.1:8000", scheme="wss")
    assert origin_allowed("https://front.example", "127.0.0.1:8000", ("https://front.example",))
