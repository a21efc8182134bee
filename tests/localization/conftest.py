"""Synthetic worlds for the localization tests: a room with boxes, a robot driving in it, its scans."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from tourbot.geometry import compose, relative
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import LaserGeometry, Scan

RESOLUTION = 0.05
GEOMETRY = LaserGeometry(num_beams=180, angle_min=-math.pi / 2, angle_increment=math.pi / 179, max_range=20.0)


def room_with_boxes() -> OccupancyGrid:
    """A 12 m x 9 m room with walls and asymmetric boxes, 5 cm cells, offset origin."""
    rows, cols = int(9 / RESOLUTION), int(12 / RESOLUTION)
    prob = np.zeros((rows, cols), np.float32)
    w = 3
    prob[:w, :] = prob[-w:, :] = 1.0
    prob[:, :w] = prob[:, -w:] = 1.0

    def box(x0: float, y0: float, x1: float, y1: float) -> None:
        prob[int(y0 / RESOLUTION) : int(y1 / RESOLUTION), int(x0 / RESOLUTION) : int(x1 / RESOLUTION)] = 1.0

    box(2.0, 2.0, 3.0, 2.6)
    box(7.5, 5.5, 8.1, 7.5)
    box(9.5, 1.0, 11.0, 1.4)
    box(4.0, 6.5, 4.4, 6.9)
    box(5.5, 3.5, 6.5, 4.0)
    return OccupancyGrid(prob, RESOLUTION, origin=(-1.0, -2.0, 0.0))


@dataclass
class Drive:
    """A drive through the room: true poses, odometry poses (with drift) and scans."""

    grid: OccupancyGrid
    truth: np.ndarray
    odom: np.ndarray
    scans: list[Scan]


def waypoints_path(n: int) -> np.ndarray:
    """True poses along an oval loop in the room's free space (world frame), ~0.3 m apart."""
    t = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    cx, cy = -1.0 + 6.0, -2.0 + 4.6
    x = cx + 3.6 * np.cos(t)
    y = cy + 2.2 * np.sin(t)
    th = np.arctan2(2.2 * np.cos(t), -3.6 * np.sin(t))
    return np.column_stack([x, y, th])


def simulate(
    grid: OccupancyGrid,
    truth: np.ndarray,
    seed: int = 0,
    circles: list[np.ndarray] | None = None,
    noise: float = 0.01,
    odom_truth: np.ndarray | None = None,
) -> Drive:
    """Scans from the true poses (the project's ray caster) and odometry that drifts.

    The odometry measures the motion along ``odom_truth`` (default: the true path), so a robot
    carried away can be simulated by an odometry path that does not jump.
    """
    moved = truth if odom_truth is None else odom_truth
    from tourbot.maps.raycast import DDACaster

    rng = np.random.default_rng(seed)
    caster = DDACaster(grid, GEOMETRY.max_range)
    odom = [np.array([10.0, -3.0, 1.0])]  # the odometry frame is not the map frame
    for k in range(1, truth.shape[0]):
        step = relative(moved[k - 1], moved[k])
        step = step + rng.normal(0.0, [0.01 + 0.02 * abs(step[0]), 0.005, 0.005 + 0.02 * abs(step[2])])
        odom.append(compose(odom[-1], step))
    scans = []
    for k in range(truth.shape[0]):
        laser = compose(truth[k], np.asarray(GEOMETRY.offset))[None, :]
        if circles is not None and len(circles[k]):
            c = circles[k]
            r = caster.cast_with_circles(laser, GEOMETRY.angles, c, np.full(c.shape[0], 0.1))[0]
        else:
            r = caster.cast(laser, GEOMETRY.angles)[0]
        r = r.astype(np.float64) + rng.normal(0.0, noise, r.shape)
        r = np.where(r >= GEOMETRY.max_range - 1e-3, GEOMETRY.max_range, r)
        scans.append(
            Scan(
                timestamp=float(k),
                ranges=r,
                geometry=GEOMETRY,
                odom=tuple(odom[k]),
                reference=tuple(truth[k]),
            )
        )
    return Drive(grid=grid, truth=truth, odom=np.array(odom), scans=scans)


@pytest.fixture(scope="module")
def room() -> OccupancyGrid:
    return room_with_boxes()
