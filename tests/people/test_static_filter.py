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


def test_a_beam_without_a_reading_is_not_free_space() -> None:
    from tourbot.people.static_filter import previous_occupancy

    cfg = StaticConfig()
    angles_min, inc = -np.pi / 2, np.pi / 180
    ranges = np.full(181, 5.0)
    point = np.array([[2.0, 0.0]])  # straight ahead, on beam 90
    assert previous_occupancy(point, ranges, angles_min, inc, cfg)[0] == cfg.p_free
    ranges[89:92] = 0.0  # dropouts: the laser says nothing about this place
    assert previous_occupancy(point, ranges, angles_min, inc, cfg, 0.02)[0] == 0.5
    ranges[89:92] = 2.0  # a return right there
    assert previous_occupancy(point, ranges, angles_min, inc, cfg, 0.02)[0] == cfg.p_occupied


def test_the_robots_own_body_is_learnt_only_while_it_moves() -> None:
    from tourbot.people.static_filter import RobotBodyMask

    mask = RobotBodyMask(StaticConfig(body_count=5.0))
    bumper = np.array([[-0.3, 0.4]])  # fixed in the laser frame
    still = np.zeros(3)
    for _ in range(20):
        mask.learn(bumper, still)  # a robot standing still: a person beside it looks the same
    assert not mask.is_body(bumper)[0]
    for k in range(6):
        mask.learn(np.r_[bumper, [[1.0 + 0.3 * k, 0.5 * k]]], np.array([0.1 * (k + 1), 0.0, 0.0]))
    assert mask.is_body(np.r_[bumper, [[1.0, 0.0]]]).tolist() == [True, False]
