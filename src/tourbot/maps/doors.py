"""Doorways suggested from an occupancy grid: gaps of a door's width in straight walls.

A doorway is two occupied cells ``a`` and ``b`` a door's width apart (0.7-1.2 m) with known free
space all along the segment between them and across it (a passage: free cells half a metre to
each side of its middle), and wall continuing beyond both ends in line with the gap (occupied
cells just past ``a`` and ``b``). Candidates closer than ``spacing`` to a better one (narrower)
are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage
from scipy.spatial import cKDTree

from tourbot.maps.grid import OccupancyGrid

__all__ = ["Doorway", "suggest_doorways"]


@dataclass(frozen=True)
class Doorway:
    """A gap from ``a`` to ``b`` (world points) in a wall."""

    a: tuple[float, float]
    b: tuple[float, float]

    @property
    def width(self) -> float:
        return float(np.hypot(self.b[0] - self.a[0], self.b[1] - self.a[1]))


def _state(grid: OccupancyGrid, pts: NDArray[np.float64], near_occ: NDArray[np.bool_]) -> NDArray[np.int8]:
    """0 free, 1 (near) occupied, 2 unknown or outside, at world ``pts`` ``(..., 2)``."""
    cells = grid.world_to_cell(pts)
    inside = grid.inside(cells)
    out = np.full(pts.shape[:-1], 2, np.int8)
    r, c = cells[..., 0][inside], cells[..., 1][inside]
    known = grid.prob[r, c] >= 0.0
    out[inside] = np.where(near_occ[r, c], 1, np.where(known, 0, 2))
    return out


def suggest_doorways(
    grid: OccupancyGrid,
    min_width: float = 0.7,
    max_width: float = 1.2,
    spacing: float = 1.0,
    stride: int = 2,
) -> list[Doorway]:
    """Doorways of ``grid`` (see the module docstring), narrowest first within each place."""
    occ = grid.occupied()
    near_occ = np.asarray(ndimage.binary_dilation(occ, iterations=1))
    cells = np.argwhere(occ)[::stride]
    if len(cells) < 2:
        return []
    pts = grid.cell_to_world(cells)
    pairs = np.asarray(sorted(cKDTree(pts).query_pairs(max_width)), dtype=np.int64).reshape(-1, 2)
    a, b = pts[pairs[:, 0]], pts[pairs[:, 1]]
    width = np.hypot(*(b - a).T)
    keep = width >= min_width
    a, b, width = a[keep], b[keep], width[keep]
    if len(a) == 0:
        return []
    u = (b - a) / width[:, None]
    normal = np.stack([-u[:, 1], u[:, 0]], axis=1)
    res = grid.resolution
    # free all along the gap (leaving out three cells at each end: the walls there are dilated)
    t = np.linspace(0.0, 1.0, 25)[None, :, None]
    inner_a = a + u * (3.0 * res)
    inner_b = b - u * (3.0 * res)
    along = inner_a[:, None, :] + t * (inner_b - inner_a)[:, None, :]
    ok = np.all(_state(grid, along, near_occ) == 0, axis=1)
    # a passage across its middle, and wall beyond both ends in line with the gap
    mid = 0.5 * (a + b)
    for side in (-0.5, 0.5, -0.25, 0.25):
        ok &= _state(grid, mid + side * normal, near_occ) == 0
    for reach in (0.15, 0.3):
        ok &= _state(grid, a - reach * u, near_occ) == 1
        ok &= _state(grid, b + reach * u, near_occ) == 1
    found: list[Doorway] = []
    centres: list[NDArray[np.float64]] = []
    for k in np.argsort(width[ok], kind="stable"):
        i = np.flatnonzero(ok)[k]
        if any(np.hypot(*(mid[i] - c)) < spacing for c in centres):
            continue
        centres.append(mid[i])
        found.append(Doorway((float(a[i, 0]), float(a[i, 1])), (float(b[i, 0]), float(b[i, 1]))))
    return found
