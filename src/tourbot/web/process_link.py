"""A robot whose loop runs in its own process, seen through the web's :class:`RobotLink`.

Why: the simulator, MCL and the navigator are CPU-bound. Stepped in the server's process they hold
the GIL for most of each 100 ms cycle, and the event loop serving the viewers waits behind them
(measured: p99 506 ms from sampling a state to handing it to a socket, with 50 viewers). In a
process of its own the robot keeps its pace and the server only reads the latest state.

Two pipes join the processes:

* state (robot -> server): the :class:`RobotView` after every step; the server's reader thread
  keeps only the latest (latest-state-wins: it never builds a backlog);
* control (server -> robot, and back): a command (its number, method name and arguments) and its
  answer (the number, then ``"ok"`` and the result, or ``"error"`` and the message of the
  :class:`TourbotError` it raised; a picture of the robot's camera comes back as its JPEG bytes).
  The numbers pair them: the late answer of a command that timed out is dropped, never taken for
  the next command's. The robot serves commands
  while it waits for its next step, so a command waits for at most one step.

The robot process ignores Ctrl-C (the terminal sends it to the whole process group): the server
shuts down first, then closes the robot (:meth:`ProcessLink.close`).
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import multiprocessing
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from multiprocessing.connection import Connection
from typing import Any, Protocol, runtime_checkable

from tourbot.errors import TourbotError
from tourbot.web.link import RobotLink, RobotView

_exiting = threading.Event()


@atexit.register
def _interpreter_exits() -> None:
    # Runs before multiprocessing's own exit handler (registered earlier) terminates the daemonic
    # robot processes: a robot that stops because the server exits is not started again.
    _exiting.set()


__all__ = ["ProcessLink", "RestartableFactory", "RobotProcessError"]

log = logging.getLogger(__name__)

_COMMANDS = frozenset({"send_goal", "start_tour", "around", "photo", "stop"})


class RobotProcessError(TourbotError):
    """The robot's process could not start, or stopped."""


