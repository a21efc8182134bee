"""The occupancy map of vision obstacles: log-odds per cell, in the frame of the site's grid
(Burgard et al., Sec. 3: the inconsistencies "accumulated in a 2D occupancy map")."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tourbot.maps.grid import OccupancyGrid

__all__ = ["VisionMap"]

FloatArray = NDArray[np.float64]


class VisionMap:
    """Log-odds of "an obstacle the laser misses stands here", per cell of ``frame``'s grid.

    A triangulated inconsistency adds ``hit`` to its cell, a floor point the images agree on adds
    ``miss`` (negative) to its own; values stay within ``[low, high]`` so that a visitor who
    stood still for a while is forgotten after a few views; cells above ``threshold`` are
    obstacles.
    """

    def __init__(
        self,
        frame: OccupancyGrid,
        hit: float = 0.9,
        miss: float = -0.4,
        low: float = -2.0,
        high: float = 3.5,
        threshold: float = 1.5,
    ) -> None:
        self.frame = frame
        self.log_odds = np.zeros(frame.shape, dtype=np.float32)
        self.seen = np.zeros(frame.shape, dtype=bool)
        self.hit, self.miss, self.low, self.high, self.threshold = hit, miss, low, high, threshold
        self.version = 0

    def _add(self, points: FloatArray, value: float) -> None:
        if not len(points):
            return
        cells = self.frame.world_to_cell(np.asarray(points, dtype=np.float64).reshape(-1, 2))
        ok = self.frame.inside(cells)
        r, c = cells[ok, 0], cells[ok, 1]
        np.add.at(self.log_odds, (r, c), value)
        np.clip(self.log_odds, self.low, self.high, out=self.log_odds)
        self.seen[r, c] = True
        self.version += 1

    def update(self, obstacles: FloatArray, floor: FloatArray) -> None:
        """Add the hits at world points ``obstacles`` ``(K, 2)`` and misses at ``floor`` ``(F, 2)``."""
        self._add(floor, self.miss)
        self._add(obstacles, self.hit)

    def occupied(self) -> NDArray[np.bool_]:
        return self.log_odds > self.threshold

    def obstacle_points(self) -> FloatArray:
        """World centres ``(K, 2)`` of the obstacle cells."""
        cells = np.argwhere(self.occupied())
        return self.frame.cell_to_world(cells) if len(cells) else np.zeros((0, 2))

    def grid(self) -> OccupancyGrid:
        """The map as an occupancy grid: probabilities where seen, unknown (0.5) elsewhere."""
        prob = 1.0 / (1.0 + np.exp(-self.log_odds.astype(np.float64)))
        prob[self.seen & (self.log_odds <= self.threshold) & (self.log_odds <= 0)] = 0.0
        prob[self.occupied()] = 1.0
        prob[~self.seen] = 0.5
        f = self.frame
        return OccupancyGrid(prob.astype(np.float32), f.resolution, f.origin)
