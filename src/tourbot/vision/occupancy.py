"""The occupancy map of vision obstacles: log-odds per cell, in the frame of the site's grid
(Burgard et al., Sec. 3: the inconsistencies "accumulated in a 2D occupancy map")."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tourbot.maps.grid import OccupancyGrid

__all__ = ["VisionMap"]

FloatArray = NDArray[np.float64]


class VisionMap:
    """Log-odds of "an obstacle the laser misses stands here", on a grid of ``resolution`` over
    the site's grid (coarser than the laser's map: triangulated points scatter by centimetres).

    A view's triangulated inconsistencies add ``hit`` to each of their cells (once per view: two
    views make an obstacle), the floor points the images agree on add ``miss`` (negative) to
    theirs; values stay within ``[low, high]`` so that a visitor who stood still for a while is
    forgotten after a few views; cells above ``threshold`` are obstacles.
    """

    def __init__(
        self,
        site_grid: OccupancyGrid,
        resolution: float = 0.1,
        hit: float = 0.9,
        miss: float = -0.4,
        low: float = -2.0,
        high: float = 3.5,
        threshold: float = 1.5,
    ) -> None:
        rows = int(np.ceil(site_grid.shape[0] * site_grid.resolution / resolution))
        cols = int(np.ceil(site_grid.shape[1] * site_grid.resolution / resolution))
        frame = OccupancyGrid(np.zeros((rows, cols), dtype=np.float32), resolution, site_grid.origin)
        self.frame = frame
        self.log_odds = np.zeros(frame.shape, dtype=np.float32)
        self.seen = np.zeros(frame.shape, dtype=bool)
        self.floor_seen = np.zeros(frame.shape, dtype=bool)  # cells some view saw free floor in
        self.hit, self.miss, self.low, self.high, self.threshold = hit, miss, low, high, threshold
        self.version = 0

    def _add(self, points: FloatArray, value: float, weights: FloatArray | None = None) -> None:
        if not len(points):
            return
        cells = self.frame.world_to_cell(np.asarray(points, dtype=np.float64).reshape(-1, 2))
        ok = self.frame.inside(cells)
        # one view counts once per cell, however many of its pixels fall there: with the weight
        # of its most certain point in the cell
        uniq, inverse = np.unique(cells[ok], axis=0, return_inverse=True)
        r, c = uniq.T
        if weights is None:
            self.log_odds[r, c] += value
        else:
            w = np.zeros(len(uniq))
            np.maximum.at(w, inverse.reshape(-1), np.asarray(weights, dtype=np.float64).reshape(-1)[ok])
            self.log_odds[r, c] += (value * w).astype(np.float32)
        np.clip(self.log_odds, self.low, self.high, out=self.log_odds)
        self.seen[r, c] = True
        self.version += 1

    def update(
        self,
        obstacles: FloatArray,
        floor: FloatArray,
        obstacle_weights: FloatArray | None = None,
        floor_weights: FloatArray | None = None,
    ) -> None:
        """Add the hits at world points ``obstacles`` ``(K, 2)`` and misses at ``floor`` ``(F, 2)``.

        ``obstacle_weights`` ``(K,)`` and ``floor_weights`` ``(F,)`` in ``[0, 1]`` scale each
        point's ``hit`` or ``miss`` (default 1: full evidence): how sure the view is that the point
        lies where it is given (the pose's spread, see :mod:`tourbot.runtime.vision`).
        """
        if len(floor) and len(obstacles):
            # a view does not contradict itself: no free floor next to its own obstacle cells
            hits = self.frame.world_to_cell(np.asarray(obstacles, dtype=np.float64).reshape(-1, 2))
            fc = self.frame.world_to_cell(np.asarray(floor, dtype=np.float64).reshape(-1, 2))
            mark = np.zeros((self.frame.shape[0] + 2, self.frame.shape[1] + 2), dtype=bool)
            h = hits[self.frame.inside(hits)] + 1
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    mark[h[:, 0] + dr, h[:, 1] + dc] = True
            inside = self.frame.inside(fc)
            near = np.zeros(len(fc), dtype=bool)
            near[inside] = mark[fc[inside, 0] + 1, fc[inside, 1] + 1]
            floor = np.asarray(floor)[~near]
            if floor_weights is not None:
                floor_weights = np.asarray(floor_weights)[~near]
        self._add(floor, self.miss, floor_weights)
        self._add(obstacles, self.hit, obstacle_weights)
        if len(floor):
            cells = self.frame.world_to_cell(np.asarray(floor, dtype=np.float64).reshape(-1, 2))
            ok = self.frame.inside(cells)
            self.floor_seen[cells[ok, 0], cells[ok, 1]] = True

    def clear(self, centre: FloatArray, radius: float) -> None:
        """Forget the obstacles within ``radius`` of ``centre``: where the robot stands is free."""
        f = self.frame
        k = int(np.ceil(radius / f.resolution))
        rc = f.world_to_cell(np.asarray(centre, dtype=np.float64)[:2])
        r0, r1 = max(int(rc[0]) - k, 0), min(int(rc[0]) + k + 1, f.shape[0])
        c0, c1 = max(int(rc[1]) - k, 0), min(int(rc[1]) + k + 1, f.shape[1])
        if r0 >= r1 or c0 >= c1:
            return
        rr, cc = np.mgrid[r0:r1, c0:c1]
        xy = f.cell_to_world(np.stack([rr, cc], axis=-1))
        inside = np.hypot(xy[..., 0] - centre[0], xy[..., 1] - centre[1]) <= radius
        block = self.log_odds[r0:r1, c0:c1]
        if (block[inside] > self.low).any():
            block[inside] = np.minimum(block[inside], self.low)
            self.version += 1

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
