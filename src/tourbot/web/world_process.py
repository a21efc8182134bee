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
    """The world ``factory`` builds (``spawn``: picklable), stepped in a child process."""

    def __init__(self, factory: Callable[[], SteppedWorld], *, speedup: float = 1.0) -> None:
        ctx = multiprocessing.get_context("spawn")
        self._pipe, child = ctx.Pipe()
        self._process = ctx.Process(
            target=_world_main, args=(factory, speedup, child), name="tourbot-world", daemon=True
        )
        self._process.start()
        child.close()
        self._ready = False

    def wait_ready(self, timeout: float = 600.0) -> None:
        """Wait until the world has been built (it waits for every robot's first pose)."""
        if self._ready:
            return
        if not self._pipe.poll(timeout):
            self.close()
            raise RobotProcessError(f"the museum's world: not ready within {timeout:.0f} s")
        try:
            kind, why = self._pipe.recv()
        except (EOFError, OSError):
            kind, why = "failed", "its process stopped while starting"
        if kind != "ready":
            self.close()
            raise RobotProcessError(f"the museum's world could not start: {why}")
        self._ready = True

    @property
    def alive(self) -> bool:
        return bool(self._process.is_alive())

    def close(self, timeout: float = 10.0) -> None:
        """Stop the world's process (idempotent)."""
        with contextlib.suppress(BrokenPipeError, OSError):
            self._pipe.send(None)
        self._process.join(timeout)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(timeout)
        self._pipe.close()
