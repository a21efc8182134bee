"""How well a map agrees with a reference map: precision and recall of occupied cells.

Both maps in the same world frame; a cell agrees when an occupied cell of the other map lies within
a tolerance (10 cm in the benchmarks), as in the map comparisons of Kummerle et al. 2009.

A SLAM map is defined up to a rigid motion (the gauge of the pose graph: the benchmarks hold the
first pose at the reference's first pose, so a map whose first steps turned by a degree is
compared turned by a degree everywhere). :func:`register_map` finds the rigid motion that lays a
map onto the reference (trimmed point-to-point ICP on the occupied cells, Besl and McKay 1992,
with the closed-form SE(2) step of Umeyama 1991), and :func:`map_agreement` takes it as
``transform``: the agreement of the map's shape, whatever frame it was drawn in.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from tourbot.geometry import compose, invert, transform_points
from tourbot.maps.grid import OccupancyGrid

__all__ = ["map_agreement", "occupied_distance", "register_map"]

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


def map_agreement(
    grid: OccupancyGrid,
    reference: OccupancyGrid,
    tolerance: float = 0.1,
    transform: FloatArray | None = None,
) -> dict[str, float]:
    """Precision and recall of ``grid``'s occupied cells against ``reference``'s, within ``tolerance`` m.

    Both maps must be in the same world frame, or ``transform`` (``x, y, theta``) takes ``grid``'s
    frame onto ``reference``'s (:func:`register_map`). Precision: the fraction of ``grid``'s
    occupied cells within ``tolerance`` of an occupied reference cell; recall: the converse.
    """
    t = np.zeros(3) if transform is None else np.asarray(transform, dtype=np.float64)
    mine = transform_points(t, grid.cell_to_world(np.argwhere(grid.occupied())))
    theirs = transform_points(invert(t), reference.cell_to_world(np.argwhere(reference.occupied())))
    precision = float(np.mean(_distance_at(reference, occupied_distance(reference), mine) <= tolerance))
    recall = float(np.mean(_distance_at(grid, occupied_distance(grid), theirs) <= tolerance))
    return {"precision": precision, "recall": recall}


def _icp(mine: FloatArray, theirs: FloatArray, trims: tuple[float, ...], iterations: int) -> FloatArray:
    """Trimmed point-to-point ICP of ``mine`` onto ``theirs`` from no motion."""
    from scipy.spatial import cKDTree

    t = np.zeros(3)
    tree = cKDTree(theirs)
    for trim in trims:
        for _ in range(iterations):
            moved = transform_points(t, mine)
            dist, idx = tree.query(moved, distance_upper_bound=trim)
            keep = np.isfinite(dist)
            if keep.sum() < 3:
                break
            p, q = moved[keep], theirs[idx[keep]]
            mp, mq = p.mean(axis=0), q.mean(axis=0)
            h = (p - mp).T @ (q - mq)
            angle = float(np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
            c, s = np.cos(angle), np.sin(angle)
            shift = mq - np.array([[c, -s], [s, c]]) @ mp
            t = compose(np.array([shift[0], shift[1], angle]), t)
            if abs(angle) < 1e-7 and float(np.hypot(*(mq - mp))) < 1e-6:
                break
    return t


def register_map(
    grid: OccupancyGrid,
    reference: OccupancyGrid,
    tolerance: float = 0.1,
    schedules: tuple[tuple[float, ...], ...] = ((1.0, 0.5, 0.3, 0.2, 0.1), (0.3, 0.2, 0.1)),
    iterations: int = 10,
) -> FloatArray:
    """The rigid motion ``x, y, theta`` that lays ``grid``'s occupied cells onto ``reference``'s.

    Point-to-point ICP (Besl and McKay 1992): each occupied cell of ``grid`` is paired with the
    nearest occupied reference cell, pairs farther apart than the current trim distance are left
    out (a wall only one map has does not pull), and the motion that best fits the pairs is
    solved in closed form (Umeyama 1991, no scale); the trim shrinks through a schedule (m),
    ``iterations`` steps each. One run per schedule in ``schedules`` (a wide one that can undo a
    turned map, a narrow one that stays near the frame it was drawn in: on a map bent by drift
    the least-squares fit of the whole is not the motion under which most of it agrees); of
    those motions and no motion at all, the one with the highest precision plus recall within
    ``tolerance`` is returned.
    """
    mine = grid.cell_to_world(np.argwhere(grid.occupied()))
    theirs = reference.cell_to_world(np.argwhere(reference.occupied()))
    candidates = [np.zeros(3)]
    if len(mine) >= 3 and len(theirs) >= 3:
        candidates += [_icp(mine, theirs, trims, iterations) for trims in schedules]

    def agreement(t: FloatArray) -> float:
        a = map_agreement(grid, reference, tolerance, transform=t)
        return a["precision"] + a["recall"]

    return max(candidates, key=agreement)
