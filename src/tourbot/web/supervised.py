"""A child process that is started again when it stops: the supervision of the web's robots and world.

A robot (:class:`tourbot.web.process_link.ProcessLink`) and the museum's world
(:class:`tourbot.web.world_process.WorldProcess`) each run in a process of their own, and each is
supervised the same way, here:

* the child writes to a state pipe: first ``("ready", ...)`` or ``("failed", why)``, then any
  messages of its own kind (a robot's views), and ``("failed", why)`` when its step fails;
* the server reads that pipe in a thread; a failure, or the pipe's end (the process died, e.g.
  ``kill -9``), starts the child again at once, at most ``max_restarts`` times in
  ``restart_window`` seconds; past that it stays stopped (logged);
* a control pipe goes the other way; ``None`` on it tells the child to stop
  (:meth:`SupervisedProcess.close`; the child is terminated if it does not).

The child's side is :func:`run_child`: build, say ready, then step at a fixed pace of the wall clock
and serve the control pipe while it waits for the next step.

A child stopped because the interpreter exits (multiprocessing's exit handler terminates daemonic
processes) is not taken for a crash: it is not started again.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import multiprocessing
import signal
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from typing import Any, TypeVar

from tourbot.errors import TourbotError

__all__ = ["RobotProcessError", "SupervisedProcess", "run_child"]

log = logging.getLogger(__name__)

_exiting = threading.Event()


@atexit.register
def _interpreter_exits() -> None:
    # Runs before multiprocessing's own exit handler (registered earlier) terminates the daemonic
    # children: a child that stops because the server exits is not started again.
    _exiting.set()


class RobotProcessError(TourbotError):
    """A supervised process (a robot's, the world's) could not start, or stopped."""


T = TypeVar("T")


def run_child(
    label: str,
    build: Callable[[], T],
    state: Connection,
    control: Connection,
    *,
    ready: Callable[[T], tuple[Any, ...]] | None = None,
    period: Callable[[T], float],
    step: Callable[[T], tuple[Any, ...] | None],
    serve: Callable[[T, Any], None] | None = None,
) -> None:
    """A supervised child's loop.

    ``build`` the thing and send ``("ready", *ready(thing))`` (or ``("failed", why)``); then
    ``step`` it every ``period(thing)`` seconds of the wall clock, sending on ``state`` what a step
    returns (if anything). Far behind (a slow machine, more than 1 s) it does not burst to catch
    up. While it waits for the next step, each message on ``control`` goes to ``serve`` (which
    answers on ``control`` itself); ``None``, the pipe's end, or any message when there is no
    ``serve`` stops it. A step that raises is logged and sent as ``("failed", why)``, and the child
    stops. Ctrl-C is ignored (the terminal sends it to the whole process group): the server shuts
    down first, then closes its children.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        thing = build()
        state.send(("ready", *(() if ready is None else ready(thing))))
    except Exception as exc:
        state.send(("failed", f"{type(exc).__name__}: {exc}"))
        return
    pace = float(period(thing))
    next_time = time.monotonic()
    while True:
        try:
            message = step(thing)
            if message is not None:
                state.send(message)
        except (BrokenPipeError, EOFError, OSError):
            return  # the server has gone
        except Exception as exc:
            log.exception("%s: its step failed", label)
            with contextlib.suppress(BrokenPipeError, OSError):
                state.send(("failed", f"{type(exc).__name__}: {exc}"))
            return
        next_time += pace
        if next_time < time.monotonic() - 1.0:  # far behind: no burst to catch up
            next_time = time.monotonic()
        try:
            while control.poll(max(0.0, next_time - time.monotonic())):
                command = control.recv()
                if command is None or serve is None:  # close
                    return
                serve(thing, command)
        except (EOFError, OSError):
            return  # the server's end of the pipe gone


