"""The global planner: Dijkstra's cost-to-go on the map inflated by the robot's radius.

The static occupancy grid (and the site's invisible obstacles: glass cases, low tables the laser
cannot see) is reduced to the planner's resolution, every cell closer to an obstacle than the
robot's radius plus a margin is forbidden (the configuration space of a round robot), and free
cells cost more near obstacles so paths keep to the middle of aisles. Dijkstra's algorithm from the
goal (:func:`tourbot.maps.dijkstra.grid_dijkstra`) gives every cell's cost-to-go (the navigation
function of Latombe 1991, as used by the museum robots' planners: value iteration in Burgard et al.
1999); the path from any start follows its steepest descent, so replanning from a new pose is just
a descent. Temporary obstacles (people blocking an aisle, a closed door) can be added for one
replanning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from tourbot.errors import TourbotError
from tourbot.maps.dijkstra import grid_dijkstra
from tourbot.maps.grid import OccupancyGrid

__all__ = ["CostMap", "NoPathError", "PlannerConfig"]

FloatArray = NDArray[np.float64]


class NoPathError(TourbotError):
    """The goal cannot be reached on the map."""


@dataclass(frozen=True)
class PlannerConfig:
    """Planner parameters: resolution of the planning grid, inflation and clearance cost.

    A cell is forbidden closer than ``robot_radius + margin`` to an obstacle; within ``comfort`` of
    an obstacle its cost grows linearly up to ``1 + clearance_weight``.
    """

    resolution: float = 0.1
    robot_radius: float = 0.3
    margin: float = 0.08
    comfort: float = 0.8
    clearance_weight: float = 4.0
    unknown_blocks: bool = True


@numba.njit(cache=True)
def _descend(field: NDArray[np.float64], r: int, c: int, max_steps: int) -> NDArray[np.int64]:
    """Cells from ``(r, c)`` down the cost-to-go to its zero (the goal), steepest neighbour each step."""
    rows, cols = field.shape
    out = np.empty((max_steps + 1, 2), dtype=np.int64)
    out[0, 0] = r
    out[0, 1] = c
    k = 1
    while k <= max_steps and field[r, c] > 0.0:
        best = field[r, c]
        br, bc = r, c
        for dr in range(-1, 2):
            for dc in range(-1, 2):
                nr, nc = r + dr, c + dc
                if 0 <= nr < rows and 0 <= nc < cols and field[nr, nc] < best:
                    best = field[nr, nc]
                    br, bc = nr, nc
        if br == r and bc == c:
            break
        r, c = br, bc
        out[k, 0] = r
        out[k, 1] = c
        k += 1
    return out[:k]


class CostMap:
    """The planning grid of a map: forbidden cells (inf) and clearance costs, at ``config.resolution``."""

    def __init__(
        self,
        grid: OccupancyGrid,
        config: PlannerConfig | None = None,
        invisible: NDArray[np.bool_] | None = None,
    ) -> None:
        self.config = cfg = config or PlannerConfig()
        factor = max(1, round(cfg.resolution / grid.resolution))
        self.resolution = grid.resolution * factor
        blocked = grid.occupied()
        if cfg.unknown_blocks:
            blocked = blocked | grid.unknown()
        if invisible is not None:
            blocked = blocked | invisible
        self.blocked = _max_pool(blocked, factor)
        self.origin = grid.origin
        self._frame = OccupancyGrid(np.zeros(self.blocked.shape, np.float32), self.resolution, grid.origin)
        self.clearance = self._clearance(self.blocked)
        self.cost = self._cost(self.clearance)
        self._fields: dict[tuple[int, int], FloatArray] = {}

    @property
    def shape(self) -> tuple[int, int]:
        return self._frame.shape

    def _clearance(self, blocked: NDArray[np.bool_]) -> FloatArray:
        if not blocked.any():
            return np.full(blocked.shape, np.inf)
        return np.asarray(ndimage.distance_transform_edt(~blocked), dtype=np.float64) * self.resolution

    def _cost(self, clearance: FloatArray) -> FloatArray:
        cfg = self.config
        inner = cfg.robot_radius + cfg.margin
        extra = np.clip((cfg.comfort - clearance) / max(cfg.comfort - inner, 1e-6), 0.0, 1.0)
        cost = 1.0 + cfg.clearance_weight * extra
        return np.where(clearance < inner, np.inf, cost)

    def cell(self, xy: ArrayLike) -> tuple[int, int]:
        r, c = self._frame.world_to_cell(np.asarray(xy, dtype=np.float64)[:2])
        return int(r), int(c)

    def traversable(self, xy: ArrayLike) -> bool:
        r, c = self.cell(xy)
        return bool(self._frame.inside(np.array([r, c])) and np.isfinite(self.cost[r, c]))

    def clearance_at(self, points: ArrayLike) -> FloatArray:
        """The distance (m) from each world point ``(K, 2)`` to the nearest blocked cell; ``inf``
        for a point off the map."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        cells = self._frame.world_to_cell(pts)
        ok = self._frame.inside(cells)
        out = np.full(len(pts), np.inf)
        out[ok] = self.clearance[cells[ok, 0], cells[ok, 1]]
        return out

    def with_obstacles(self, points: ArrayLike) -> CostMap:
        """A copy where the cells of ``points`` (world, ``(K, 2)``: people seen blocking the way, a
        closed door) are obstacles too, inflated like the map's."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        new = object.__new__(CostMap)
        new.config, new.resolution, new.origin, new._frame = (
            self.config,
            self.resolution,
            self.origin,
            self._frame,
        )
        new._fields = {}
        blocked = self.blocked.copy()
        cells = self._frame.world_to_cell(pts)
        ok = self._frame.inside(cells)
        blocked[cells[ok, 0], cells[ok, 1]] = True
        new.blocked = blocked
        new.clearance = new._clearance(blocked)
        new.cost = new._cost(new.clearance)
        return new

    def field(self, goal: ArrayLike) -> FloatArray:
        """The cost-to-go to ``goal`` (world x, y), cached per goal cell."""
        r, c = self._snap(self.cell(goal))
        key = (r, c)
        if key not in self._fields:
            self._fields[key] = grid_dijkstra(self.cost, r, c)
        return self._fields[key]

    def plan(self, start: ArrayLike, goal: ArrayLike) -> FloatArray:
        """A path ``(K, 2)`` of world points from ``start`` to ``goal``; NoPathError when none."""
        field = self.field(goal)
        r, c = self._snap(self.cell(start), field)
        if not np.isfinite(field[r, c]):
            s, g = np.asarray(start, dtype=np.float64), np.asarray(goal, dtype=np.float64)
            raise NoPathError(f"no path from ({s[0]:.2f}, {s[1]:.2f}) to ({g[0]:.2f}, {g[1]:.2f})")
        cells = _descend(field, r, c, field.size)
        pts = self._frame.cell_to_world(cells.astype(np.float64))
        pts[-1] = np.asarray(goal, dtype=np.float64)[:2]
        return pts

    def _snap(self, rc: tuple[int, int], field: FloatArray | None = None) -> tuple[int, int]:
        """The nearest cell to ``rc`` that is traversable (and reachable on ``field``), within 1 m."""
        ok = np.isfinite(self.cost) if field is None else np.isfinite(field)
        r, c = rc
        rows, cols = ok.shape
        if 0 <= r < rows and 0 <= c < cols and ok[r, c]:
            return r, c
        reach = max(1, round(1.0 / self.resolution))
        r0, r1 = max(0, r - reach), min(rows, r + reach + 1)
        c0, c1 = max(0, c - reach), min(cols, c + reach + 1)
        sub = np.argwhere(ok[r0:r1, c0:c1])
        if len(sub) == 0:
            return min(max(r, 0), rows - 1), min(max(c, 0), cols - 1)
        d = (sub[:, 0] + r0 - r) ** 2 + (sub[:, 1] + c0 - c) ** 2
        k = int(np.argmin(d))
        return int(sub[k, 0] + r0), int(sub[k, 1] + c0)


def _max_pool(mask: NDArray[np.bool_], factor: int) -> NDArray[np.bool_]:
    if factor == 1:
        return mask.copy()
    rows = math.ceil(mask.shape[0] / factor) * factor
    cols = math.ceil(mask.shape[1] / factor) * factor
    padded = np.zeros((rows, cols), dtype=bool)
    padded[: mask.shape[0], : mask.shape[1]] = mask
    blocks = padded.reshape(rows // factor, factor, cols // factor, factor)
    return np.asarray(blocks.any(axis=(1, 3)), dtype=bool)
