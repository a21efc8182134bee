"""The supervision the web's robots and world share: a child that fails or dies is started again,
within its restart budget, and a closed one is not."""

from __future__ import annotations

import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

import pytest

from tourbot.web.supervised import RobotProcessError, SupervisedProcess, run_child


class _Counter:
    """Counts its steps; its step fails after ``fail_after`` seconds (never if < 0)."""

    def __init__(self, fail_after: float) -> None:
        self.fail_after = fail_after
        self.start = time.monotonic()
        self.n = 0
        self.greeting = "hello"
        self.period = 0.01

    def step(self) -> tuple[str, int]:
        self.n += 1
        if 0 <= self.fail_after < time.monotonic() - self.start:
            raise ValueError("the step failed")
        return ("tick", self.n)


def _child(fail_after: float, state: Connection, control: Connection) -> None:
    """Ready (saying hello), then a ``("tick", n)`` every 10 ms."""
    run_child(
        "the ticker",
        lambda: _Counter(fail_after),
        state,
        control,
        ready=lambda counter: (counter.greeting,),
        period=lambda counter: counter.period,
        step=_Counter.step,
    )


def _refuses(state: Connection, control: Connection) -> None:
    del control  # it stops before it could be told to
    state.send(("failed", "TourbotError: no such site"))


class _Ticker(SupervisedProcess):
    def __init__(self, fail_after: float, **budget: Any) -> None:
        self.fail_after = fail_after
        self.readies: list[str] = []
        self.ticks = 0
        super().__init__("the ticker", **budget)

    def _target(self) -> tuple[Callable[..., None], tuple[Any, ...], str]:
        return _child, (self.fail_after,), "tourbot-ticker"

    def _on_ready(self, message: tuple[Any, ...]) -> None:
        self.readies.append(message[1])

    def _on_message(self, message: tuple[Any, ...]) -> None:
        self.ticks = message[1]


class _Refuser(SupervisedProcess):
    def _target(self) -> tuple[Callable[..., None], tuple[Any, ...], str]:
        return _refuses, (), "tourbot-refuser"

    def _on_ready(self, message: tuple[Any, ...]) -> None:
        raise AssertionError(f"never ready: {message}")


def _wait(condition: Callable[[], bool], limit: float = 60.0) -> None:
    end = time.monotonic() + limit
    while not condition():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.02)


def test_messages_reach_the_subclass_and_close_ends_the_child() -> None:
    ticker = _Ticker(-1.0, max_restarts=5, restart_window=60.0)
    ticker.wait_ready(60)
    assert ticker.readies == ["hello"]
    _wait(lambda: ticker.ticks > 5)
    ticker.close()
    assert not ticker.alive
    assert ticker.restarts == []
    ticker.close()  # idempotent


def test_a_killed_child_is_started_again() -> None:
    ticker = _Ticker(-1.0, max_restarts=5, restart_window=60.0)
    try:
        ticker.wait_ready(60)
        ticker._process.kill()
        _wait(lambda: len(ticker.readies) == 2 and ticker.alive and not ticker.restarting)
        assert len(ticker.restarts) == 1
        assert ticker.failure is None
        ticks = ticker.ticks
        _wait(lambda: ticker.ticks > ticks)  # the new child is followed
    finally:
        ticker.close()


def test_a_child_that_fails_too_often_stays_stopped_and_says_why() -> None:
    ticker = _Ticker(0.05, max_restarts=2, restart_window=60.0)
    try:
        ticker.wait_ready(60)
        _wait(lambda: len(ticker.restarts) == 2 and not ticker.restarting and not ticker.alive)
        time.sleep(0.5)
        assert len(ticker.readies) == 3  # the first child and two restarts, no more
        assert ticker.failure == "ValueError: the step failed"
    finally:
        ticker.close()


def test_a_child_that_cannot_start_says_why() -> None:
    refuser = _Refuser("the refuser", max_restarts=5, restart_window=60.0)
    with pytest.raises(RobotProcessError, match="the refuser could not start: TourbotError: no such site"):
        refuser.wait_ready(60)
    assert not refuser.alive
