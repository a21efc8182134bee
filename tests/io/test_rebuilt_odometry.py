from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tourbot.io.rebuilt_odometry import rebuild_odometry, with_rebuilt_odometry
from tourbot.records import LaserGeometry, RobotLog, Scan


def test_the_jump_onto_a_reanchoring_line_is_skipped(tmp_path: Path) -> None:
    log = tmp_path / "a.log"
    log.write_text(
        "ODOM 0 0 0 0 0 0 1.0 pippo 1.0\n"
        "ODOM 1 0 0 0 0 0 2.0 pippo 2.0\n"
        "FLASER 3 1 1 1 1 0 0 1 0 0 2.1 pippo 2.1\n"
        "ODOM 5 5 1.5707963 0 0 0 0 pippo 0\n"  # re-anchored: a jump of (4, 5, 90 deg)
        "ODOM 5 6 1.5707963 0 0 0 3.0 pippo 3.0\n"  # one metre on, along the new heading
        "FLASER 3 1 1 1 7 7 0 1 0 0 3.1 pippo 3.1\n"
        "ODOM 7 7 0 0 0 0 5.21 pippo 5.21\n"  # a re-anchoring copy with a garbage timestamp
    )
    kinds, poses = rebuild_odometry(log)
    assert kinds == ["FLASER", "FLASER"]
    # the increment after the anchor is one metre forward in the robot frame, from (1, 0, 0)
    assert np.allclose(poses, [[1, 0, 0], [2, 0, 0]], atol=1e-6)


def test_rebuilt_odometry_drifts_on_intel(real_log: Callable[[str], RobotLog], shared_data: Path) -> None:
    from tourbot.metrics.relative import aligned_trajectory_error

    path = shared_data / "carmen" / "intel-corrected.log.gz"
    log = real_log("intel")
    rebuilt = with_rebuilt_odometry(log, path)
    ref = log.reference_poses
    assert aligned_trajectory_error(log.odom_poses, ref).rmse < 0.2  # the anchored stream: the answer
    assert aligned_trajectory_error(rebuilt.odom_poses, ref).rmse > 10.0  # real odometry drifts (24 m)


def test_no_readings_is_an_error(tmp_path: Path) -> None:
    log = tmp_path / "b.log"
    log.write_text("FLASER 3 1 1 1 1 0 0 1 0 0 2.1 pippo 2.1\n")  # no reading before the scan
    geom = LaserGeometry(3, -1.0, 1.0, 10.0)
    robot = RobotLog("b", [Scan(2.1, np.ones(3), geom, sensor="FLASER")])
    with pytest.raises(ValueError, match="no timestamped ODOM"):
        with_rebuilt_odometry(robot, log)
