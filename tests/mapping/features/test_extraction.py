from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.mapping.conftest import building
from tourbot.mapping.features.extraction import (
    ExtractionParams,
    extract_corners,
    extract_segments,
    fit_line,
    scan_points,
)
from tourbot.maps.raycast import DDACaster
from tourbot.records import LaserGeometry


def _room_scan(noise: float = 0.005, seed: int = 0) -> tuple[np.ndarray, float]:
    """A scan from (2, 3) facing +x in the corner of walls x = 6 and y = 7 (and y = 0)."""
    rng = np.random.default_rng(seed)
    angles = np.radians(np.arange(-90.0, 90.0, 1.0))
    pose = np.array([2.0, 3.0])
    ranges = []
    for a in angles:
        d = np.array([math.cos(a), math.sin(a)])
        hits = []
        if d[0] > 1e-9:
            hits.append((6.0 - pose[0]) / d[0])
        if d[1] > 1e-9:
            hits.append((7.0 - pose[1]) / d[1])
        if d[1] < -1e-9:
            hits.append((0.0 - pose[1]) / d[1])
        ranges.append(min(hits) + rng.normal(0.0, noise))
    return scan_points(np.array(ranges), angles, 30.0), math.radians(1.0)


def test_segments_recover_known_walls() -> None:
    pts, step = _room_scan()
    segments = extract_segments(pts, step)
    # walls in the robot frame (robot at (2, 3)): x = 4 (alpha 0, r 4), y = 4 (alpha pi/2, r 4),
    # y = -3 (alpha -pi/2, r 3)
    walls = {(0.0, 4.0), (math.pi / 2, 4.0), (-math.pi / 2, 3.0)}
    found = set()
    for s in segments:
        for alpha, r in walls:
            if (
                abs(math.atan2(math.sin(s.alpha - alpha), math.cos(s.alpha - alpha))) < math.radians(1.0)
                and abs(s.r - r) < 0.02
            ):
                found.add((alpha, r))
    assert found == walls
    assert len(segments) == 3
    corners = extract_corners(segments)
    assert len(corners) == 2
    expected = [np.array([4.0, -3.0]), np.array([4.0, 4.0])]
    for c in corners:
        assert min(np.hypot(*(c.position - e)) for e in expected) < 0.05
        assert abs(c.angle - math.pi / 2) < math.radians(2.0)


def test_segments_of_the_synthetic_hall_lie_on_its_walls() -> None:
    grid = building()
    geom = LaserGeometry(181, -np.pi / 2, np.pi / 180, 30.0)
    pose = np.array([[2.0, 6.0, 0.3]])
    ranges = DDACaster(grid, geom.max_range).cast(pose, geom.angles)[0].astype(np.float64)
    segments = extract_segments(scan_points(ranges, geom.angles, geom.max_range), geom.angle_increment)
    assert len(segments) >= 3
    occupied = grid.cell_to_world(np.argwhere(grid.occupied()))
    c, s = math.cos(0.3), math.sin(0.3)
    for seg in segments:
        for p in (seg.start, seg.end):
            world = np.array([2.0 + c * p[0] - s * p[1], 6.0 + s * p[0] + c * p[1]])
            assert np.min(np.hypot(*(occupied - world).T)) < 0.1


def test_fit_line_covariance_matches_its_spread() -> None:
    """The (alpha, r) covariance of the fit agrees with the spread of fits over noise draws."""
    rng = np.random.default_rng(1)
    x = np.linspace(-1.0, 3.0, 40)
    fits = []
    for _ in range(400):
        pts = np.stack([x, 2.0 + rng.normal(0.0, 0.02, len(x))], axis=1)
        alpha, r, cov = fit_line(pts, 0.02)
        fits.append((alpha, r))
    spread = np.cov(np.array(fits).T)
    assert np.allclose(np.sqrt(np.diag(spread)), np.sqrt(np.diag(cov)), rtol=0.2)
    assert np.sign(spread[0, 1]) == np.sign(cov[0, 1])


@settings(max_examples=40, deadline=None)
@given(
    alpha=st.floats(-math.pi, math.pi),
    r=st.floats(0.2, 10.0),
    length=st.floats(0.5, 5.0),
    offset=st.floats(-3.0, 3.0),
)
def test_fit_line_recovers_any_line(alpha: float, r: float, length: float, offset: float) -> None:
    n = np.array([math.cos(alpha), math.sin(alpha)])
    t = np.array([-n[1], n[0]])
    s = np.linspace(offset, offset + length, 20)
    pts = r * n[None, :] + s[:, None] * t[None, :]
    a, rr, _ = fit_line(pts, 0.01)
    assert abs(math.atan2(math.sin(a - alpha), math.cos(a - alpha))) < 1e-6
    assert abs(rr - r) < 1e-6


def test_short_or_sparse_pieces_are_not_segments() -> None:
    params = ExtractionParams()
    angles = np.radians(np.arange(-90.0, 90.0, 1.0))
    ranges = np.full(len(angles), 100.0)  # nothing returned
    ranges[80:84] = 2.0  # four returns: fewer than min_points
    assert extract_segments(scan_points(ranges, angles, 30.0), math.radians(1.0), params) == []
