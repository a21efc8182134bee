"""KISS-ICP (Vizzo et al., RA-L 2023; PyPI ``kiss-icp``) as a 2D scan-matching front end.

Each scan's returned beams become a planar point cloud (z = 0) in the laser frame; the pose
KISS-ICP estimates is brought back to SE(2). KISS-ICP predicts each frame with a constant-velocity
model; here the prediction is the wheel odometry's increment instead (set as its ``last_delta``
before each frame), so that it gets the same input as tourbot's front end. No loop closure.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, relative
from tourbot.records import Scan

__all__ = ["kiss_icp_path"]


def _se3(pose: NDArray[np.float64]) -> NDArray[np.float64]:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    m[:2, 3] = pose[:2]
    return m


def kiss_icp_path(
    scans: list[Scan], start: NDArray[np.float64], max_range: float = 25.0, voxel_size: float = 0.1
) -> NDArray[np.float64]:
    """KISS-ICP's robot poses ``(S, 3)`` over ``scans``, its frame put at ``start``."""
    from kiss_icp.config import KISSConfig
    from kiss_icp.kiss_icp import KissICP

    config = KISSConfig()
    config.data.max_range = max_range
    config.data.min_range = 0.05
    config.data.deskew = False
    config.mapping.voxel_size = voxel_size
    config.registration.max_num_threads = 1
    icp = KissICP(config)
    out = np.empty((len(scans), 3))
    prev_odom: NDArray[np.float64] | None = None
    offset = np.asarray(scans[0].geometry.offset, dtype=np.float64)
    for k, scan in enumerate(scans):
        g = scan.geometry
        r = np.asarray(scan.ranges, dtype=np.float64)
        ok = (r > g.min_range) & (r < min(g.max_range, max_range))
        ang = g.angles[ok]
        pts = np.stack([r[ok] * np.cos(ang), r[ok] * np.sin(ang), np.zeros(int(ok.sum()))], axis=1)
        odom = np.asarray(scan.odom, dtype=np.float64)
        if prev_odom is not None:  # the odometry's increment, in the laser frame, as the prediction
            laser_step = relative(compose(prev_odom, offset), compose(odom, offset))
            icp.last_delta = _se3(laser_step)
        prev_odom = odom
        icp.register_frame(pts, np.zeros(len(pts)))
        m = icp.last_pose
        laser = np.array([m[0, 3], m[1, 3], math.atan2(m[1, 0], m[0, 0])])
        out[k] = compose(laser, relative(offset, np.zeros(3)))  # laser pose -> robot pose
    # the first laser frame is KISS-ICP's origin: put it at ``start``
    base = compose(np.asarray(start, dtype=np.float64), offset)
    robot = compose(base, out)
    return np.asarray(robot)
