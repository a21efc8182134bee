"""Crowds and kidnaps for the MCL tests in the synthetic room."""

from __future__ import annotations

import math

import numpy as np

from tourbot.geometry import compose, relative
from tourbot.localization.mcl import MonteCarloLocalization
from tourbot.maps.grid import OccupancyGrid

from ..conftest import Drive


def errors(est_poses: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.hypot(est_poses[:, 0] - truth[:, 0], est_poses[:, 1] - truth[:, 1])


def run(mcl: MonteCarloLocalization, drive: Drive) -> np.ndarray:
    return np.array([mcl.update(drive.odom[k], s).pose for k, s in enumerate(drive.scans)])


def people_in_front(truth: np.ndarray, rng: np.random.Generator) -> list[np.ndarray]:
    """Two people (four legs) 0.8-1.5 m in front of the robot at every pose."""
    out = []
    for p in truth:
        pts = []
        for _ in range(2):
            d = rng.uniform(0.8, 1.5)
            a = rng.uniform(-0.6, 0.6)
            c = compose(p, np.array([d * math.cos(a), d * math.sin(a), 0.0]))
            pts += [c[:2] + np.array([0.0, 0.12]), c[:2] - np.array([0.0, 0.12])]
        out.append(np.array(pts))
    return out


def crowd_around(truth: np.ndarray, rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """``n`` legs (10 cm circles) 0.5-1.5 m from the robot, spread over its field of view."""
    out = []
    for p in truth:
        d = rng.uniform(0.5, 1.5, n)
        a = rng.uniform(-math.pi / 2, math.pi / 2, n)
        out.append(
            np.array(
                [
                    compose(p, np.array([di * math.cos(ai), di * math.sin(ai), 0.0]))[:2]
                    for di, ai in zip(d, a, strict=True)
                ]
            )
        )
    return out


def phantom_kidnap(odom: np.ndarray, at: int, delta: np.ndarray) -> np.ndarray:
    """The odometry after a kidnap before scan ``at`` as :mod:`tourbot.sim.kidnap` makes it: a
    motion ``delta`` that never happened, carried along by every later reading."""
    out = odom.copy()
    correction = compose(compose(odom[at], delta), relative(odom[at], np.zeros(3)))
    out[at:] = compose(correction, odom[at:])
    return out


def legs_before_walls(
    truth: np.ndarray, grid: OccupancyGrid, gap: float, rng: np.random.Generator
) -> list[np.ndarray]:
    """Four legs (10 cm circles) whose near side is ``gap`` metres in front of the wall that a
    beam at -60, -20, 20 or 60 degrees (a little jittered) would hit: visitors along the walls."""
    from tourbot.maps.raycast import DDACaster

    from ..conftest import GEOMETRY

    caster = DDACaster(grid, GEOMETRY.max_range)
    out = []
    for p in truth:
        laser = compose(p, np.asarray(GEOMETRY.offset))
        angles = np.radians([-60.0, -20.0, 20.0, 60.0]) + rng.uniform(-0.05, 0.05, 4)
        wall = caster.cast(laser[None, :], angles)[0].astype(np.float64)
        d = np.maximum(wall - gap - 0.1, 0.5)  # the leg's centre, its near side gap before the wall
        a = laser[2] + angles
        out.append(np.column_stack([laser[0] + d * np.cos(a), laser[1] + d * np.sin(a)]))
    return out


def rarely_seen(grid: OccupancyGrid, beyond_x: float, beyond_y: float) -> OccupancyGrid:
    """``grid`` with its free cells right of ``beyond_x`` or above ``beyond_y`` (world metres)
    unknown, as a map built from one log leaves the free space its beams crossed only a few
    times (too few misses to call it free); walls and boxes stay as they are."""
    prob = grid.prob.copy()
    x = grid.origin[0] + (np.arange(prob.shape[1]) + 0.5) * grid.resolution
    y = grid.origin[1] + (np.arange(prob.shape[0]) + 0.5) * grid.resolution
    xx, yy = np.meshgrid(x, y)
    prob[((xx > beyond_x) | (yy > beyond_y)) & (prob < grid.occupied_thresh)] = -1.0
    return OccupancyGrid(prob, grid.resolution, origin=grid.origin)
