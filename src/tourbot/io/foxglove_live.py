"""A live Foxglove WebSocket server (``foxglove-sdk``) carrying a run's ROS 2 channels.

:class:`FoxgloveLive` is a :class:`~tourbot.io.ros2_messages.Ros2Channels`: every message goes out
as CDR on a channel with its ``ros2msg`` schema, so Foxglove (the desktop app or the web app
pointed at ``ws://HOST:PORT``) decodes it as it would a ROS 2 bag. Each server has its own
``foxglove.Context``: several robots, or a test beside a demo, never mix their channels. The map,
written once per run, is latched: a client that subscribes later gets the last one at once.
"""

from __future__ import annotations

import threading
from types import TracebackType
from typing import Any

from tourbot.errors import InputError
from tourbot.io.ros2_messages import TOPICS, Ros2Channels, message_definition

__all__ = ["FoxgloveLive"]

LATCHED = frozenset({"/map"})


def _latch(live: FoxgloveLive) -> Any:
    """A ``foxglove.websocket.ServerListener`` sending the last latched message to a new subscriber."""
    from foxglove.websocket import ServerListener

    class Latch(ServerListener):
        def on_subscribe(self, client: Any, channel: Any) -> None:  # noqa: ARG002
            last = live._last.get(channel.topic)
            if last is not None:
                # the subscription takes effect once this callback returns: send just after
                threading.Timer(0.05, live._emit, (channel.topic, *last)).start()

    return Latch()


class FoxgloveLive(Ros2Channels):
    """The channels served live on ``host:port`` (a context manager: the server stops on exit)."""

    def __init__(self, port: int, host: str = "127.0.0.1", name: str = "tourbot") -> None:
        super().__init__()
        if not 0 <= port <= 65535:
            raise InputError(f"must be a TCP port (0-65535), got {port}", field="--foxglove")
        self.host, self.port, self.name = host, port, name
        self._server: Any = None
        self._context: Any = None
        self._listener: Any = None
        self._last: dict[str, tuple[int, bytes]] = {}
        self._channels: dict[str, Any] = {}

    def __enter__(self) -> FoxgloveLive:
        import foxglove

        # the context must outlive the channels (when it is collected, they close)
        self._context = context = foxglove.Context()
        self._listener = _latch(self)
        try:
            self._server = foxglove.start_server(
                name=self.name,
                host=self.host,
                port=self.port,
                context=context,
                server_listener=self._listener,
            )
        except Exception as exc:  # the SDK raises its own error types for a port in use
            raise InputError(
                f"cannot serve Foxglove on {self.host}:{self.port}: {exc}", field="--foxglove"
            ) from None
        self.port = int(self._server.port)  # the one chosen, when asked for port 0
        for topic, msgtype in TOPICS.items():
            schema = foxglove.Schema(
                name=msgtype, encoding="ros2msg", data=message_definition(msgtype).encode()
            )
            self._channels[topic] = foxglove.Channel(
                topic, schema=schema, message_encoding="cdr", context=context
            )
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        server, self._server = self._server, None
        for channel in self._channels.values():
            channel.close()
        self._channels.clear()
        if server is not None:
            server.stop()
        self._context = self._listener = None

    def _emit(self, topic: str, stamp_ns: int, data: bytes) -> None:
        if self._server is None:
            raise RuntimeError("FoxgloveLive is not open: use it in a with statement")
        if topic in LATCHED:
            self._last[topic] = (stamp_ns, data)
        self._channels[topic].log(data, log_time=stamp_ns)
