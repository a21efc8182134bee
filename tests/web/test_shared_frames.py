"""The stream's prebuilt frames on the wire of a real uvicorn server (``tourbot serve``'s settings)."""

from __future__ import annotations

import base64
import json
import os
import socket
import time
import zlib
from pathlib import Path

import httpx

from tests.web.live import LiveServer
from tests.web.test_serve import _hall_app
from tourbot.web.app import COOKIE
from tourbot.web.stream import StreamDecoder

_TAIL = b"\x00\x00\xff\xff"  # what permessage-deflate strips from each compressed message


def _read_exactly(sock: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise ConnectionError("closed")
        data += chunk
    return data


def _frames(sock: socket.socket, seconds: float) -> list[tuple[int, int, bytes]]:
    """The server's frames as they came on the socket: (opcode, RSV1, payload)."""
    found = []
    end = time.monotonic() + seconds
    sock.settimeout(0.5)
    while time.monotonic() < end:
        try:
            b0, b1 = _read_exactly(sock, 2)
        except TimeoutError:
            continue
        assert not b1 & 0x80, "a server frame is never masked"
        n = b1 & 0x7F
        if n == 126:
            n = int.from_bytes(_read_exactly(sock, 2), "big")
        elif n == 127:
            n = int.from_bytes(_read_exactly(sock, 8), "big")
        assert b0 & 0x80, "the server sends whole messages (FIN)"
        found.append((b0 & 0x0F, (b0 >> 6) & 1, _read_exactly(sock, n)))
    return found


def test_stream_frames_go_uncompressed_and_texts_keep_their_deflate_context(
    sqlite_url: str, tmp_path: Path
) -> None:
    """On a connection that negotiated permessage-deflate, the stream's binary messages come as
    uncompressed frames (RSV1 clear) that decode as the stream, and the JSON texts still come
    compressed, in one deflate context that their decoder follows across the binary frames."""
    server = LiveServer(_hall_app(sqlite_url, tmp_path))
    with server as url:
        token = httpx.get(f"{url}/api/session").cookies[COOKIE]
        host = url.removeprefix("http://")
        with socket.create_connection(("127.0.0.1", server.port)) as sock:
            key = base64.b64encode(os.urandom(16)).decode()
            request = (
                f"GET /ws/lefkos HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                "Sec-WebSocket-Extensions: permessage-deflate; client_max_window_bits\r\n"
                f"Origin: {url}\r\nCookie: {COOKIE}={token}\r\n\r\n"
            )
            sock.sendall(request.encode())
            head = b""
            while b"\r\n\r\n" not in head:
                head += sock.recv(1)
            assert head.startswith(b"HTTP/1.1 101")
            assert b"permessage-deflate" in head.lower()
            frames = _frames(sock, 3.0)
    binary = [payload for opcode, rsv1, payload in frames if opcode == 2 and not rsv1]
    assert len(binary) >= 3, "a keyframe and deltas of the walking people"
    assert not [f for f in frames if f[0] == 2 and f[1]], "no stream frame is compressed"
    decoder = StreamDecoder()
    for payload in binary:
        decoder.feed(payload)  # the stream as the page reads it
    assert len(decoder.scene().people) == 7
    inflate = zlib.decompressobj(wbits=-15)  # one context for the connection (context takeover)
    texts = [json.loads(inflate.decompress(p + _TAIL)) for opcode, rsv1, p in frames if opcode == 1 and rsv1]
    assert [t["type"] for t in texts][:2] == ["hello", "status"]
    assert not [f for f in frames if f[0] == 1 and not f[1]], "every text is compressed"
