"""The vision obstacle map: two views make an obstacle, one view counts once, the floor clears."""

from __future__ import annotations

import numpy as np

from tourbot.maps.grid import OccupancyGrid
from tourbot.vision.occupancy import VisionMap


def _map() -> VisionMap:
    return VisionMap(OccupancyGrid(np.zeros((100, 100), np.float32), 0.05, (0.0, 0.0, 0.0)))


def test_two_views_make_an_obstacle_and_many_pixels_of_one_view_do_not() -> None:
    m = _map()
    none = np.zeros((0, 2))
    m.update(np.full((50, 2), 2.03), none)
    assert not m.occupied().any()
    m.update(np.array([[2.04, 2.04]]), none)
    assert m.obstacle_points().shape == (1, 2)
    assert np.allclose(m.obstacle_points()[0], [2.05, 2.05])


def test_free_floor_clears_a_phantom_but_not_beside_the_same_views_hits() -> None:
    m = _map()
    p = np.array([[1.02, 1.02]])
    for _ in range(2):
        m.update(p, np.zeros((0, 2)))
    assert m.occupied().any()
    m.update(p, p)  # the same view's floor next to its own hit does not count
    assert m.occupied().any()
    for _ in range(4):  # three hits (2.7) less four misses (1.6)
        m.update(np.zeros((0, 2)), p)
    assert not m.occupied().any()
    for _ in range(3):
        m.update(np.zeros((0, 2)), p)
    g = m.grid()
    assert g.prob[m.frame.world_to_cell(p)[0][0], m.frame.world_to_cell(p)[0][1]] == 0.0
    assert g.prob[0, 0] == 0.5  # never seen: unknown


def test_clear_forgets_under_the_robot() -> None:
    m = _map()
    for _ in range(3):
        m.update(np.array([[2.0, 2.0], [4.0, 4.0]]), np.zeros((0, 2)))
    m.clear(np.array([2.0, 2.0]), 0.3)
    pts = m.obstacle_points()
    assert len(pts) == 1
    assert np.allclose(pts[0], [4.05, 4.05])
