from __future__ import annotations

import numpy as np
import pytest

from tourbot.mapping.incremental import IncrementalMapper, MapperParams, MappingError
from tourbot.mapping.metrics import relative_pose_error
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import LaserGeometry, RobotLog, Scan


def test_scan_matching_beats_odometry_on_a_synthetic_hall(hall: OccupancyGrid, hall_log: RobotLog) -> None:
    mapper = IncrementalMapper(start=hall_log.reference_poses[0])
    for scan in hall_log.scans:
        mapper.add_scan(scan)
    ref = hall_log.reference_poses
    slam = relative_pose_error(np.asarray(mapper.poses), ref)
    odom = relative_pose_error(hall_log.odom_poses, ref)
    assert slam.trans_mean < 0.5 * odom.trans_mean
    assert slam.rot_mean < 0.5 * odom.rot_mean
    # the map holds the hall's walls where they are
    grid = mapper.grid()
    walls = hall.cell_to_world(np.argwhere(hall.occupied()))
    cells = grid.world_to_cell(walls)
    seen = grid.inside(cells)
    hit = grid.occupied()[cells[seen, 0], cells[seen, 1]]
    assert hit.mean() > 0.3  # walls the robot saw are mostly mapped


def test_window_forgets_old_scans(hall_log: RobotLog) -> None:
    mapper = IncrementalMapper(MapperParams(window=5), start=hall_log.reference_poses[0])
    for scan in hall_log.scans[:12]:
        mapper.add_scan(scan)
    assert len(mapper._recent) == 5
    # the aligned-against counts are exactly those of the last five scans
    last5 = IncrementalMapper(MapperParams(window=None), start=hall_log.reference_poses[0])
    total = int(mapper._near_hits.sum())
    for scan, pose in zip(hall_log.scans[7:12], mapper.poses[7:12], strict=True):
        last5.integrate(scan, np.asarray(pose))
    assert total == int(last5._hits.sum())
    assert mapper._near_hits.min() >= 0
    assert mapper._near_misses.min() >= 0


def test_grid_grows_to_fit(hall_log: RobotLog) -> None:
    mapper = IncrementalMapper(MapperParams(initial_size=4.0), start=hall_log.reference_poses[0])
    for scan in hall_log.scans[:5]:
        mapper.add_scan(scan)
    grid = mapper.grid()
    assert grid.width > 15.0


def test_scan_without_odometry_is_an_error() -> None:
    geom = LaserGeometry(3, -0.1, 0.1, 10.0)
    with pytest.raises(MappingError, match="odometry"):
        IncrementalMapper().add_scan(Scan(0.0, np.ones(3), geom))


@pytest.mark.slow
def test_real_intel_log_start(shared_data: object) -> None:
    from pathlib import Path

    from tourbot.io.carmen import read_carmen

    assert isinstance(shared_data, Path)
    log = read_carmen(shared_data / "carmen" / "intel-corrected.log.gz")
    scans = log.scans[:150]
    mapper = IncrementalMapper(start=log.reference_poses[0])
    for scan in scans:
        mapper.add_scan(scan)
    ref = log.reference_poses[:150]
    slam = relative_pose_error(np.asarray(mapper.poses), ref)
    odom = relative_pose_error(log.odom_poses[:150], ref)
    assert slam.trans_mean < odom.trans_mean
    assert slam.rot_mean < 0.5 * odom.rot_mean
