"""Small synthetic scans for the people tests: leg circles inside a ring wall."""

from __future__ import annotations

import numpy as np

from tourbot.maps.raycast import circle_ranges
from tourbot.records import LaserGeometry, Scan

GEOMETRY = LaserGeometry(num_beams=720, angle_min=-np.pi, angle_increment=2 * np.pi / 720, max_range=30.0)


def scan_with_circles(
    t: float,
    pose: tuple[float, float, float] | np.ndarray,
    circles: list[tuple[float, float, float]],
    wall: float = 10.0,
    geometry: LaserGeometry = GEOMETRY,
) -> Scan:
    """A noise-free scan from ``pose`` of circles ``(x, y, radius)`` inside a ring wall around it
    (the circles cast by the project's one ray caster, :func:`tourbot.maps.raycast.circle_ranges`)."""
    p = np.asarray(pose, dtype=np.float64)
    out = np.full((1, geometry.num_beams), wall, dtype=np.float32)
    c = np.asarray(circles, dtype=np.float64).reshape(-1, 3)
    circle_ranges(
        p[0:1].copy(),
        p[1:2].copy(),
        p[2:3].copy(),
        geometry.angles,
        np.ascontiguousarray(c[:, 0]),
        np.ascontiguousarray(c[:, 1]),
        np.ascontiguousarray(c[:, 2]),
        out,
    )
    return Scan(t, out[0].astype(np.float64), geometry)


def legs_of(x: float, y: float, heading: float, phase: float) -> list[tuple[float, float, float]]:
    """Two 6 cm leg circles of a person at ``(x, y)`` walking along ``heading``, stride by ``phase``."""
    f = np.array([np.cos(heading), np.sin(heading)])
    s = np.array([-np.sin(heading), np.cos(heading)])
    out = []
    for side in (-1.0, 1.0):
        c = np.array([x, y]) + side * 0.1 * s + side * 0.15 * np.sin(phase) * f
        out.append((float(c[0]), float(c[1]), 0.06))
    return out
