"""Move around an exhibit: the viewpoints on the robot's map."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest

from tourbot.maps.grid import OccupancyGrid
from tourbot.navigation.around import AroundConfig, exhibit_centre, viewpoints_around
from tourbot.navigation.planner import CostMap


def _hall(walls: Sequence[tuple[slice, slice]] = ()) -> CostMap:
    """A 10 m x 10 m hall at 10 cm, walled round, with more ``walls`` (row, column slices)."""
    prob = np.zeros((100, 100), dtype=np.float32)
    prob[0, :] = prob[-1, :] = prob[:, 0] = prob[:, -1] = 1.0
    for rows, cols in walls:
        prob[rows, cols] = 1.0
    return CostMap(OccupancyGrid(prob, 0.1, (0.0, 0.0, 0.0)))


def _angle(point: tuple[float, float, float], centre: tuple[float, float]) -> float:
    return math.atan2(point[1] - centre[1], point[0] - centre[0])


def test_in_the_open_the_robot_views_the_exhibit_from_every_side() -> None:
    pose = (5.0, 3.0, math.pi / 2)  # looking north at an exhibit at (5, 4.2)
    views = viewpoints_around(pose, _hall(), AroundConfig(distance=1.2, views=6))
    centre = exhibit_centre(pose, 1.2)
    assert centre == pytest.approx((5.0, 4.2))
    assert len(views) == 6
    assert views[0] == pytest.approx(pose)  # the viewing pose first
    for k, (x, y, theta) in enumerate(views):
        assert math.hypot(x - centre[0], y - centre[1]) == pytest.approx(1.2)
        facing = math.atan2(centre[1] - y, centre[0] - x)
        assert math.remainder(theta - facing, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
        turned = math.remainder(_angle(views[k], centre) - _angle(views[0], centre), 2 * math.pi)
        assert turned == pytest.approx(math.remainder(k * math.pi / 3, 2 * math.pi), abs=1e-9)


def test_against_a_wall_only_the_reachable_side_in_one_sweep() -> None:
    """An exhibit in front of a wall (the wall 0.6 m behind it): the viewpoints behind are left
    out, and the others come in one sweep from one end of the free arc to the other."""
    pose = (5.0, 3.0, math.pi / 2)
    hall = _hall([(slice(48, 50), slice(1, 99))])  # a wall across at y = 4.8 m
    views = viewpoints_around(pose, hall, AroundConfig(distance=1.2, views=6))
    centre = exhibit_centre(pose, 1.2)
    assert 2 <= len(views) < 6
    assert all(y < 4.4 for _, y, _ in views)  # none beyond (or too close to) the wall
    assert any(v == pytest.approx(pose) for v in views)
    angles = np.unwrap([_angle(v, centre) for v in views])
    steps = np.diff(angles)
    assert np.allclose(steps, math.pi / 3)  # one way round, neighbour after neighbour


def test_a_viewpoint_the_robot_cannot_reach_is_left_out() -> None:
    """A viewpoint inside a closed room of the map is free but unreachable from the viewing pose."""
    pose = (5.0, 3.0, 0.0)  # the exhibit at (6.2, 3.0); the viewpoint east of it at (7.4, 3.0)
    room = [
        (slice(22, 24), slice(68, 82)),
        (slice(38, 40), slice(68, 82)),
        (slice(22, 40), slice(68, 70)),
        (slice(22, 40), slice(80, 82)),
    ]
    open_hall = viewpoints_around(pose, _hall(), AroundConfig(distance=1.2, views=6))
    closed = viewpoints_around(pose, _hall(room), AroundConfig(distance=1.2, views=6))
    east = (7.4, 3.0)
    assert any(math.hypot(x - east[0], y - east[1]) < 1e-6 for x, y, _ in open_hall)
    assert not any(math.hypot(x - east[0], y - east[1]) < 1e-6 for x, y, _ in closed)


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="at least 2 views"):
        AroundConfig(views=1)
