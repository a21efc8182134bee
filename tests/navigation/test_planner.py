from __future__ import annotations

import numpy as np
import pytest

from tourbot.maps.grid import OccupancyGrid
from tourbot.navigation.planner import CostMap, NoPathError, PlannerConfig


def _room_with_wall(gap: bool = True) -> OccupancyGrid:
    """10 m x 6 m at 5 cm: outer walls, and a wall at x = 5 m with a 1.2 m door at y in [2.4, 3.6]."""
    prob = np.zeros((120, 200), dtype=np.float32)
    prob[0, :] = prob[-1, :] = 1.0
    prob[:, 0] = prob[:, -1] = 1.0
    prob[:, 100] = 1.0
    if gap:
        prob[48:72, 100] = 0.0
    return OccupancyGrid(prob, 0.05)


def test_path_goes_through_the_door_and_keeps_clear() -> None:
    cm = CostMap(_room_with_wall(), PlannerConfig(robot_radius=0.3, margin=0.05))
    path = cm.plan((1.0, 1.0), (9.0, 1.0))
    assert np.allclose(path[0], (1.0, 1.0), atol=0.1)
    assert np.allclose(path[-1], (9.0, 1.0))
    crossing = path[np.argmin(np.abs(path[:, 0] - 5.0))]
    assert 2.4 + 0.3 <= crossing[1] <= 3.6 - 0.3
    for p in path[1:-1]:
        assert cm.traversable(p)
    steps = np.hypot(*np.diff(path, axis=0).T)
    assert steps.max() < 0.2  # consecutive cells


def test_no_path_when_the_door_is_shut_or_blocked() -> None:
    with pytest.raises(NoPathError):
        CostMap(_room_with_wall(gap=False)).plan((1.0, 1.0), (9.0, 1.0))
    cm = CostMap(_room_with_wall())
    # people standing in the doorway
    crowd = np.array([[5.0, y] for y in np.arange(2.4, 3.61, 0.1)])
    with pytest.raises(NoPathError):
        cm.with_obstacles(crowd).plan((1.0, 1.0), (9.0, 1.0))
    cm.plan((1.0, 1.0), (9.0, 1.0))  # the original is unchanged


def test_invisible_obstacles_are_planned_around() -> None:
    grid = _room_with_wall()
    invisible = np.zeros(grid.shape, dtype=bool)
    invisible[30:120, 40:60] = True  # a long glass case from y = 1.5 m to the wall, x in [2, 3]
    cm = CostMap(grid, invisible=invisible)
    path = cm.plan((1.0, 3.0), (4.0, 3.0))
    assert path[:, 1].min() < 1.5 - 0.3
    plain = CostMap(grid).plan((1.0, 3.0), (4.0, 3.0))
    assert len(plain) < len(path)


def test_clearance_at_is_the_distance_to_the_nearest_blocked_cell_and_inf_off_the_map() -> None:
    cm = CostMap(_room_with_wall())
    d = cm.clearance_at([[3.0, 1.0], [5.0, 1.0], [25.0, 1.0], [-1.0, 2.0]])
    assert d[0] == pytest.approx(1.0, abs=cm.resolution * 1.5)  # the bottom wall, 1 m below
    assert d[1] == 0.0  # on the wall at x = 5 m
    assert np.isinf(d[2])
    assert np.isinf(d[3])
