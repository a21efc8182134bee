"""``tourbot bench sim``: the quick run times the simulator and runs one guided tour."""

from __future__ import annotations

import json
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
