from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.people.scenes import GEOMETRY, scan_with_circles
from tourbot.people.occlusion import (
    OcclusionConfig,
    occlusion_map,
    occlusion_probability,
    occlusion_probability_reference,
)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**16), p=st.integers(0, 50), holes=st.booleans())
def test_kernel_matches_reference(seed: int, p: int, holes: bool) -> None:
    rng = np.random.default_rng(seed)
    ranges = rng.uniform(0.5, 10.0, 90)
    if holes:
        ranges[rng.uniform(size=90) < 0.3] = np.inf
    points = rng.uniform(-9.0, 9.0, (p, 2))
    cfg = OcclusionConfig()
    a = occlusion_probability(points, ranges, -np.pi / 2, np.pi / 89, cfg)
    b = occlusion_probability_reference(points, ranges, -np.pi / 2, np.pi / 89, cfg)
    np.testing.assert_allclose(a, b, atol=1e-12)


def test_a_person_hides_what_is_behind() -> None:
    scan = scan_with_circles(0.0, (0.0, 0.0, 0.0), [(2.0, 0.0, 0.15)])
    cfg = OcclusionConfig()
    pts = np.array([[4.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.0, 4.0]])
    p = occlusion_probability(pts, scan.ranges, GEOMETRY.angle_min, GEOMETRY.angle_increment, cfg)
    assert p[0] > 0.99  # behind the person
    assert p[1] < 0.01  # in front of it
    assert p[2] < 0.5  # the person itself is not hidden by its own legs
    assert p[3] < 0.01  # beside it, in the open


def test_out_of_view_is_occluded() -> None:
    cfg = OcclusionConfig(max_range=8.0)
    ranges = np.full(181, 5.0)
    p = occlusion_probability(np.array([[-2.0, 0.0], [9.0, 0.0]]), ranges, -np.pi / 2, np.pi / 180, cfg)
    np.testing.assert_allclose(p, [1.0, 1.0])


def test_occlusion_map_has_a_shadow() -> None:
    scan = scan_with_circles(0.0, (0.0, 0.0, 0.0), [(2.0, 0.0, 0.3)])
    grid, corner = occlusion_map(scan, (0.0, 0.0, 0.0), size=10.0, resolution=0.1)
    assert grid.shape == (100, 100)
    col = lambda x: int((x - corner[0]) / 0.1)  # noqa: E731
    row = int((0.0 - corner[1]) / 0.1)
    assert grid[row, col(4.0)] > 0.9
    assert grid[row, col(1.0)] < 0.1
    assert grid[row + 30, col(4.0)] < 0.1
