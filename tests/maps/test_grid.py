from __future__ import annotations

import numpy as np
import pytest

from tourbot.maps.grid import MapError, OccupancyGrid


def test_world_cell_roundtrip_with_yaw() -> None:
    grid = OccupancyGrid(np.zeros((20, 30), np.float32), 0.1, origin=(1.0, -2.0, 0.3))
    cells = np.array([[0, 0], [5, 7], [19, 29]])
    back = grid.world_to_cell(grid.cell_to_world(cells))
    assert np.array_equal(back, cells)


def test_masks() -> None:
    prob = np.array([[-1.0, 0.0, 1.0]], np.float32)
    grid = OccupancyGrid(prob, 0.05)
    assert grid.unknown().tolist() == [[True, False, False]]
    assert grid.free().tolist() == [[False, True, False]]
    assert grid.occupied().tolist() == [[False, False, True]]


def test_bad_grid() -> None:
    with pytest.raises(MapError, match="2D"):
        OccupancyGrid(np.zeros(3, np.float32), 0.05)
    with pytest.raises(MapError, match="resolution"):
        OccupancyGrid(np.zeros((3, 3), np.float32), 0.0)
