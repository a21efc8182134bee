"""``tourbot bench site``: the whole path from a log to a served tour, on a synthetic building."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.mapping.conftest import building, drive
from tourbot.bench.site import _one
from tourbot.bench.web import CHROMIUM
from tourbot.io.carmen import write_carmen

pytestmark = [
    pytest.mark.slow,
    pytest.mark.browser,
    pytest.mark.skipif(not CHROMIUM.exists(), reason=f"Debian's chromium is not installed at {CHROMIUM}"),
]


def test_a_new_site_is_served_and_toured_from_its_log(tmp_path: Path) -> None:
    pytest.importorskip("playwright.async_api")
    log = drive(building(), n=120)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    row = _one("hall", path, tmp_path / "sites", "empty", tour_seconds=180.0, enough=1)
    assert row["site new s"] > 0
    assert row["serve start s"] > 0
    assert row["commands"] == 2
    assert row["clicks"] == 6  # log in, open, place, save; book, start the tour
    assert row["fields"] == 3  # user, password, name
    assert len(row["arrivals s"]) >= 1, row  # the robot reached the tour's first stop
    assert row["served tour s"] == pytest.approx(
        row["site new s"] + row["serve start s"] + row["staff page s"] + row["to 1st stop s"]
    )
    assert row["met"] == (row["served tour s"] <= 600.0)
