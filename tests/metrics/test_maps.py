from __future__ import annotations

import numpy as np

from tourbot.geometry import transform_points
from tourbot.maps.grid import OccupancyGrid
from tourbot.metrics.maps import map_agreement, register_map


def _rooms(motion: np.ndarray | None = None) -> OccupancyGrid:
    """Walls of two rooms and a corridor stub (a shape ICP can lock onto), drawn after ``motion``."""
    rng = np.random.default_rng(0)
    walls = [((0, 0), (6, 0)), ((6, 0), (6, 4)), ((6, 4), (0, 4)), ((0, 4), (0, 0)), ((3, 0), (3, 2.5)),
             ((6, 2), (9, 2.2)), ((1, 1), (1.8, 1.4))]  # fmt: skip
    pts = np.concatenate([np.linspace(a, b, 200) for a, b in walls]) + rng.normal(0, 0.005, (1400, 2))
    if motion is not None:
        pts = transform_points(motion, pts)
    grid = OccupancyGrid(np.zeros((280, 280), np.float32), 0.05, origin=(-2.0, -2.0, 0.0))
    cells = grid.world_to_cell(pts)
    grid.prob[cells[:, 0], cells[:, 1]] = 1.0
    return grid


def test_a_turned_map_agrees_once_registered() -> None:
    ref = _rooms()
    turned = _rooms(np.array([0.25, -0.15, np.radians(2.0)]))
    before = map_agreement(turned, ref)
    t = register_map(turned, ref)
    after = map_agreement(turned, ref, transform=t)
    assert before["precision"] < 0.6
    assert after["precision"] > 0.97
    assert after["recall"] > 0.97
    # the motion found undoes the one applied
    moved = transform_points(np.array([0.25, -0.15, np.radians(2.0)]), np.array([[4.0, 3.0]]))
    back = transform_points(t, moved)
    assert np.hypot(*(back[0] - [4.0, 3.0])) < 0.05


def test_registration_never_makes_agreement_worse() -> None:
    ref = _rooms()
    same = _rooms()
    t = register_map(same, ref)
    assert map_agreement(same, ref, transform=t)["precision"] >= map_agreement(same, ref)["precision"]
    assert np.hypot(t[0], t[1]) < 0.03
    assert abs(t[2]) < np.radians(0.3)
