"""The museum's world (its one crowd, :class:`tourbot.sim.world.MuseumWorld`) in a process of its own.

Why its own process: the crowd is part of no robot, so a robot's process that dies and is
restarted (:class:`tourbot.web.process_link.ProcessLink`) takes none of it along: the visitors
walk on where they were. And, as a robot, it is CPU-bound (the peak crowd's social forces), so it
is kept out of the server's event loop.

The world steps every ``dt / speedup`` seconds of the wall clock, as the robots do; far behind
(a slow machine) it does not burst to catch up. It reads the robots' poses and writes the visitors
through the fleet's shared memory; the pipe to the server only says it is ready (or why it could
not start) and, closed, tells it to stop.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import signal
import threading
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Protocol

from tourbot.web.process_link import RobotProcessError

__all__ = ["SteppedWorld", "WorldProcess"]

log = logging.getLogger(__name__)


class SteppedWorld(Protocol):
    """What the world's process steps: ``dt`` seconds a :meth:`step`."""

    dt: float

    def step(self) -> None: ...


def _world_main(factory: Callable[[], SteppedWorld], speedup: float, pipe: Connection) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the server stops first, then closes the world
    try:
        world = factory()
        pipe.send(("ready", ""))
    except Exception as exc:
        pipe.send(("failed", f"{type(exc).__name__}: {exc}"))
        return
    period = float(world.dt) / speedup
    next_time = time.monotonic()
    while True:
        try:
            world.step()
        except Exception:
            log.exception("the museum's world failed")
            return
        next_time += period
        if next_time < time.monotonic() - 1.0:  # far behind: no burst to catch up
            next_time = time.monotonic()
        try:
            if pipe.poll(max(0.0, next_time - time.monotonic())):
                return  # close (a message, or the server's end of the pipe gone)
        except (EOFError, OSError):
            return


class WorldProcess:
    """The world ``factory`` builds (``spawn``: picklable), stepped in a child process.

    Supervised as a robot's process is: a world whose process stops is started again (its new
    crowd carries on from the shared one, :class:`tourbot.sim.world.MuseumWorld`), at most
    ``max_restarts`` times in ``restart_window`` seconds; past that it stays stopped (logged) and
    the visitors stand where they were.
    """

    def __init__(
        self,
        factory: Callable[[], SteppedWorld],
        *,
        speedup: float = 1.0,
        max_restarts: int = 5,
        restart_window: float = 60.0,
    ) -> None:
        self._ctx = multiprocessing.get_context("spawn")
        self._factory = factory
        self._speedup = speedup
        self.max_restarts = max_restarts
        self.restart_window = restart_window
        self.restarts: list[float] = []  # monotonic times of the restarts
        self._closing = False
        self._lock = threading.Lock()
        self._watcher: threading.Thread | None = None
        self._spawn()

    def _spawn(self) -> None:
        self._pipe, child = self._ctx.Pipe()
        self._process = self._ctx.Process(
            target=_world_main, args=(self._factory, self._speedup, child), name="tourbot-world", daemon=True
        )
        self._process.start()
        child.close()

    def _ready(self, timeout: float) -> None:
        if not self._pipe.poll(timeout):
            raise RobotProcessError(f"the museum's world: not ready within {timeout:.0f} s")
        try:
            kind, why = self._pipe.recv()
        except (EOFError, OSError):
            kind, why = "failed", "its process stopped while starting"
        if kind != "ready":
            raise RobotProcessError(f"the museum's world could not start: {why}")

    def wait_ready(self, timeout: float = 600.0) -> None:
        """Wait until the world has been built (it waits for every robot's first pose); then watch it."""
        if self._watcher is not None:
            return
        try:
            self._ready(timeout)
        except RobotProcessError:
            self.close()
            raise
        self._watcher = threading.Thread(target=self._watch, name="world-watch", daemon=True)
        self._watcher.start()

    def _watch(self) -> None:
        """Start the world again whenever its process stops (within the restart budget)."""
        while True:
            self._process.join()
            with self._lock:
                if self._closing:
                    return
                now = time.monotonic()
                self.restarts = [t for t in self.restarts if now - t < self.restart_window]
                if len(self.restarts) >= self.max_restarts:
                    n, window = len(self.restarts), self.restart_window
                    log.error("the museum's world: %d restarts in %.0f s, it stays stopped", n, window)
                    return
                self.restarts.append(now)
                log.error(
                    "the museum's world stopped (exit code %s): starting it again", self._process.exitcode
                )
                self._pipe.close()
                self._spawn()
            try:
                self._ready(120.0)
            except RobotProcessError as exc:
                log.error("%s", exc)
                with self._lock:
                    if self._process.is_alive():
                        self._process.terminate()

    @property
    def alive(self) -> bool:
        return bool(self._process.is_alive())

    def close(self, timeout: float = 10.0) -> None:
        """Stop the world's process (idempotent); it is not started again."""
        with self._lock:
            self._closing = True
            with contextlib.suppress(BrokenPipeError, OSError):
                self._pipe.send(None)
            self._process.join(timeout)
            if self._process.is_alive():
                self._process.terminate()
                self._process.join(timeout)
            self._pipe.close()
        if self._watcher is not None and self._watcher is not threading.current_thread():
            self._watcher.join(timeout)
