from __future__ import annotations

import numpy as np

from tourbot.maps.doors import suggest_doorways
from tourbot.maps.grid import OccupancyGrid


def _two_rooms(gap: float) -> OccupancyGrid:
    """Two 4 m rooms side by side (5 cm cells), the wall between with a gap of ``gap`` m."""
    res = 0.05
    prob = np.zeros((80, 160), np.float32)
    prob[0, :] = prob[-1, :] = prob[:, 0] = prob[:, -1] = 1.0
    prob[:, 80] = 1.0
    lo = 40 - round(gap / res / 2)
    prob[lo : lo + round(gap / res), 80] = 0.0
    return OccupancyGrid(prob, res)


def test_a_door_wide_gap_is_found_where_it_is() -> None:
    doors = suggest_doorways(_two_rooms(0.9))
    assert len(doors) == 1
    d = doors[0]
    assert 0.8 < d.width < 1.05
    mid = (np.asarray(d.a) + np.asarray(d.b)) / 2
    assert abs(mid[0] - 4.025) < 0.1
    assert abs(mid[1] - 2.0) < 0.15


def test_no_door_in_a_gap_too_wide_or_none() -> None:
    assert suggest_doorways(_two_rooms(2.0)) == []
    assert suggest_doorways(_two_rooms(0.0)) == []
