"""The museum's world (its one crowd, :class:`tourbot.sim.world.MuseumWorld`) in a process of its own.

Why its own process: the crowd is part of no robot, so a robot's process that dies and is
restarted (:class:`tourbot.web.process_link.ProcessLink`) takes none of it along: the visitors
walk on where they were. And, as a robot, it is CPU-bound (the peak crowd's social forces), so it
is kept out of the server's event loop.

The world steps every ``dt / speedup`` seconds of the wall clock, as the robots do; far behind
(a slow machine) it does not burst to catch up. It reads the robots' poses and writes the visitors
through the fleet's shared memory; its state pipe to the server only says it is ready (or why it
could not start, or why its step failed), and its control pipe, sent ``None`` or closed, tells it
to stop. It is supervised as a robot is (:class:`tourbot.web.supervised.SupervisedProcess`).
"""

from __future__ import annotations

from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any, Protocol

from tourbot.web.supervised import SupervisedProcess, run_child

__all__ = ["SteppedWorld", "WorldProcess"]


class SteppedWorld(Protocol):
    """What the world's process steps: ``dt`` seconds a :meth:`step`."""

    dt: float

    def step(self) -> None: ...


def _world_main(
    factory: Callable[[], SteppedWorld], speedup: float, state: Connection, control: Connection
) -> None:
    run_child(
        "the museum's world",
        factory,
        state,
        control,
        period=lambda world: float(world.dt) / speedup,
        step=_step,
    )


def _step(world: SteppedWorld) -> None:
    world.step()


class WorldProcess(SupervisedProcess):
    """The world ``factory`` builds (``spawn``: picklable), stepped in a child process.

    Supervised as a robot's process is (:class:`tourbot.web.supervised.SupervisedProcess`): a world
    whose process stops is started again (its new crowd carries on from the shared one,
    :class:`tourbot.sim.world.MuseumWorld`), at most ``max_restarts`` times in ``restart_window``
    seconds; past that it stays stopped (logged) and the visitors stand where they were.
    """

    def __init__(
        self,
        factory: Callable[[], SteppedWorld],
        *,
        speedup: float = 1.0,
        max_restarts: int = 5,
        restart_window: float = 60.0,
    ) -> None:
        self._factory = factory
        self._speedup = speedup
        super().__init__("the museum's world", max_restarts=max_restarts, restart_window=restart_window)

    def _target(self) -> tuple[Callable[..., None], tuple[Any, ...], str]:
        return _world_main, (self._factory, self._speedup), "tourbot-world"

    def _on_ready(self, message: tuple[Any, ...]) -> None:
        """Nothing to keep: the world's state is in the fleet's shared memory."""
