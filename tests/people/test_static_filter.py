from __future__ import annotations

import numpy as np

from tests.people.scenes import scan_with_circles
from tourbot.maps.grid import OccupancyGrid
from tourbot.people.static_filter import StaticConfig, StaticFilter


def test_static_post_is_static_and_new_leg_is_moving() -> None:
    f = StaticFilter(StaticConfig(lag=1))
    post = (2.0, 0.0, 0.06)
    pose = np.array([0.0, 0.0, 0.0])
    first = f.moving_probability(np.array([[1.95, 0.0]]), scan_with_circles(0.0, pose, [post]), pose)
    np.testing.assert_allclose(first, [0.5])  # no history yet: unknown
    pose2 = np.array([0.1, 0.05, 0.02])  # the robot moved a little
    leg = (1.0, 1.0, 0.06)  # a leg where the floor was free a scan ago
    pts = np.array([[1.95, 0.0], [1.0, 0.95]])
    p = f.moving_probability(pts, scan_with_circles(0.1, pose2, [post, leg]), pose2)
    assert p[0] < 0.1
    assert p[1] > 0.9


def test_hidden_in_previous_scan_is_unknown() -> None:
    f = StaticFilter()
    pose = np.array([0.0, 0.0, 0.0])
    f.moving_probability(np.zeros((0, 2)), scan_with_circles(0.0, pose, [(1.0, 0.0, 0.3)]), pose)
    p = f.moving_probability(np.array([[3.0, 0.0]]), scan_with_circles(0.1, pose, [(3.05, 0.0, 0.06)]), pose)
    np.testing.assert_allclose(p, [0.5])


def test_features_on_the_map_are_static() -> None:
    prob = np.zeros((40, 40), dtype=np.float32)
    prob[20, 10] = 1.0  # an occupied cell around x = 0.5 m, y = 1.0 m (0.05 m cells)
    grid = OccupancyGrid(prob=prob, resolution=0.05)
    f = StaticFilter(grid_map=grid)
    on = f.on_map(np.array([[0.52, 1.02], [1.5, 1.5], [-3.0, 0.0]]))
    assert on.tolist() == [True, False, False]
