"""Tests of the figures of ``tourbot bench mapping``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tourbot.bench.mapping import hit_scans
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import LaserGeometry, RobotLog, Scan


def _log(poses: list[tuple[float, float, float]], ranges: list[list[float]]) -> RobotLog:
    geometry = LaserGeometry(num_beams=3, angle_min=-0.1, angle_increment=0.1, max_range=10.0)
    scans = [
        Scan(timestamp=float(i), ranges=np.asarray(r, dtype=np.float64), geometry=geometry, reference=p)
        for i, (p, r) in enumerate(zip(poses, ranges, strict=True))
    ]
    return RobotLog(source="test", scans=scans)


def _grid() -> OccupancyGrid:
    return OccupancyGrid(np.zeros((100, 100), np.float32), 0.05, (-2.5, -2.5, 0.0), 0.65, 0.2)


def test_hit_scans_counts_distinct_scans_and_their_baseline() -> None:
    # two scans from 1 m apart see the same point (2, 0); the first also sees (1, 0) with two beams
    poses = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)]
    ranges = [[10.0, 2.0, 10.0], [10.0, 1.0, 10.0]]
    log = _log(poses, ranges)
    grid = _grid()
    count, baseline = hit_scans(log, np.zeros((2, 3), bool), grid)
    wall = tuple(grid.world_to_cell(np.array([2.0, 0.0])))
    assert count[wall] == 2
    assert baseline[wall] == np.float64(1.0)
    assert count.sum() == 2  # no-return beams add nothing; the second scan's end is the same cell
    # the same point left out of the second scan: one scan, no baseline
    left_out = np.array([[False, False, False], [False, True, False]])
    count, baseline = hit_scans(log, left_out, grid)
    assert count[wall] == 1
    assert baseline[wall] == 0.0
    # a neighbourhood of one cell: the 3 x 3 cells around each end count the scan
    count, _ = hit_scans(log, left_out, grid, radius=1)
    assert count.sum() == 9
    assert count[wall[0] + 1, wall[1] + 1] == 1


def test_slam_starts_where_told_and_both_starts_track_the_path() -> None:
    # the odometry in a frame 2 m and 30 deg away from the reference's, as raw odometry often is
    from tests.mapping.conftest import building, drive
    from tourbot.bench.mapping import _slam
    from tourbot.geometry import compose
    from tourbot.metrics import relative_pose_error

    log = drive(building(), n=60)
    shift = np.array([2.0, -1.0, np.radians(30.0)])
    log = RobotLog(
        "shifted",
        [replace(s, odom=tuple(compose(shift, np.asarray(s.odom)))) for s in log.scans],
    )
    ref, odom = log.reference_poses, log.odom_poses
    assert not np.allclose(odom[0], ref[0])
    for start in (ref[0], odom[0]):
        run = _slam(log, start)
        np.testing.assert_allclose(run.poses[0], start)
        assert relative_pose_error(run.poses, ref).trans_mean < 0.02  # odometry: 0.05 m of noise a step
