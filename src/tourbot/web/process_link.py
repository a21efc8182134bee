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

import logging
import time
from collections.abc import Callable
from dataclasses import replace
from multiprocessing.connection import Connection
from typing import Any, Protocol, runtime_checkable

from tourbot.errors import TourbotError
from tourbot.web.link import RobotLink, RobotView
from tourbot.web.supervised import RobotProcessError, SupervisedProcess, run_child

__all__ = ["ProcessLink", "RestartableFactory"]

log = logging.getLogger(__name__)

_COMMANDS = frozenset({"send_goal", "start_tour", "around", "photo", "stop"})


def _robot_main(
    factory: Callable[[], RobotLink], speedup: float, state: Connection, control: Connection
) -> None:
    """The robot process: build the link, then step it at its period / ``speedup`` and serve commands."""
    run_child(
        "the robot",
        factory,
        state,
        control,
        ready=lambda link: (link.period, link.view()),
        period=lambda link: float(link.period) / speedup,
        step=_step,
        serve=lambda link, message: _serve(link, control, message),
    )


def _step(link: RobotLink) -> tuple[str, RobotView]:
    link.step()
    return ("view", link.view())


def _serve(link: RobotLink, control: Connection, message: tuple[int, str, tuple[Any, ...]]) -> None:
    """Run a command on the robot; answer its number with ``ok`` and the result, or ``error``."""
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


class ProcessLink(SupervisedProcess):
    """A :class:`RobotLink` built by ``factory`` in a child process (``spawn``: ``factory`` must be
    picklable, e.g. a frozen dataclass with ``__call__``).

    :meth:`step` does nothing: the robot steps itself, ``speedup`` times faster than its period.
    :meth:`view` returns the latest state the robot sent; commands wait for the robot's answer (at
    most ``command_timeout`` seconds) and raise its error as a :class:`TourbotError`. A picture
    (:meth:`photo`) waits up to ``photo_timeout`` seconds: rendering the 1280 x 960 camera costs
    the robot 0.7-2 s of CPU (the first one the most), which on a loaded machine took more than
    the 10 s a command may take, and the visitor got no picture.

    Supervised (:class:`tourbot.web.supervised.SupervisedProcess`): a robot process that dies (or
    whose step fails) is started again at once, from its last estimated pose when the factory is a
    :class:`RestartableFactory`. The server's side (the slots, the queue, the viewers) never
    notices more than a pause and a "restarting" status. At most ``max_restarts`` restarts in
    ``restart_window`` seconds; past that the robot stays failed (a robot that cannot run is not
    restarted forever).
    """

    def __init__(
        self,
        factory: Callable[[], RobotLink],
        *,
        speedup: float = 1.0,
        name: str = "robot",
        command_timeout: float = 10.0,
        photo_timeout: float = 30.0,
        max_restarts: int = 5,
        restart_window: float = 60.0,
    ) -> None:
        self._factory = factory
        self._speedup = speedup
        self.name = name
        self.period = 0.1
        self.command_timeout = command_timeout
        self.photo_timeout = photo_timeout
        self._view: RobotView | None = None
        self._seq = 0  # the number of the last command sent
        super().__init__(f"robot {name}", max_restarts=max_restarts, restart_window=restart_window)

    def _target(self) -> tuple[Callable[..., None], tuple[Any, ...], str]:
        """The robot's loop, built where it last was (its last estimated pose) on a restart."""
        view = self._view
        factory = self._factory
        if view is not None and isinstance(factory, RestartableFactory):
            factory = factory.at((view.x, view.y, view.theta))
        return _robot_main, (factory, self._speedup), f"tourbot-robot-{self.name}"

    def _on_ready(self, message: tuple[Any, ...]) -> None:
        """``ready`` with the robot's period and first view."""
        _, self.period, self._view = message

    def _on_message(self, message: tuple[Any, ...]) -> None:
        if message[0] == "view":
            self._view = message[1]
        else:
            super()._on_message(message)

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
        return bytes(self._call("photo", timeout=self.photo_timeout))

    def stop(self) -> None:
        self._call("stop")

    def _call(self, name: str, *args: Any, timeout: float | None = None) -> Any:
        """Run command ``name`` in the robot's process and wait for its answer, at most ``timeout``
        seconds (``command_timeout`` by default)."""
        assert name in _COMMANDS
        wait = self.command_timeout if timeout is None else timeout
        self.wait_ready()
        with self._lock:
            if self.failure is not None or not self._process.is_alive():
                raise RobotProcessError(f"{self.label}: {self.failure or 'its process stopped'}")
            try:
                self._seq += 1
                self._control.send((self._seq, name, args))
                deadline = time.monotonic() + wait
                while True:  # answers to earlier commands that timed out are dropped
                    if not self._control.poll(max(0.0, deadline - time.monotonic())):
                        raise RobotProcessError(f"{self.label}: no answer in {wait} s")
                    seq, *answer = self._control.recv()
                    if seq == self._seq:
                        break
            except (BrokenPipeError, EOFError, OSError):
                raise RobotProcessError(f"{self.label}: its process stopped") from None
        kind, result = answer
        if kind != "ok":
            raise TourbotError(str(result))
        return result
