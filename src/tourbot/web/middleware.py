"""The server's outer guards, as ASGI middleware: they run before any route parses or authenticates.

* :class:`BodyLimit` refuses a request body larger than a limit (413) from its ``Content-Length``
  before reading a byte, and cuts off a body sent without one (chunked) once it passes the limit.
  No route ever holds more than the limit in memory, logged in or not.
* :class:`SameOrigin` refuses a state-changing request (POST, PUT, PATCH, DELETE) that a browser
  sent from another origin (403): cross-site request forgery. ``Sec-Fetch-Site`` must say
  ``same-origin`` when the browser sends it, and ``Origin`` must be the server's own scheme, host
  *and port* (SameSite cookies do not separate ports: a page on another port of the same host is
  "same-site"). A request with neither header does not come from a browser's page and carries no
  ambient authority worth forging.
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable, MutableMapping
from typing import Any

from tourbot.web.guard import origin_allowed

__all__ = ["BodyLimit", "SameOrigin"]

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

_UNSAFE = frozenset({"POST", "PUT", "PATCH", "DELETE"})


async def _refuse(send: Send, status: int, detail: str) -> None:
    body = json.dumps({"detail": detail}).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope.get("headers", ()):
        if key == name:
            return bytes(value).decode("latin-1")
    return None


class BodyLimit:
    """At most ``max_bytes`` of request body on every HTTP route (413 beyond)."""

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = _header(scope, b"content-length")
        if declared is not None:
            if not declared.strip().isdigit():
                await _refuse(send, 400, "malformed Content-Length")
                return
            if int(declared) > self.max_bytes:
                await _refuse(send, 413, f"request body too large: at most {self.max_bytes} bytes")
                return
        received = 0
        started = refused = False
        limit = f"request body too large: at most {self.max_bytes} bytes"

        async def counted() -> Message:
            nonlocal received, refused
            if refused:
                return {"type": "http.disconnect"}
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    # answer now and tell the route the client has gone (the rest is never read)
                    refused = True
                    if not started:
                        await _refuse(send, 413, limit)
                    return {"type": "http.disconnect"}
            return message

        async def watched(message: Message) -> None:
            nonlocal started
            if refused:
                return  # the 413 was the answer
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, counted, watched)
        except Exception:
            if not refused:
                raise


class SameOrigin:
    """Cross-site request forgery: state-changing requests only from the server's own pages."""

    def __init__(self, app: ASGIApp, allowed: tuple[str, ...] = ()) -> None:
        self.app = app
        self.allowed = allowed

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and scope["method"] in _UNSAFE:
            fetch_site = _header(scope, b"sec-fetch-site")
            origin = _header(scope, b"origin")
            if origin is not None and origin in self.allowed:
                pass  # a configured front end (its pages are another origin, on purpose)
            elif fetch_site is not None and fetch_site not in ("same-origin", "none"):
                await _refuse(send, 403, "cross-site request refused")
                return
            elif origin is not None and not origin_allowed(
                origin, _header(scope, b"host"), scheme=str(scope.get("scheme", "http"))
            ):
                await _refuse(send, 403, "cross-origin request refused")
                return
        await self.app(scope, receive, send)
