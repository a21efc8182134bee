"""Static objects that look like legs, filtered out (Burgard et al., Sec. 4 and Fig. 6).

"To distinguish these static objects from moving people our system additionally considers the
differences between occupancy probability grids built from consecutive scans." A leg feature sits
in a cell the current scan sees occupied; the difference map at that cell is ``P_now(occ) -
P_prev(occ)``, where the previous scan's occupancy comes from the inverse sensor model of the beam
that crossed the cell: free when the beam went through it, occupied when it ended there, unknown
(0.5) when the cell was hidden or out of view. A chair leg gives ~0; a walking person's leg, where
the floor was free a moment ago, gives ~``p_occupied - p_free``. The grids are evaluated only at the
features' cells (the only cells the fusion of Fig. 6 reads), not rasterised whole.

With a map, features on or right beside its occupied cells are furniture, not people.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from tourbot.maps.grid import OccupancyGrid
from tourbot.people.occlusion import points_in_sensor_frame
from tourbot.records import Scan

__all__ = ["RobotBodyMask", "StaticConfig", "StaticFilter", "previous_occupancy"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class StaticConfig:
    """``lag``: compare with the previous scan (the paper's consecutive scans) and with the scan
    ``lag`` scans back, keeping the stronger evidence of motion (5 at 10 Hz also catches people
    walking slowly, whose legs move only a few centimetres between consecutive scans);
    ``tolerance``: how close (m) a previous return must be to call the cell occupied then;
    ``p_free`` / ``p_occupied``: the inverse sensor model's values; ``map_clearance``: features
    within this distance (m) of an occupied map cell are static.

    The robot's own body seen by the laser (at the edges of a 270-degree field of view, a bumper or
    a mast) moves with the robot: in the world frame it walks. Leg detections are counted per
    ``body_cell`` (m) of the laser frame over the scans at which the robot had moved
    ``body_min_motion`` (m, or that many radians) since the last counted one, with an exponential
    memory of ``body_memory`` such scans; a cell detected at least ``body_count`` times and in at
    least ``body_rate`` of them is the robot's body. (A robot standing still teaches nothing: a
    person standing beside it is fixed in the laser frame too; a person walking along with a
    moving robot in the same 10 cm cell for 15 scans, about 2 s, is rare.)"""

    lag: int = 5
    tolerance: float = 0.08
    body_cell: float = 0.1
    body_rate: float = 0.1
    body_count: float = 15.0
    body_memory: int = 200
    body_min_motion: float = 0.05
    p_free: float = 0.1
    p_occupied: float = 0.9
    map_clearance: float = 0.15
    max_range: float = 8.0


def previous_occupancy(
    points_sensor: FloatArray,
    ranges: FloatArray,
    angle_min: float,
    angle_increment: float,
    cfg: StaticConfig,
    min_range: float = 0.0,
) -> FloatArray:
    """P(occupied) of points ``(P, 2)`` (in the earlier scan's laser frame) by that scan's beams.

    The nearest beam and its two neighbours are read, so a small change of bearing between the
    scans (the robot moved) still finds a return from the same surface. A cell counts as free only
    when all three beams returned (beyond ``min_range``) from behind it: a beam with no reading
    (lasers report 0 for a dropout) might have ended on it.
    """
    B = ranges.shape[0]
    d = np.hypot(points_sensor[:, 0], points_sensor[:, 1])
    idx = np.rint((np.arctan2(points_sensor[:, 1], points_sensor[:, 0]) - angle_min) / angle_increment)
    idx = idx.astype(np.int64)
    inside = (idx >= 0) & (idx < B) & (d <= cfg.max_range)
    window = np.clip(idx[:, None] + np.arange(-1, 2)[None, :], 0, B - 1)
    r = ranges[window]
    # A reading of 0 (or below the laser's minimum, or NaN) is no reading: the beam may have
    # ended anywhere, so it says nothing; +inf (nothing within range) went through.
    read = ~np.isnan(r) & (r > min_range)
    gap = np.where(read, r - d[:, None], np.nan)  # >0: beam ended behind the point
    hit = (np.abs(gap) <= cfg.tolerance).any(axis=1)
    through = (read & (gap > cfg.tolerance)).all(axis=1)
    p = np.full(points_sensor.shape[0], 0.5)
    p[through] = cfg.p_free
    p[hit] = cfg.p_occupied
    p[~inside] = 0.5
    return p


class StaticFilter:
    """P(moving) of leg features from the difference of occupancy grids of recent scans.

    Feed every scan through :meth:`moving_probability` in order; the first scans (no history yet)
    get 0.5, "unknown".
    """

    def __init__(self, config: StaticConfig | None = None, grid_map: OccupancyGrid | None = None) -> None:
        self.config = config or StaticConfig()
        self._history: deque[tuple[Scan, FloatArray]] = deque(maxlen=max(self.config.lag, 1))
        self._map = grid_map
        self._near_map: NDArray[np.bool_] | None = None
        if grid_map is not None:
            cells = max(math.ceil(self.config.map_clearance / grid_map.resolution), 0)
            occ = grid_map.occupied()
            self._near_map = ndimage.binary_dilation(occ, iterations=cells) if cells > 0 else occ

    @property
    def has_map(self) -> bool:
        return self._map is not None

    def on_map(self, world_points: FloatArray) -> NDArray[np.bool_]:
        """Whether points lie on or beside an occupied cell of the map (all False without a map)."""
        if self._map is None or self._near_map is None or world_points.shape[0] == 0:
            return np.zeros(world_points.shape[0], dtype=bool)
        cells = self._map.world_to_cell(world_points)
        inside = self._map.inside(cells)
        out = np.zeros(world_points.shape[0], dtype=bool)
        c = cells[inside]
        out[inside] = self._near_map[c[:, 0], c[:, 1]]
        return out

    def moving_probability(self, world_points: FloatArray, scan: Scan, robot_pose: FloatArray) -> FloatArray:
        """P(moving) of leg features at ``world_points`` ``(M, 2)`` seen in ``scan`` at ``robot_pose``.

        The difference map ``P_now - P_prev`` at each feature's cell, rescaled to [0, 1]
        (``P_now = p_occupied``: the feature is a return of the current scan), the largest over the
        previous scan and the one ``lag`` back; 0.5 ("unknown") before any history; 0 on the map.
        """
        cfg = self.config
        pose = np.asarray(robot_pose, dtype=np.float64)
        out = np.full(world_points.shape[0], 0.5)
        if self._history and world_points.shape[0]:
            out[:] = 0.0
            earlier = (
                [self._history[-1]] if len(self._history) == 1 else [self._history[-1], self._history[0]]
            )
            for prev_scan, prev_pose in earlier:
                local = points_in_sensor_frame(world_points, prev_pose, prev_scan)
                g = prev_scan.geometry
                p_prev = previous_occupancy(
                    local,
                    np.asarray(prev_scan.ranges, float),
                    g.angle_min,
                    g.angle_increment,
                    cfg,
                    g.min_range,
                )
                diff = np.clip((cfg.p_occupied - p_prev) / (cfg.p_occupied - cfg.p_free), 0.0, 1.0)
                out = np.maximum(out, diff)
        out[self.on_map(world_points)] = 0.0
        self._history.append((scan, pose.copy()))
        return out


class RobotBodyMask:
    """Leg detections fixed in the laser frame while the robot moves are the robot's own body.

    The robot's pose only tells whether it moved; no map is needed. See :class:`StaticConfig`.
    """

    def __init__(self, config: StaticConfig | None = None) -> None:
        self.config = config or StaticConfig()
        self._count: dict[tuple[int, int], float] = {}
        self._total = 0.0
        self._last: FloatArray | None = None

    def _cells(self, laser_points: FloatArray) -> list[tuple[int, int]]:
        c = np.floor(laser_points / self.config.body_cell).astype(np.int64)
        return [(int(a), int(b)) for a, b in c]

    def is_body(self, laser_points: FloatArray) -> NDArray[np.bool_]:
        """Which detections ``(M, 2)`` (laser frame) lie on the robot's body, as learned so far."""
        cfg = self.config
        cells = self._cells(np.asarray(laser_points, dtype=np.float64).reshape(-1, 2))
        floor = max(cfg.body_count, cfg.body_rate * self._total)
        return np.array([self._count.get(c, 0.0) >= floor for c in cells], dtype=bool)

    def learn(self, laser_points: FloatArray, robot_pose: FloatArray) -> None:
        """Count the detections of a scan taken at ``robot_pose`` if the robot moved since the last."""
        cfg = self.config
        pose = np.asarray(robot_pose, dtype=np.float64)
        if self._last is not None:
            turn = abs(math.remainder(float(pose[2] - self._last[2]), math.tau))
            if max(float(np.hypot(*(pose[:2] - self._last[:2]))), turn) < cfg.body_min_motion:
                return
        self._last = pose.copy()
        decay = 1.0 - 1.0 / max(cfg.body_memory, 1)
        self._total = self._total * decay + 1.0
        seen = set(self._cells(np.asarray(laser_points, dtype=np.float64).reshape(-1, 2)))
        for c in list(self._count):
            self._count[c] *= decay
            if self._count[c] < 0.5 and c not in seen:
                del self._count[c]
        for c in seen:
            self._count[c] = self._count.get(c, 0.0) + 1.0
