"""``tourbot bench museum`` on a short run: a row per robot, the JSON, the notes."""

from __future__ import annotations

import json
from pathlib import Path

from tourbot.cli.main import main


def test_bench_museum_reports_every_robot(tmp_path: Path) -> None:
    out = tmp_path / "museum.json"
    main(
        [
            "bench",
            "museum",
            "--robots",
            "2",
            "--crowd",
            "60",
            "--seeds",
            "1",
            "--seconds",
            "5",
            "-o",
            str(out),
        ]
    )
    payload = json.loads(out.read_text())
    rows = payload["rows"]
    assert [r["robot"] for r in rows] == [1, 2]
    for row in rows:
        assert row["visitors"] == 60
        assert 0.4 < row["closest_m"] < 50.0  # nobody inside a robot (0.3 m + half a person)
        assert row["person_collisions"] == 0
    assert len(payload["notes"]) == 2
