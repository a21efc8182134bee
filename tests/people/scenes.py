"""Small synthetic scans for the people tests: a ring wall and leg circles, ray-circle intersection."""

from __future__ import annotations

import numpy as np

from tourbot.records import LaserGeometry, Scan

GEOMETRY = LaserGeometry(num_beams=720, angle_min=-np.pi, angle_increment=2 * np.pi / 720, max_range=30.0)


def scan_with_circles(
    t: float,
    pose: tuple[float, float, float] | np.ndarray,
    circles: list[tuple[float, float, float]],
    wall: float = 10.0,
    geometry: LaserGeometry = GEOMETRY,
) -> Scan:
    """A noise-free scan from ``pose`` of circles ``(x, y, radius)`` inside a ring wall around it."""
    p = np.asarray(pose, dtype=np.float64)
    ang = geometry.angles + p[2]
    d = np.stack([np.cos(ang), np.sin(ang)], -1)
    r = np.full(geometry.num_beams, wall)
    for cx, cy, rad in circles:
        oc = p[0:2] - np.array([cx, cy])
        b = d @ oc
        disc = b * b - (oc @ oc - rad * rad)
        hit_t = -b - np.sqrt(np.maximum(disc, 0.0))
        hit = (disc > 0.0) & (hit_t > 0.0) & (hit_t < r)
        r = np.where(hit, hit_t, r)
    return Scan(t, r, geometry)


def legs_of(x: float, y: float, heading: float, phase: float) -> list[tuple[float, float, float]]:
    """Two 6 cm leg circles of a person at ``(x, y)`` walking along ``heading``, stride by ``phase``."""
    f = np.array([np.cos(heading), np.sin(heading)])
    s = np.array([-np.sin(heading), np.cos(heading)])
    out = []
    for side in (-1.0, 1.0):
        c = np.array([x, y]) + side * 0.1 * s + side * 0.15 * np.sin(phase) * f
        out.append((float(c[0]), float(c[1]), 0.06))
    return out
