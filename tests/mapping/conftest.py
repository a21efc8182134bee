"""A synthetic building and a robot driving through it, for the mapping tests."""

from __future__ import annotations

import numpy as np
import pytest

from tourbot.geometry import compose, relative
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import DDACaster
from tourbot.records import LaserGeometry, RobotLog, Scan


def building(res: float = 0.05) -> OccupancyGrid:
    """A 20 m x 12 m hall with two rooms, pillars and a corridor, walls one cell thick."""
    rows, cols = int(12 / res), int(20 / res)
    prob = np.zeros((rows, cols), np.float32)
    prob[0, :] = prob[-1, :] = prob[:, 0] = prob[:, -1] = 1.0
    prob[: int(7 / res), int(8 / res)] = 1.0  # a wall with a door at the top
    prob[int(4 / res), int(12 / res) :] = 1.0  # a room in the corner
    for x, y in [(3, 3), (5, 8), (15, 9), (11, 2)]:
        r, c = int(y / res), int(x / res)
        prob[r - 4 : r + 4, c - 4 : c + 4] = 1.0
    return OccupancyGrid(prob, res)


def drive(grid: OccupancyGrid, n: int = 120, seed: int = 0, odom_noise: float = 0.05) -> RobotLog:
    """Scans along a loop through the hall, with odometry that drifts."""
    rng = np.random.default_rng(seed)
    geom = LaserGeometry(181, -np.pi / 2, np.pi / 180, 30.0)
    caster = DDACaster(grid, geom.max_range)
    waypoints = np.array(
        [[2.0, 6.0], [6.5, 5.5], [6.5, 10.0], [10.0, 10.0], [17.0, 6.5], [10.0, 6.0], [4.0, 10.5]]
    )
    seg = np.linspace(0, len(waypoints) - 1, n)
    xy = np.array([np.interp(seg, np.arange(len(waypoints)), waypoints[:, k]) for k in (0, 1)]).T
    heading = np.arctan2(np.gradient(xy[:, 1]), np.gradient(xy[:, 0]))
    truth = np.c_[xy, heading]
    odom = truth[0].copy()
    scans = []
    for i in range(n):
        if i:
            step = relative(truth[i - 1], truth[i])
            noisy = step + rng.normal(0.0, [odom_noise, odom_noise / 2, odom_noise / 2])
            odom = compose(odom, noisy)
        ranges = caster.cast(truth[i][None], geom.angles)[0].astype(np.float64)
        ranges = ranges + rng.normal(0.0, 0.01, ranges.shape)
        scans.append(Scan(float(i), ranges, geom, odom=tuple(odom), reference=tuple(truth[i])))
    return RobotLog("synthetic", scans)


def corridor_scan(odom: tuple[float, float, float], end: float | None = None) -> Scan:
    """A scan in a corridor with walls 1 m either side of the robot, facing along it; beyond
    8 m no return, so that no end wall is seen unless ``end`` (m ahead) puts one in sight. The
    walls look the same from anywhere along the corridor: ``odom`` alone says where it is."""
    geom = LaserGeometry(181, -np.pi / 2, np.pi / 180, 8.0)
    a = geom.angles
    with np.errstate(divide="ignore"):
        ranges = np.where(np.abs(np.sin(a)) > 1e-9, 1.0 / np.abs(np.sin(a)), np.inf)
        if end is not None:
            ranges = np.minimum(ranges, np.where(np.cos(a) > 1e-9, end / np.cos(a), np.inf))
    return Scan(0.0, np.minimum(ranges, 8.0), geom, odom=odom)


@pytest.fixture(scope="module")
def hall() -> OccupancyGrid:
    return building()


@pytest.fixture(scope="module")
def hall_log(hall: OccupancyGrid) -> RobotLog:
    return drive(hall)
