"""The recorder writes its recording whole or not at all."""

from __future__ import annotations

from pathlib import Path

import pytest

from tourbot.runtime.sinks import Recorder


class _BrokenSnapshot:
    def to_json(self) -> str:
        raise ValueError("cannot encode")


def test_a_recording_that_fails_keeps_the_previous_one(tmp_path: Path) -> None:
    path = tmp_path / "recording.jsonl.gz"
    Recorder(path).close()  # an empty recording, written whole
    before = path.read_bytes()
    recorder = Recorder(path)
    recorder.snapshots = [_BrokenSnapshot()]  # type: ignore[list-item]
    with pytest.raises(ValueError, match="cannot encode"):
        recorder.close()
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["recording.jsonl.gz"]
    assert Recorder.read(path) == []
