from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tourbot.mapping.incremental import MappingError
from tourbot.mapping.new_site import check_log, site_document, tour_stops
from tourbot.maps.doors import Doorway
from tourbot.records import RobotLog
from tourbot.site.model import site_from_dict


def test_logs_that_cannot_be_mapped_are_refused(hall_log: RobotLog) -> None:
    check_log(hall_log, "hall")
    with pytest.raises(MappingError, match="10 laser scans"):
        check_log(RobotLog("short", hall_log.scans[:10]), "short")
    blind = RobotLog("blind", [replace(s, odom=None) for s in hall_log.scans])
    with pytest.raises(MappingError, match="no odometry"):
        check_log(blind, "blind")
    still = RobotLog("still", [replace(s, odom=(0.0, 0.0, 0.0)) for s in hall_log.scans])
    with pytest.raises(MappingError, match=r"moves 0\.00 m"):
        check_log(still, "still")


def test_the_document_is_a_valid_site_with_doors_and_a_tour(tmp_path: Path) -> None:
    path = np.c_[np.linspace(0, 10, 50), np.zeros(50), np.zeros(50)]
    stops = tour_stops(path)
    assert [s[0] for s in stops] == pytest.approx([1.25, 3.75, 6.25, 8.75], abs=0.21)  # 0.2 m samples
    doc = site_document("x", "x.log", [Doorway((1.0, 2.0), (1.0, 2.9))], stops)
    doc["map"] = {"walls": [[[0, 0], [10, 0], [10, 5]]]}  # no grid file in this test
    site = site_from_dict(doc, base_dir=tmp_path)
    assert site.doors[0].leaf_length == pytest.approx(0.9)
    assert site.doors[0].closed_direction == pytest.approx(np.pi / 2, abs=1e-3)
    assert site.tour("highlights").exhibits == ["stop-1", "stop-2", "stop-3", "stop-4"]
