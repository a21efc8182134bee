"""Poses in SE(2): angle wrapping, composition, inversion, frame changes and interpolation.

A pose is ``(x, y, theta)`` in metres and radians, right-handed, ``theta`` wrapped to (-pi, pi].
Batches of poses are ``(N, 3)`` float64 arrays; every function here accepts a single pose (shape
``(3,)``) or a batch.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Pose",
    "compose",
    "interpolate_pose",
    "interpolate_poses",
    "invert",
    "relative",
    "transform_points",
    "wrap_angle",
]

FloatArray = NDArray[np.float64]


class Pose(NamedTuple):
    """A single 2D pose; ``np.asarray(pose)`` gives the ``(3,)`` array form."""

    x: float
    y: float
    theta: float


def wrap_angle(angle: ArrayLike) -> FloatArray:
    """Wrap angles to (-pi, pi]."""
    a = np.asarray(angle, dtype=np.float64)
    wrapped = np.pi - np.mod(np.pi - a, 2.0 * np.pi)
    return np.asarray(wrapped, dtype=np.float64)


def compose(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """``a (+) b``: the pose ``b``, expressed in frame ``a``, brought to the frame of ``a``'s parent."""
    pa = np.asarray(a, dtype=np.float64)
    pb = np.asarray(b, dtype=np.float64)
    c, s = np.cos(pa[..., 2]), np.sin(pa[..., 2])
    x = pa[..., 0] + c * pb[..., 0] - s * pb[..., 1]
    y = pa[..., 1] + s * pb[..., 0] + c * pb[..., 1]
    th = wrap_angle(pa[..., 2] + pb[..., 2])
    return np.stack([x, y, th], axis=-1)


def invert(a: ArrayLike) -> FloatArray:
    """The inverse pose: ``compose(a, invert(a)) == 0``."""
    pa = np.asarray(a, dtype=np.float64)
    c, s = np.cos(pa[..., 2]), np.sin(pa[..., 2])
    x = -c * pa[..., 0] - s * pa[..., 1]
    y = s * pa[..., 0] - c * pa[..., 1]
    return np.stack([x, y, wrap_angle(-pa[..., 2])], axis=-1)


def relative(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """``a (-) b``... the pose of ``b`` in the frame of ``a`` (``compose(a, relative(a, b)) == b``)."""
    return compose(invert(a), b)


def transform_points(pose: ArrayLike, points: ArrayLike) -> FloatArray:
    """Points ``(M, 2)`` given in the frame ``pose`` expressed in the parent frame."""
    p = np.asarray(pose, dtype=np.float64)
    pts = np.asarray(points, dtype=np.float64)
    c, s = np.cos(p[2]), np.sin(p[2])
    x = p[0] + c * pts[..., 0] - s * pts[..., 1]
    y = p[1] + s * pts[..., 0] + c * pts[..., 1]
    return np.stack([x, y], axis=-1)


def interpolate_pose(
    a: tuple[float, float, float], b: tuple[float, float, float], f: float
) -> tuple[float, float, float]:
    """The pose a fraction ``f`` of the way from ``a`` to ``b`` (``f`` in [0, 1]): linear in
    position, the heading turning the short way (odometry at a scan's time)."""
    if f <= 0.0:
        return a
    if f >= 1.0:
        return b
    dth = float(wrap_angle(b[2] - a[2]))
    return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), float(wrap_angle(a[2] + f * dth)))


def interpolate_poses(
    times: NDArray[np.float64], poses: NDArray[np.float64], at: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Poses ``(M, 3)`` at times ``at`` from readings ``poses`` at ``times`` (strictly increasing),
    as :func:`interpolate_pose`, clamped at the ends; a time of a reading gives that reading."""
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
