"""The server's guards: what a client may send, how often, and from which page.

Every message from a browser is untrusted: it is size-checked, parsed into one of the
:data:`Command` models (unknown fields refused) and rate-limited per session with a token bucket.
A bad message gets an error reply, never a crash; a WebSocket from a foreign origin is refused.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Annotated, Literal
from urllib.parse import urlsplit

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError

from tourbot.errors import TourbotError

__all__ = [
    "MAX_CHAT_TEXT",
    "Around",
    "Chat",
    "Command",
    "CommandError",
    "GuardConfig",
    "TokenBucket",
    "json_depth",
    "origin_allowed",
    "parse_command",
]


class CommandError(TourbotError):
    """A client message that is refused: too large, malformed, or not allowed."""


@dataclass(frozen=True)
class GuardConfig:
    """Limits on what clients send: message size, command rate (sustained and burst), and the
    text channel's rate per session (``chat_per_minute`` sustained, ``chat_burst`` at once)."""

    max_message_bytes: int = 2048
    max_json_depth: int = 8  # a command is one flat object; deeper nesting is refused unparsed
    commands_per_second: float = 5.0
    burst: int = 10
    chat_per_minute: float = 12.0
    chat_burst: int = 3


@dataclass
class TokenBucket:
    """Rate limit: ``rate`` tokens per second, at most ``burst`` saved up."""

    rate: float
    burst: int
    tokens: float = field(default=-1.0)
    stamp: float = field(default=-math.inf)

    def allow(self, now: float) -> bool:
        if self.tokens < 0.0:
            self.tokens, self.stamp = float(self.burst), now
        self.tokens = min(float(self.burst), self.tokens + (now - self.stamp) * self.rate)
        self.stamp = now
        if self.tokens >= 1.0:
            self.tokens -= 1.0
            return True
        return False


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


_Coord = Annotated[float, Field(ge=-1e4, le=1e4, allow_inf_nan=False)]
_Slug = Annotated[str, Field(min_length=1, max_length=64)]


class Book(_Strict):
    type: Literal["book"]


class Leave(_Strict):
    type: Literal["leave"]


class Ping(_Strict):
    type: Literal["ping"]


class Stop(_Strict):
    type: Literal["stop"]


class GoTo(_Strict):
    type: Literal["goto"]
    x: _Coord
    y: _Coord
    theta: Annotated[float, Field(ge=-10.0, le=10.0, allow_inf_nan=False)] | None = None


class GoToExhibit(_Strict):
    type: Literal["exhibit"]
    exhibit: _Slug


class StartTour(_Strict):
    type: Literal["tour"]
    tour: _Slug


class Around(_Strict):
    """Move around this exhibit (Burgard et al., section 6.1): view it from several directions."""

    type: Literal["around"]
    exhibit: _Slug


#: The longest text message of the text channel (characters).
MAX_CHAT_TEXT = 300


class Chat(_Strict):
    """A text message to the people on site (from the visitor in control) or back (on-board)."""

    type: Literal["chat"]
    text: Annotated[str, Field(min_length=1, max_length=MAX_CHAT_TEXT)]


class Say(_Strict):
    """A phrase typed on (or heard by) the on-board screen."""

    type: Literal["say"]
    text: Annotated[str, Field(max_length=200)]


Command = Annotated[
    Book | Leave | Ping | Stop | GoTo | GoToExhibit | StartTour | Around | Chat | Say,
    Field(discriminator="type"),
]
_COMMAND: TypeAdapter[Command] = TypeAdapter(Command)


def json_depth(text: str) -> int:
    """The deepest nesting of arrays and objects in the JSON ``text`` (brackets inside strings are
    not counted), found by one scan without parsing, so that no parser ever recurses on it."""
    depth = deepest = 0
    in_string = escaped = False
    for char in text:
        if in_string:
            if escaped:
                escaped = False
            elif char == "\\":
                escaped = True
            elif char == '"':
                in_string = False
        elif char == '"':
            in_string = True
        elif char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth -= 1
    return deepest


def parse_command(raw: str | bytes, config: GuardConfig) -> Command:
    """The command in ``raw``; :class:`CommandError` saying what is wrong otherwise.

    The error names what is wrong, never repeats the message (nor a part of it).
    """
    if len(raw) > config.max_message_bytes:
        raise CommandError(f"message of {len(raw)} bytes refused: at most {config.max_message_bytes}")
    try:
        text = raw.decode() if isinstance(raw, bytes) else raw
    except UnicodeDecodeError:
        raise CommandError("message is not JSON: not UTF-8 text") from None
    if json_depth(text) > config.max_json_depth:
        raise CommandError(f"message refused: nested deeper than {config.max_json_depth} levels")
    try:
        data = json.loads(text)
    except ValueError as exc:
        reason = exc.msg if isinstance(exc, json.JSONDecodeError) else "malformed"
        raise CommandError(f"message is not JSON: {reason}") from None
    try:
        return _COMMAND.validate_python(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        # Never the input itself: pydantic quotes an unknown tag, and an extra field's name is the
        # client's; the location of a known command's field is ours.
        loc = [str(p) for p in first["loc"][:2]]
        reason = first["msg"]
        if first["type"] == "union_tag_invalid":
            loc, reason = [], "unknown command type"
        elif first["type"] == "extra_forbidden":
            loc, reason = loc[:1], "unknown field"
        raise CommandError(f"bad command ({'.'.join(loc) or 'message'}): {reason}") from None


def origin_allowed(
    origin: str | None, host: str | None, allowed: tuple[str, ...] = (), scheme: str | None = None
) -> bool:
    """A request may come from the server's own pages (same host and port, and the same scheme
    when ``scheme`` of the request is given: ``http``/``ws`` or ``https``/``wss``) or an allowed
    origin only.

    Browsers always send ``Origin`` on WebSockets; a request without it is not from a page and
    is refused as well.
    """
    if not origin:
        return False
    if origin in allowed:
        return True
    parts = urlsplit(origin)
    if parts.scheme not in ("http", "https") or host is None or parts.netloc != host:
        return False
    return scheme is None or parts.scheme == {"ws": "http", "wss": "https"}.get(scheme, scheme)
