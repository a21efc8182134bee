"""The checks before the work: a map that does not fit, too little odometry, no motion."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tourbot.cli._checks import log_problems, map_problem
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import Odometry, RobotLog

from ..localization.conftest import room_with_boxes, simulate, waypoints_path


def _drive() -> tuple[OccupancyGrid, RobotLog]:
    grid = room_with_boxes()
    drive = simulate(grid, waypoints_path(20), seed=4)
    return grid, RobotLog(source="synthetic", scans=drive.scans)


def test_the_own_map_fits_even_when_a_crowd_shortens_half_the_beams() -> None:
    grid, log = _drive()
    assert map_problem(log, grid) is None
    rng = np.random.default_rng(0)
    crowded = []
    for s in log.scans:
        r = s.ranges.copy()
        hit = rng.random(r.size) < 0.5
        r[hit] *= rng.uniform(0.1, 0.8, int(hit.sum()))
        crowded.append(replace(s, ranges=r))
    assert map_problem(replace(log, scans=crowded), grid) is None


def test_another_building_does_not_fit() -> None:
    _grid, log = _drive()
    prob = np.zeros((600, 600), np.float32)
    prob[:3, :] = prob[-3:, :] = prob[:, :3] = prob[:, -3:] = 1.0
    problem = map_problem(log, OccupancyGrid(prob, 0.05, origin=(-10.0, -10.0, 0.0)))
    assert problem is not None
    assert problem.startswith("the map does not fit the log")


def test_too_few_readings_and_no_motion() -> None:
    _grid, log = _drive()
    assert log_problems(log) == []  # odometry on the scans, no stream: fine
    sparse = replace(log, odometry=[Odometry(0.0, (0.0, 0.0, 0.0))])
    assert log_problems(sparse)[0].startswith(f"only 1 odometry reading for {len(log.scans)} scans")
    still = replace(log, scans=[replace(s, odom=(1.0, 1.0, 0.0)) for s in log.scans])
    assert log_problems(still)[0].startswith("the odometry does not move")
