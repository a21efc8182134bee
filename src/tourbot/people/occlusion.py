"""The occlusion map: the probability that a place near the robot is hidden from the laser.

Burgard et al., Sec. 4 and Fig. 5 (right): "for each position in the vicinity of the robot, the
probability that the corresponding position is not visible given the current range scan". A place
at distance ``d`` along a beam that returned ``r`` is hidden when something stands in front of it,
``r < d - margin``; the margin (about a person's radius plus the range noise) keeps a person from
occluding itself. With range noise ``sigma`` the probability is ``Phi((d - margin - r) / sigma)``.
Places outside the field of view or beyond the sensor's reach are not visible (probability 1);
a beam with no return passed by, so the place is visible (probability 0).

The tracker does not count a missed detection against a person whose samples are occluded, so
the track stays alive and its samples spread out (Burgard et al., Fig. 7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, transform_points
from tourbot.records import Scan

__all__ = [
    "OcclusionConfig",
    "occlusion_map",
    "occlusion_probability",
    "occlusion_probability_reference",
    "points_in_sensor_frame",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class OcclusionConfig:
    """``margin``: depth in front of a place that does not hide it (a person's radius, 0.3 m);
    ``sigma``: range noise of the laser (0.05 m); ``max_range``: farthest place the tracker sees."""

    margin: float = 0.3
    sigma: float = 0.05
    max_range: float = 8.0


def points_in_sensor_frame(points: FloatArray, robot_pose: FloatArray, scan: Scan) -> FloatArray:
    """World points ``(..., 2)`` expressed in the laser frame of ``scan`` taken at ``robot_pose``."""
    sensor = compose(robot_pose, np.asarray(scan.geometry.offset, dtype=np.float64))
    c, s = math.cos(sensor[2]), math.sin(sensor[2])
    inv = np.array([-c * sensor[0] - s * sensor[1], s * sensor[0] - c * sensor[1], -sensor[2]])
    return transform_points(inv, points)


def occlusion_probability_reference(
    points: FloatArray, ranges: FloatArray, angle_min: float, angle_increment: float, config: OcclusionConfig
) -> FloatArray:
    """Plain-numpy P(occluded) of points ``(P, 2)`` given in the laser frame."""
    B = ranges.shape[0]
    d = np.hypot(points[:, 0], points[:, 1])
    bearing = np.arctan2(points[:, 1], points[:, 0])
    idx = np.rint((bearing - angle_min) / angle_increment).astype(np.int64)
    inside = (idx >= 0) & (idx < B) & (d <= config.max_range)
    r = ranges[np.clip(idx, 0, B - 1)]
    returned = np.isfinite(r) & (r > 0.0) & (r < config.max_range)
    z = (d - config.margin - np.where(returned, r, 0.0)) / config.sigma
    erf = np.vectorize(math.erf, otypes=[np.float64])
    p = 0.5 * (1.0 + erf(z / math.sqrt(2.0))) if z.size else np.zeros(0)
    p = np.where(returned, p, 0.0)
    return np.where(inside, p, 1.0)


@numba.njit(cache=True)
def _occlusion_kernel(
    points: FloatArray,
    ranges: FloatArray,
    angle_min: float,
    angle_increment: float,
    margin: float,
    sigma: float,
    max_range: float,
) -> FloatArray:
    P = points.shape[0]
    B = ranges.shape[0]
    out = np.empty(P)
    for k in range(P):
        x = points[k, 0]
        y = points[k, 1]
        d = math.sqrt(x * x + y * y)
        i = int(np.rint((math.atan2(y, x) - angle_min) / angle_increment))
        if i < 0 or i >= B or d > max_range:
            out[k] = 1.0
            continue
        r = ranges[i]
        if not (np.isfinite(r) and r > 0.0 and r < max_range):
            out[k] = 0.0
            continue
        z = (d - margin - r) / sigma
        out[k] = 0.5 * (1.0 + math.erf(z / math.sqrt(2.0)))
    return out


def occlusion_probability(
    points: FloatArray, ranges: FloatArray, angle_min: float, angle_increment: float, config: OcclusionConfig
) -> FloatArray:
    """P(occluded) of points ``(P, 2)`` in the laser frame (numba kernel of the reference above)."""
    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    return _occlusion_kernel(
        pts,
        np.ascontiguousarray(ranges, dtype=np.float64),
        float(angle_min),
        float(angle_increment),
        config.margin,
        config.sigma,
        config.max_range,
    )


def occlusion_map(
    scan: Scan,
    robot_pose: FloatArray | tuple[float, float, float],
    *,
    size: float = 10.0,
    resolution: float = 0.05,
    config: OcclusionConfig | None = None,
) -> tuple[FloatArray, tuple[float, float]]:
    """The occlusion grid of Fig. 5 (right): P(occluded) of a ``size`` x ``size`` m square of cells
    centred on the robot. Returns the ``(rows, cols)`` grid (row = y) and its lower-left corner."""
    cfg = config or OcclusionConfig()
    pose = np.asarray(robot_pose, dtype=np.float64)
    n = round(size / resolution)
    centres = (np.arange(n) + 0.5) * resolution - size / 2.0
    gx, gy = np.meshgrid(centres + pose[0], centres + pose[1])
    world = np.stack([gx.ravel(), gy.ravel()], -1)
    local = points_in_sensor_frame(world, pose, scan)
    g = scan.geometry
    p = occlusion_probability(local, scan.ranges, g.angle_min, g.angle_increment, cfg)
    return p.reshape(n, n), (pose[0] - size / 2.0, pose[1] - size / 2.0)
