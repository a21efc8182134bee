"""A real server for the web tests: the app under uvicorn (as ``tourbot serve`` runs it) in a thread
on a free loopback port, optionally over TLS or behind trusted proxies."""

from __future__ import annotations

import socket
import threading
import time
from pathlib import Path
from typing import Any

import uvicorn

from tourbot.web.serve import uvicorn_config


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class LiveServer:
    """``with LiveServer(app) as url:`` serves ``app`` on 127.0.0.1 until the block ends."""

    def __init__(
        self,
        app: Any,
        *,
        certfile: Path | None = None,
        keyfile: Path | None = None,
        trusted_proxies: tuple[str, ...] = (),
    ) -> None:
        self.port = free_port()
        config = uvicorn_config(app, certfile=certfile, keyfile=keyfile, trusted_proxies=trusted_proxies)
        config.host, config.port = "127.0.0.1", self.port
        self.server = uvicorn.Server(config)
        self.scheme = "https" if certfile is not None else "http"
        self.thread = threading.Thread(target=self.server.run, daemon=True)

    def __enter__(self) -> str:
        self.thread.start()
        deadline = time.monotonic() + 20
        while not self.server.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise RuntimeError("server did not start")
            time.sleep(0.05)
        return f"{self.scheme}://127.0.0.1:{self.port}"

    def __exit__(self, *_: object) -> None:
        self.server.should_exit = True
        self.thread.join(10)
