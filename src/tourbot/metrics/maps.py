"""How well a map agrees with a reference map: precision and recall of occupied cells.

Both maps in the same world frame; a cell agrees when an occupied cell of the other map lies within
a tolerance (10 cm in the benchmarks), as in the map comparisons of Kummerle et al. 2009.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from tourbot.maps.grid import OccupancyGrid

__all__ = ["map_agreement", "occupied_distance"]

FloatArray = NDArray[np.float64]


def occupied_distance(grid: OccupancyGrid) -> FloatArray:
    """Distance (m) from each cell of ``grid`` to its nearest occupied cell."""
    return np.asarray(ndimage.distance_transform_edt(~grid.occupied()) * grid.resolution)


def _distance_at(grid: OccupancyGrid, dist: FloatArray, points: FloatArray) -> FloatArray:
    cells = grid.world_to_cell(points)
    inside = grid.inside(cells)
    out = np.full(len(points), np.inf)
    out[inside] = dist[cells[inside, 0], cells[inside, 1]]
    return out


def map_agreement(grid: OccupancyGrid, reference: OccupancyGrid, tolerance: float = 0.1) -> dict[str, float]:
    """Precision and recall of ``grid``'s occupied cells against ``reference``'s, within ``tolerance`` m.

    Both maps must be in the same world frame. Precision: the fraction of ``grid``'s occupied cells
    within ``tolerance`` of an occupied reference cell; recall: the converse.
    """
    mine = grid.cell_to_world(np.argwhere(grid.occupied()))
    theirs = reference.cell_to_world(np.argwhere(reference.occupied()))
    precision = float(np.mean(_distance_at(reference, occupied_distance(reference), mine) <= tolerance))
    recall = float(np.mean(_distance_at(grid, occupied_distance(grid), theirs) <= tolerance))
    return {"precision": precision, "recall": recall}
