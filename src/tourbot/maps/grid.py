"""The occupancy grid: a probability of occupancy per cell, with world <-> cell transforms.

Convention (the ROS map_server one, after loading): ``prob[row, col]``, row index growing with y
and column index with x in the grid frame; the grid frame is the pose ``origin = (x, y, yaw)`` of
the corner of cell ``(0, 0)`` in the world. Cell ``(r, c)`` covers ``[c, c+1) x [r, r+1)`` cells
of ``resolution`` metres. ``prob`` is float32 in [0, 1], and ``UNKNOWN`` (-1) where nothing is
known.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.errors import TourbotError
from tourbot.geometry import compose, invert, transform_points

__all__ = ["UNKNOWN", "MapError", "OccupancyGrid"]

UNKNOWN = -1.0


class MapError(TourbotError):
    """A map that is malformed or does not fit the request."""


@dataclass
class OccupancyGrid:
    """Occupancy probabilities on a regular grid, placed in the world by ``origin``."""

    prob: NDArray[np.float32]
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196

    def __post_init__(self) -> None:
        self.prob = np.ascontiguousarray(self.prob, dtype=np.float32)
        if self.prob.ndim != 2 or self.prob.size == 0:
            raise MapError(f"an occupancy grid needs a non-empty 2D array, got shape {self.prob.shape}")
        if not self.resolution > 0:
            raise MapError(f"resolution must be positive, got {self.resolution}")
        self.origin = (float(self.origin[0]), float(self.origin[1]), float(self.origin[2]))

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)``."""
        return (int(self.prob.shape[0]), int(self.prob.shape[1]))

    @property
    def width(self) -> float:
        """Extent along the grid's x axis, metres."""
        return self.prob.shape[1] * self.resolution

    @property
    def height(self) -> float:
        """Extent along the grid's y axis, metres."""
        return self.prob.shape[0] * self.resolution

    def occupied(self) -> NDArray[np.bool_]:
        """Cells whose probability exceeds ``occupied_thresh``."""
        return self.prob > self.occupied_thresh

    def free(self) -> NDArray[np.bool_]:
        """Known cells whose probability is below ``free_thresh``."""
        return (self.prob >= 0.0) & (self.prob < self.free_thresh)

    def unknown(self) -> NDArray[np.bool_]:
        return self.prob < 0.0

    def world_to_grid(self, poses: ArrayLike) -> NDArray[np.float64]:
        """Poses ``(..., 3)`` from the world frame to the grid frame (metres, radians)."""
        return compose(invert(self.origin), np.asarray(poses, dtype=np.float64))

    def grid_to_world(self, poses: ArrayLike) -> NDArray[np.float64]:
        """Poses ``(..., 3)`` from the grid frame to the world frame."""
        return compose(self.origin, np.asarray(poses, dtype=np.float64))

    def world_to_cell(self, points: ArrayLike) -> NDArray[np.int64]:
        """Points ``(..., 2)`` in the world to integer ``(row, col)`` indices (may be outside)."""
        pts = np.asarray(points, dtype=np.float64)
        local = transform_points(invert(self.origin), pts)
        cols = np.floor(local[..., 0] / self.resolution).astype(np.int64)
        rows = np.floor(local[..., 1] / self.resolution).astype(np.int64)
        return np.stack([rows, cols], axis=-1)

    def cell_to_world(self, cells: ArrayLike) -> NDArray[np.float64]:
        """Centres of ``(row, col)`` cells ``(..., 2)`` as world points ``(..., 2)``."""
        rc = np.asarray(cells, dtype=np.float64)
        res = self.resolution
        local = np.stack([(rc[..., 1] + 0.5) * res, (rc[..., 0] + 0.5) * res], axis=-1)
        return transform_points(self.origin, local)

    def inside(self, cells: ArrayLike) -> NDArray[np.bool_]:
        """Whether ``(row, col)`` indices ``(..., 2)`` fall inside the grid."""
        rc = np.asarray(cells)
        rows, cols = self.shape
        return (rc[..., 0] >= 0) & (rc[..., 0] < rows) & (rc[..., 1] >= 0) & (rc[..., 1] < cols)

    def free_cell_centres(self) -> NDArray[np.float64]:
        """World coordinates ``(K, 2)`` of the centres of all free cells (for global localization)."""
        rc = np.argwhere(self.free())
        return self.cell_to_world(rc)