def _robot_main(
    factory: Callable[[], RobotLink], speedup: float, state: Connection, control: Connection
) -> None:
    """The robot process: build the link, then step it at its period / ``speedup`` and serve commands."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        link = factory()
        state.send(("ready", link.period, link.view()))
    except Exception as exc:
        state.send(("failed", f"{type(exc).__name__}: {exc}"))
        return
    period = float(link.period) / speedup
    next_time = time.monotonic()
    while True:
        try:
            link.step()
            state.send(("view", link.view()))
        except (BrokenPipeError, EOFError, OSError):
            return  # the server has gone
        except Exception as exc:
            log.exception("the robot's step failed")
            state.send(("failed", f"{type(exc).__name__}: {exc}"))
            return
        next_time += period
        if next_time < time.monotonic() - 1.0:  # far behind (slow machine): no burst to catch up
            next_time = time.monotonic()
        while control.poll(max(0.0, next_time - time.monotonic())):
            try:
                message = control.recv()
            except (EOFError, OSError):
                return
            if message is None:  # close
                return
            seq, name, args = message
            try:
                result = getattr(link, name)(*args)
                control.send((seq, "ok", result))
            except TourbotError as exc:
                control.send((seq, "error", str(exc)))
            except Exception as exc:
                log.exception("robot command %s failed", name)
                control.send((seq, "error", f"{type(exc).__name__}: {exc}"))


@runtime_checkable
class RestartableFactory(Protocol):
    """A robot factory that can build the same robot standing at another pose (a restart)."""

    def __call__(self) -> RobotLink: ...

    def at(self, pose: tuple[float, float, float]) -> Callable[[], RobotLink]: ...


class ProcessLink:
    """A :class:`RobotLink` built by ``factory`` in a child process (``spawn``: ``factory`` must be
    picklable, e.g. a frozen dataclass with ``__call__``).

    :meth:`step` does nothing: the robot steps itself, ``speedup`` times faster than its period.
    :meth:`view` returns the latest state the robot sent; commands wait for the robot's answer (at
    most ``command_timeout`` seconds) and raise its error as a :class:`TourbotError`.

    Supervised: a robot process that dies (or whose step fails) is started again at once, from its
    last estimated pose when the factory is a :class:`RestartableFactory`. The server's side (the
    slots, the queue, the viewers) never notices more than a pause and a "restarting" status. At
    most ``max_restarts`` restarts in ``restart_window`` seconds; past that the robot stays failed
    (a robot that cannot run is not restarted forever).
    """

    def __init__(
        self,
        factory: Callable[[], RobotLink],
        *,
        speedup: float = 1.0,
        name: str = "robot",
        command_timeout: float = 10.0,
        max_restarts: int = 5,
        restart_window: float = 60.0,
    ) -> None:
        self._ctx = multiprocessing.get_context("spawn")
        self._factory = factory
        self._speedup = speedup
        self.name = name
        self.period = 0.1
        self.command_timeout = command_timeout
        self.max_restarts = max_restarts
        self.restart_window = restart_window
        self.failure: str | None = None
        self.restarts: list[float] = []  # monotonic times of the restarts
        self.restarting = False
        self._closing = False
        self._view: RobotView | None = None
        self._command_lock = threading.Lock()
        self._seq = 0  # the number of the last command sent
        self._reader: threading.Thread | None = None
        self._spawn(factory)

    def _spawn(self, factory: Callable[[], RobotLink]) -> None:
        self._state, child_state = self._ctx.Pipe(duplex=False)
        self._control, child_control = self._ctx.Pipe()
        self._process = self._ctx.Process(
            target=_robot_main,
            args=(factory, self._speedup, child_state, child_control),
            name=f"tourbot-robot-{self.name}",
            daemon=True,
        )
        self._process.start()
        child_state.close()
        child_control.close()

    def _ready(self, timeout: float) -> None:
        """The first message of a new process: ``ready`` with its period and first view."""
        if not self._state.poll(timeout):
            raise RobotProcessError(f"robot {self.name}: not ready within {timeout:.0f} s")
        try:
            message = self._state.recv()
        except (EOFError, OSError):
            raise RobotProcessError(f"robot {self.name}: its process stopped while starting") from None
        if message[0] != "ready":
            raise RobotProcessError(f"robot {self.name} could not start: {message[1]}")
        _, self.period, self._view = message

    def wait_ready(self, timeout: float = 600.0) -> None:
        """Wait until the robot has been built (the first run compiles kernels); then follow it."""
        if self._reader is not None:
            return
        try:
            self._ready(timeout)
        except RobotProcessError:
            self.close()
            raise
        self._reader = threading.Thread(target=self._read, name=f"robot-{self.name}-state", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        """Follow the robot's states; restart a robot whose process stopped or whose step failed."""
        while True:
            try:
                message = self._state.recv()
            except (EOFError, OSError):
                message = ("failed", "the robot's process stopped")
            if message[0] == "view":
                self._view = message[1]
                continue
            if self._closing or _exiting.is_set():
                return
            self.restarting = True  # until _restart decides otherwise: never shown "failed" meanwhile
            self.failure = str(message[1])
            log.error("robot %s stopped: %s", self.name, self.failure)
            if not self._restart():
                return

    def _restart(self) -> bool:
        """Start the robot again from its last estimated pose; False when it may not (or cannot)."""
        now = time.monotonic()
        self.restarts = [t for t in self.restarts if now - t < self.restart_window]
        if len(self.restarts) >= self.max_restarts:
            self.restarting = False
            log.error("robot %s: %d restarts in %.0f s, it stays stopped", self.name, len(self.restarts),
                      self.restart_window)  # fmt: skip
            return False
        self.restarts.append(now)
        self.restarting = True
        view = self._view
        factory = self._factory
        if view is not None and isinstance(factory, RestartableFactory):
            factory = factory.at((view.x, view.y, view.theta))
        with self._command_lock:
            self._stop_process(5.0)
            self._state.close()
            if self._closing or _exiting.is_set():
                return False
            self._spawn(factory)
        try:
            self._ready(120.0)
        except RobotProcessError as exc:
            self.failure = str(exc)
            log.error("robot %s: restart failed: %s", self.name, exc)
            return self._restart()
        self.failure = None
        self.restarting = False
        log.warning("robot %s restarted", self.name)
        return True

    # --- RobotLink ------------------------------------------------------------------------------
    def step(self) -> None:
        """Nothing: the robot steps in its own process."""

    def view(self) -> RobotView:
        """The latest state; once the robot's process has stopped, that state at rest, marked failed."""
        self.wait_ready()
        view = self._view
        assert view is not None
        if self.failure is not None:
            what = "restarting" if self.restarting else "failed"
            nav = replace(view.nav, state=what, message=f"the robot stopped: {self.failure}")
            return replace(view, v=0.0, omega=0.0, nav=nav)
        return view

    def send_goal(self, x: float, y: float, theta: float | None = None, exhibit: str | None = None) -> None:
        self._call("send_goal", x, y, theta, exhibit)

    def start_tour(self, name: str, exhibits: list[tuple[str, float, float, float]]) -> None:
        self._call("start_tour", name, exhibits)

    def around(self, exhibit: str, x: float, y: float, theta: float) -> None:
        self._call("around", exhibit, x, y, theta)

    def photo(self) -> bytes:
        return bytes(self._call("photo"))

    def stop(self) -> None:
        self._call("stop")

    def _call(self, name: str, *args: Any) -> Any:
        assert name in _COMMANDS
        self.wait_ready()
        with self._command_lock:
            if self.failure is not None or not self._process.is_alive():
                raise RobotProcessError(f"robot {self.name}: {self.failure or 'its process stopped'}")
            try:
                self._seq += 1
                self._control.send((self._seq, name, args))
                deadline = time.monotonic() + self.command_timeout
                while True:  # answers to earlier commands that timed out are dropped
                    if not self._control.poll(max(0.0, deadline - time.monotonic())):
                        raise RobotProcessError(f"robot {self.name}: no answer in {self.command_timeout} s")
                    seq, *answer = self._control.recv()
                    if seq == self._seq:
                        break
            except (BrokenPipeError, EOFError, OSError):
                raise RobotProcessError(f"robot {self.name}: its process stopped") from None
        kind, result = answer
        if kind != "ok":
            raise TourbotError(str(result))
        return result

    def _stop_process(self, timeout: float) -> None:
        with contextlib.suppress(BrokenPipeError, OSError):
            self._control.send(None)
        self._process.join(timeout)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(timeout)
        self._control.close()

    def close(self, timeout: float = 10.0) -> None:
        """Stop the robot's process (idempotent); it is not restarted."""
        self._closing = True
        with self._command_lock:
            self._stop_process(timeout)
        if self._reader is not None and self._reader is not threading.current_thread():
            self._reader.join(timeout)
        self._state.close()
