"""Progress of a long command over a log's scans (or a sweep's tasks), visible wherever its stderr goes.

On a terminal a live bar (rich); otherwise (redirected to a file, a pipe, a job log) a plain line
every few seconds: scans done, rate, time left, and how many are running when several run at once
(``advance(running=...)``). A run of minutes is never silent.
"""

from __future__ import annotations

import sys
import time
from types import TracebackType
from typing import TextIO

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeRemainingColumn,
)

__all__ = ["LINE_EVERY", "ScanProgress"]

#: Seconds between two plain-text progress lines.
LINE_EVERY = 10.0


class ScanProgress:
    """``with ScanProgress("localize", n) as p: ... p.advance()``: a bar on a terminal, lines elsewhere."""

    def __init__(self, label: str, total: int, *, unit: str = "scans", stream: TextIO | None = None) -> None:
        self.label = label
        self.total = total
        self.unit = unit
        self.done = 0
        self.running: int | None = None
        self._stream = stream if stream is not None else sys.stderr
        self._console = Console(file=self._stream)
        self._bar: Progress | None = None
        self._task: TaskID | None = None
        self._start = 0.0
        self._last_line = 0.0

    @property
    def is_terminal(self) -> bool:
        return self._console.is_terminal

    def __enter__(self) -> ScanProgress:
        self._start = self._last_line = time.perf_counter()
        if self.is_terminal:
            columns = (
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeRemainingColumn(),
            )
            self._bar = Progress(*columns, console=self._console, transient=True)
            self._bar.__enter__()
            self._task = self._bar.add_task(self.label, total=self.total)
        return self

    def advance(self, n: int = 1, *, running: int | None = None) -> None:
        """``n`` more done; ``running``: how many are under way now (a pool's tasks), shown too."""
        self.done += n
        if running is not None:
            self.running = running
        if self._bar is not None and self._task is not None:
            label = self.label if self.running is None else f"{self.label} ({self.running} running)"
            self._bar.update(self._task, advance=n, description=label)
            return
        now = time.perf_counter()
        if now - self._last_line >= LINE_EVERY:
            self._last_line = now
            self._line(now)

    def _line(self, now: float) -> None:
        took = now - self._start
        rate = self.done / took if took > 0 else 0.0
        left = f"{(self.total - self.done) / rate:.0f} s left" if rate > 0 else "time left unknown"
        done = f"{self.done}/{self.total} {self.unit}"
        if self.running is not None:
            done += f", {self.running} running"
        speed = f"{rate:.1f}" if rate >= 1 else f"{rate:.2g}"  # a sweep's tasks: 0.046 tasks/s
        self._stream.write(f"{self.label}: {done}, {speed} {self.unit}/s, {left}\n")
        self._stream.flush()

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self._bar is not None:
            self._bar.__exit__(kind, exc, tb)
            return
        took = time.perf_counter() - self._start
        state = "stopped" if kind is not None else "done"
        self._stream.write(f"{self.label}: {state} at {self.done}/{self.total} {self.unit} in {took:.1f} s\n")
        self._stream.flush()
