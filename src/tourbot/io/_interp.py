"""Odometry at a scan's time: linear interpolation between two readings, angles the short way."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import wrap_angle

__all__ = ["interpolate_pose", "interpolate_poses"]

Pose = tuple[float, float, float]


def interpolate_pose(a: Pose, b: Pose, f: float) -> Pose:
    """The pose a fraction ``f`` of the way from ``a`` to ``b`` (``f`` in [0, 1])."""
    if f <= 0.0:
        return a
    if f >= 1.0:
        return b
    dth = float(wrap_angle(b[2] - a[2]))
    return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), float(wrap_angle(a[2] + f * dth)))


def interpolate_poses(
    times: NDArray[np.float64], poses: NDArray[np.float64], at: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Poses ``(M, 3)`` at times ``at`` from readings (``times`` strictly increasing), clamped at the ends."""
    i = np.clip(np.searchsorted(times, at, side="left"), 1, max(len(times) - 1, 1))
    out = np.empty((len(at), 3), dtype=np.float64)
    if len(times) == 1:
        out[:] = poses[0]
        return out
    t0, t1 = times[i - 1], times[i]
    f = np.clip((at - t0) / (t1 - t0), 0.0, 1.0)
    a, b = poses[i - 1], poses[i]
    out[:, :2] = a[:, :2] + f[:, None] * (b[:, :2] - a[:, :2])
    out[:, 2] = wrap_angle(a[:, 2] + f * wrap_angle(b[:, 2] - a[:, 2]))
    exact = at == t1
    out[exact] = b[exact]
    return out
