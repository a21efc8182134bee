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


def test_weights_scale_the_evidence_once_per_cell_at_the_surest_point() -> None:
    m, plain = _map(), _map()
    hit = np.array([[2.01, 2.01], [2.06, 2.06], [3.01, 3.01]])  # two points in one 10 cm cell
    floor = np.array([[4.01, 4.01], [4.51, 4.51]])
    m.update(hit, floor, np.array([0.2, 0.5, 0.0]), np.array([1.0, 0.25]))
    plain.update(hit, floor)
    cell = m.frame.world_to_cell(hit)
    fc = m.frame.world_to_cell(floor)
    assert m.log_odds[cell[0, 0], cell[0, 1]] == np.float32(0.5 * m.hit)  # the surest of the two
    assert m.log_odds[cell[2, 0], cell[2, 1]] == 0.0  # weight 0: no evidence ...
    assert m.seen[cell[2, 0], cell[2, 1]]  # ... but looked at
    assert m.log_odds[fc[0, 0], fc[0, 1]] == np.float32(m.miss)
    assert m.log_odds[fc[1, 0], fc[1, 1]] == np.float32(0.25 * m.miss)
    assert plain.log_odds[cell[0, 0], cell[0, 1]] == np.float32(plain.hit)  # no weights: full evidence
    # four views at weight 0.5 make an obstacle where two at full weight do
    for _ in range(3):
        m.update(hit[:1], np.zeros((0, 2)), np.array([0.5]))
    assert m.occupied()[cell[0, 0], cell[0, 1]]
    assert not _weighted_twice(0.5).occupied().any()


def _weighted_twice(w: float) -> VisionMap:
    m = _map()
    for _ in range(2):
        m.update(np.array([[2.01, 2.01]]), np.zeros((0, 2)), np.array([w]))
    return m


def test_weighted_floor_next_to_the_views_own_hits_is_still_dropped() -> None:
    m = _map()
    p = np.array([[1.02, 1.02]])
    m.update(p, np.array([[1.02, 1.02], [3.0, 3.0]]), np.array([1.0]), np.array([1.0, 0.5]))
    c, f = m.frame.world_to_cell(p)[0], m.frame.world_to_cell(np.array([[3.0, 3.0]]))[0]
    assert m.log_odds[c[0], c[1]] == np.float32(m.hit)
    assert m.log_odds[f[0], f[1]] == np.float32(0.5 * m.miss)
