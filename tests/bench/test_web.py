"""The byte-counting relay of ``tourbot bench web``: what the server sends, split by connection kind."""

from __future__ import annotations

import asyncio

from tourbot.bench.web import _relay


def test_the_relay_counts_websocket_and_plain_http_connections_apart() -> None:
    async def scenario() -> dict[str, int]:
        async def answer(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            request = await reader.readline()
            if b"upgrade" in request:
                writer.write(b"HTTP/1.1 101 Switching Protocols\r\n\r\n" + b"x" * 50)
            else:
                writer.write(b"HTTP/1.1 200 OK\r\n\r\n" + b"y" * 300)
            await writer.drain()
            writer.close()

        server = await asyncio.start_server(answer, "127.0.0.1", 0)
        port, down, relay = await _relay(int(server.sockets[0].getsockname()[1]))
        for line in (b"GET /ws upgrade\r\n", b"GET /api/robots\r\n", b"GET /api/site\r\n"):
            reader, writer = await asyncio.open_connection("127.0.0.1", port)
            writer.write(line)
            await writer.drain()
            await reader.read()
            writer.close()
        relay.close()
        server.close()
        return down

    down = asyncio.run(scenario())
    assert down["websocket"] == len(b"HTTP/1.1 101 Switching Protocols\r\n\r\n") + 50
    assert down["http"] == 2 * (len(b"HTTP/1.1 200 OK\r\n\r\n") + 300)
    assert down["total"] == down["websocket"] + down["http"]
