"""The live stream's WebSocket frames, built once per state and written as they are to every viewer.

Profiled with 500 viewers on one follower server, about 80 % of the event loop went to sending
the same stream message to each viewer, and most of that was per connection: compressing it with
the viewer's own permessage-deflate context (27 %) and framing it (websockets' ``send_binary``).
The stream's messages are already compact (quantized deltas, :mod:`tourbot.web.stream`), so
here they go out uncompressed: :meth:`~tourbot.web.stream.StreamBroadcast.frame_for` builds the
frame once per state (RFC 6455, section 5.2) and :class:`SharedFrameProtocol` writes those bytes
to each viewer's socket, nothing else per viewer.

A frame without the RSV1 bit is an uncompressed message, which permessage-deflate allows on a
connection that negotiated it (RFC 7692, section 6): the JSON texts (status, path, speech) are
still compressed with the connection's own context, and neither end's compressor sees the
uncompressed binary messages, so that context stays in step.

The app asks for it by adding the frame to a normal ASGI message,
``{"type": "websocket.send", "bytes": message, FRAME_KEY: frame}``: any other ASGI server ignores
the extra key and sends ``bytes`` its own way.
"""

from __future__ import annotations

from typing import Any

from uvicorn.protocols.utils import ClientDisconnected
from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol
from websockets.protocol import State

from tourbot.web.stream import FRAME_KEY

__all__ = ["SharedFrameProtocol"]


class SharedFrameProtocol(WebSocketsSansIOProtocol):
    """uvicorn's WebSocket protocol (websockets' sans-I/O implementation) that writes a message's
    prebuilt frame (``FRAME_KEY``) straight to the socket; everything else is uvicorn's own."""

    async def send(self, message: Any) -> None:
        frame = message.get(FRAME_KEY) if message.get("type") == "websocket.send" else None
        if frame is None or not self._open():
            await super().send(message)
            return
        await self.writable.wait()  # back-pressure as uvicorn's own send (a slow viewer's buffer)
        if self.disconnected:
            raise ClientDisconnected()
        if not self._open():  # closed while waiting: uvicorn's send says how
            await super().send(message)
            return
        self.transport.write(frame)

    def _open(self) -> bool:
        return (
            self.handshake_complete
            and self.initial_response is None
            and not self.close_sent
            and self.conn.state is State.OPEN
        )
