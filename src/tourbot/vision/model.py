"""The 2.5D model of the world built from one laser scan, and image t-1 back-projected through it.

Burgard et al., Sec. 3 (after Baltzakis et al. 2002): from the scan ``s_{t-1}`` the robot builds a
2.5D model, vertical planar walls through the scan's endpoints (consecutive endpoints closer than
``max_gap`` are joined; a beam without a return leaves no wall) standing on the floor. Seen from a
camera, a vertical-plane model gives every pixel's ray a horizontal range that depends only on the
ray's azimuth (:func:`model_profile`); the ray then meets the floor or a wall
(:func:`model_points`). Image ``i_{t-1}`` sampled where those points fall in camera ``t-1`` is the
image ``î_t`` the model predicts at time ``t`` (:func:`back_project`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import transform_points
from tourbot.records import Scan

__all__ = ["back_project", "model_points", "model_profile", "scan_endpoints"]

FloatArray = NDArray[np.float64]


def scan_endpoints(scan: Scan, pose: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The scan's endpoints ``(B, 2)`` in the world for a robot ``pose``, and which beams returned."""
    g = scan.geometry
    r = np.asarray(scan.ranges, dtype=np.float64)
    ok = (r < g.max_range) & (r > g.min_range)
    a = g.angles + g.offset[2]
    local = np.stack([g.offset[0] + r * np.cos(a), g.offset[1] + r * np.sin(a)], axis=-1)
    return transform_points(pose, local), ok


def model_profile(
    endpoints: FloatArray,
    returned: NDArray[np.bool_],
    origin: FloatArray,
    azimuths: FloatArray,
    max_gap: float,
) -> FloatArray:
    """Horizontal range ``(A,)`` from ``origin`` (x, y) along each world azimuth to the nearest wall
    of the model (``inf`` where there is none): the walls are the segments between consecutive
    returned endpoints less than ``max_gap`` apart.

    Plain numpy: every azimuth against every wall; ask only for the azimuths a camera sees."""
    p = endpoints[:-1]
    q = endpoints[1:]
    keep = returned[:-1] & returned[1:] & (np.hypot(*(q - p).T) < max_gap)
    if (
        len(endpoints) > 2
        and returned[0]
        and returned[-1]
        and np.hypot(*(endpoints[0] - endpoints[-1])) < max_gap
    ):
        p = np.vstack([p, endpoints[-1:]])
        q = np.vstack([q, endpoints[:1]])
        keep = np.r_[keep, True]
    p, q = p[keep] - origin, q[keep] - origin
    out = np.full(len(azimuths), np.inf)
    if not len(p):
        return out
    d = np.stack([np.cos(azimuths), np.sin(azimuths)], axis=-1)  # (A, 2)
    e = q - p  # (S, 2)
    cross_de = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (A, S)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (p[None, :, 0] * e[None, :, 1] - p[None, :, 1] * e[None, :, 0]) / cross_de
        u = (p[None, :, 0] * d[:, None, 1] - p[None, :, 1] * d[:, None, 0]) / cross_de
    hit = (np.abs(cross_de) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1)
    t = np.where(hit, t, np.inf)
    return np.asarray(t.min(axis=1))


def model_points(
    azimuth: FloatArray,
    horizontal: FloatArray,
    vertical: FloatArray,
    height: float,
    profile: FloatArray,
    azimuth_step: float,
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """Where rays from a camera at ``height`` meet the model: the distance along each ray and
    whether it is the floor (else a wall). A ray is given by its world ``azimuth``, the length
    ``horizontal`` of its unit direction's horizontal part and its ``vertical`` part (any shape);
    ``profile`` holds the ranges of ``2 pi / azimuth_step`` azimuths from ``-pi``."""
    n = len(profile)
    k = np.round((azimuth + math.pi) / azimuth_step).astype(np.int64) % n
    with np.errstate(divide="ignore", invalid="ignore"):
        t_wall = np.where(horizontal > 1e-6, profile[k] / horizontal, np.inf)
        t_floor = np.where(vertical < -1e-6, -height / vertical, np.inf)
    floor = t_floor <= t_wall
    return np.minimum(t_floor, t_wall).astype(np.float32), floor


def back_project(
    previous: NDArray[np.uint8],
    points: NDArray[np.float32],
    rotation: FloatArray,
    position: FloatArray,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """``î_t``: image ``previous`` sampled (bilinear) where world ``points`` ``(H, W, 3)`` fall in
    the previous camera (``rotation`` columns: its axes in the world; ``position``); and where
    they fall inside it."""
    import cv2

    cam = (points - position.astype(np.float32)) @ rotation.astype(np.float32)
    z = cam[..., 2]
    ok = z > 0.05
    zs = np.where(ok, z, 1.0)
    mx = (cx + fx * cam[..., 0] / zs).astype(np.float32)
    my = (cy + fy * cam[..., 1] / zs).astype(np.float32)
    h, w = previous.shape
    ok &= (mx >= 0) & (mx <= w - 1) & (my >= 0) & (my <= h - 1) & np.isfinite(mx) & np.isfinite(my)
    mx = np.where(ok, mx, -1.0).astype(np.float32)
    my = np.where(ok, my, -1.0).astype(np.float32)
    warped = cv2.remap(previous.astype(np.float32), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return np.asarray(warped, dtype=np.float32), ok
