"""tourbot.io.progress: the plain lines of a run whose stderr is not a terminal."""

from __future__ import annotations

import io

import pytest

import tourbot.io.progress
from tourbot.io.progress import ScanProgress


def test_a_pool_s_lines_say_how_many_tasks_run(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tourbot.io.progress, "LINE_EVERY", 0.0)
    stream = io.StringIO()
    with ScanProgress("sweep", 4, unit="tasks", stream=stream) as progress:
        progress.advance()
        progress.advance(running=2)
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("sweep: 1/4 tasks, ")
    assert "running" not in lines[0]  # one at a time: nothing said
    assert lines[1].startswith("sweep: 2/4 tasks, 2 running, ")
    assert "s left" in lines[1]
    assert lines[2].startswith("sweep: done at 2/4 tasks in ")
