"""``tourbot bench sim``: the quick run times the simulator and runs one guided tour."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from tourbot.cli.main import main


@pytest.mark.slow
def test_quick_run_reports_speed_and_a_tour(tmp_path: Path) -> None:
    out = tmp_path / "sim.json"
    main(["bench", "sim", "--quick", "--crowds", "sparse", "--output", str(out)])
    payload = json.loads(out.read_text())
    speed, tour = payload["rows"]
    assert speed["case"] == "simulator, 50 people"
    # Both clocks are measured: simulated time per wall-clock second and per CPU second.
    assert speed["real-time x"] > 0
    assert speed["CPU real-time x"] > 0
    assert tour["case"] == "tour 'short', sparse crowd"
    assert tour["runs"] == 1
    assert tour["CPU real-time x"] > 0
    assert tour["collisions"] == 0
    assert tour["success %"] == 100.0
    assert any("fewer than 10 seeds" in note for note in payload["notes"])


@pytest.mark.slow
def test_kidnaps_standing_and_touring_are_timed(tmp_path: Path) -> None:
    out = tmp_path / "kidnap.json"
    args = ["--quick", "--no-tours", "--crowds", "sparse", "--kidnap-seeds", "1", "--kidnap-window", "20"]
    main(["bench", "sim", *args, "--output", str(out)])
    payload = json.loads(out.read_text())
    kidnaps = [r for r in payload["rows"] if r["case"].startswith("kidnap")]
    assert [r["case"] for r in kidnaps] == [
        "kidnap 5 m standing, sparse crowd",
        "kidnap 5 m touring, sparse crowd",
    ]
    for key in ("kidnaps_standing_sparse", "kidnaps_touring_sparse"):
        (run,) = payload["meta"][key]
        moved = math.hypot(run["destination"][0] - run["source"][0], run["destination"][1] - run["source"][1])
        assert 4.5 <= moved <= 5.5
        assert run["recovered"] is not None  # found again (the default settings)
    assert payload["meta"]["max_injection"] > 0
