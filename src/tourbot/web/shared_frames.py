"""The live stream's WebSocket frames, built once per state and written as they are to every viewer.

Profiled with 500 viewers on one follower server, about 80 % of the event loop went to sending
the same stream message to each viewer, and most of that was per connection: compressing it with
the viewer's own permessage-deflate context (27 %) and framing it (websockets' ``send_binary``).
The stream's messages are already compact (quantized deltas, :mod:`tourbot.web.stream`), so
here they go out uncompressed: :meth:`~tourbot.web.stream.StreamBroadcast.frame_for` builds the
frame once per state (RFC 6455, section 5.2), and the hub (:class:`tourbot.web.hub.RobotHub`)
hands those bytes to :meth:`SharedFrameProtocol.write_frame` of every viewer in one pass: one
socket write per viewer, no task, no ASGI message, no compressor, no framing.

A frame without the RSV1 bit is an uncompressed message, which permessage-deflate allows on a
connection that negotiated it (RFC 7692, section 6): the JSON texts (status, path, speech) are
still compressed with the connection's own context, and neither end's compressor sees the
uncompressed binary messages, so that context stays in step.

The protocol offers the writer to the app as an ASGI extension, ``scope["extensions"][FRAME_KEY]``;
under any other ASGI server (or the test client) the app sends the messages as usual.
"""

from __future__ import annotations

from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol
from websockets.http11 import Request
from websockets.protocol import State

from tourbot.web.stream import FRAME_KEY

__all__ = ["SharedFrameProtocol"]


class SharedFrameProtocol(WebSocketsSansIOProtocol):
    """uvicorn's WebSocket protocol (websockets' sans-I/O implementation) that also offers the app
    ``scope["extensions"][FRAME_KEY] = {"write": write_frame}``: a prebuilt frame written
    straight to the socket. Everything else is uvicorn's own."""

    def handle_connect(self, event: Request) -> None:
        super().handle_connect(event)
        scope = getattr(self, "scope", None)  # none when the handshake was refused
        if scope is not None:
            scope["extensions"][FRAME_KEY] = {"write": self.write_frame}

    def write_frame(self, frame: bytes) -> bool:
        """Write ``frame`` now if the connection is open and its socket's buffer is below the high
        water mark (uvicorn's own back-pressure); whether it was written."""
        if not self._open() or not self.writable.is_set() or self.transport.is_closing():
            return False
        self.transport.write(frame)
        return True

    def _open(self) -> bool:
        return (
            self.handshake_complete
            and not self.disconnected
            and self.initial_response is None
            and not self.close_sent
            and self.conn.state is State.OPEN
        )