class SupervisedProcess(ABC):
    """A child process (``spawn``) read by a thread of the server and started again when it stops.

    Subclasses say what the child is (:meth:`_target`: the function and its arguments before the
    two pipes) and what its messages mean (:meth:`_on_ready`, :meth:`_on_message`). ``label``
    names it in errors and logs ("robot lefkos", "the museum's world").
    """

    def __init__(self, label: str, *, max_restarts: int, restart_window: float) -> None:
        self._ctx = multiprocessing.get_context("spawn")
        self.label = label
        self.max_restarts = max_restarts
        self.restart_window = restart_window
        self.failure: str | None = None  # why the child last stopped, until it runs again
        self.restarts: list[float] = []  # monotonic times of the restarts
        self.restarting = False
        self._closing = False
        self._lock = threading.Lock()  # held while the child is replaced, stopped or sent to
        self._reader: threading.Thread | None = None
        self._spawn()

    # --- what the subclass says -----------------------------------------------------------------
    @abstractmethod
    def _target(self) -> tuple[Callable[..., None], tuple[Any, ...], str]:
        """The child's function, its arguments before ``(state, control)``, and the process's name."""

    @abstractmethod
    def _on_ready(self, message: tuple[Any, ...]) -> None:
        """The child's ``("ready", ...)`` message."""

    def _on_message(self, message: tuple[Any, ...]) -> None:
        """Any later message of the child other than ``("failed", why)``."""
        log.warning("%s: unexpected message %r", self.label, message[0])

    # --- the mechanism ----------------------------------------------------------------------------
    def _spawn(self) -> None:
        target, args, name = self._target()
        self._state, child_state = self._ctx.Pipe(duplex=False)
        self._control, child_control = self._ctx.Pipe()
        self._process: BaseProcess = self._ctx.Process(
            target=target, args=(*args, child_state, child_control), name=name, daemon=True
        )
        self._process.start()
        child_state.close()
        child_control.close()

    def _ready(self, timeout: float) -> None:
        """The first message of a new child: ``ready``, or why it could not start."""
        if not self._state.poll(timeout):
            raise RobotProcessError(f"{self.label}: not ready within {timeout:.0f} s")
        try:
            message = self._state.recv()
        except (EOFError, OSError):
            raise RobotProcessError(f"{self.label}: its process stopped while starting") from None
        if message[0] != "ready":
            raise RobotProcessError(f"{self.label} could not start: {message[1]}")
        self._on_ready(message)

    def wait_ready(self, timeout: float = 600.0) -> None:
        """Wait until the child has been built (the first run compiles kernels); then follow it."""
        if self._reader is not None:
            return
        try:
            self._ready(timeout)
        except RobotProcessError:
            self.close()
            raise
        self._reader = threading.Thread(target=self._read, name=f"{self._process.name}-state", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        """Follow the child's messages; start it again when it fails or its process stops."""
        while True:
            try:
                message = self._state.recv()
            except (EOFError, OSError):
                self._process.join(1.0)  # reaped, for its exit code
                message = ("failed", f"its process stopped (exit code {self._process.exitcode})")
            if message[0] != "failed":
                self._on_message(message)
                continue
            if self._closing or _exiting.is_set():
                return
            self.restarting = True  # until _restart decides otherwise: never shown "failed" meanwhile
            self.failure = str(message[1])
            log.error("%s stopped: %s", self.label, self.failure)
            if not self._restart():
                return

    def _restart(self) -> bool:
        """Start the child again; False when it may not (the restart budget) or cannot."""
        while True:
            now = time.monotonic()
            self.restarts = [t for t in self.restarts if now - t < self.restart_window]
            if len(self.restarts) >= self.max_restarts:
                self.restarting = False
                log.error("%s: %d restarts in %.0f s, it stays stopped", self.label, len(self.restarts),
                          self.restart_window)  # fmt: skip
                return False
            self.restarts.append(now)
            self.restarting = True
            with self._lock:
                self._stop_process(5.0)
                self._state.close()
                if self._closing or _exiting.is_set():
                    return False
                self._spawn()
            try:
                self._ready(120.0)
            except RobotProcessError as exc:
                self.failure = str(exc)
                log.error("%s: restart failed: %s", self.label, exc)
                continue
            self.failure = None
            self.restarting = False
            log.warning("%s restarted", self.label)
            return True

    @property
    def alive(self) -> bool:
        """Whether the child's process runs."""
        return bool(self._process.is_alive())

    def _stop_process(self, timeout: float) -> None:
        with contextlib.suppress(BrokenPipeError, OSError):
            self._control.send(None)
        self._process.join(timeout)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(timeout)
        self._control.close()

    def close(self, timeout: float = 10.0) -> None:
        """Stop the child's process (idempotent); it is not started again."""
        self._closing = True
        with self._lock:
            self._stop_process(timeout)
        if self._reader is not None and self._reader is not threading.current_thread():
            self._reader.join(timeout)
        self._state.close()
