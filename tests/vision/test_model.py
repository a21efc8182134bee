"""The laser's 2.5D model: walls through the endpoints, floor elsewhere, and the back-projection."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.records import LaserGeometry, Scan
from tourbot.vision.model import back_project, model_points, model_profile, scan_endpoints


def _wall_at(x: float, n: int = 181) -> tuple[np.ndarray, np.ndarray]:
    """Endpoints of a scan of the wall ``x = const`` seen from the origin."""
    a = np.linspace(-1.2, 1.2, n)
    r = x / np.cos(a)
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=-1), np.ones(n, dtype=bool)


@given(st.floats(1.0, 8.0), st.floats(-0.9, 0.9))
@settings(max_examples=30, deadline=None)
def test_profile_meets_the_wall_through_the_endpoints(x: float, az: float) -> None:
    ep, ok = _wall_at(x)
    r = model_profile(ep, ok, np.zeros(2), np.array([az]), max_gap=0.5)[0]
    assert math.isclose(r, x / math.cos(az), rel_tol=2e-3)


def test_gaps_and_missing_returns_leave_no_wall() -> None:
    ep, ok = _wall_at(3.0)
    ok[80:100] = False  # no return in the middle
    r = model_profile(ep, ok, np.zeros(2), np.array([0.0, 1.0]), max_gap=0.5)
    assert np.isinf(r[0])
    assert np.isfinite(r[1])
    far = model_profile(ep * 40.0, np.ones(len(ep), bool), np.zeros(2), np.array([0.0]), max_gap=0.5)
    assert np.isinf(far[0])  # endpoints 40 x farther apart than max_gap: not joined


def test_rays_meet_the_floor_before_a_far_wall_and_a_near_wall_before_the_floor() -> None:
    step = math.radians(1.0)
    profile = np.full(360, 5.0)
    # a ray 30 deg down from 1.2 m reaches the floor at 2.08 m, before the wall at 5 m
    down = math.radians(30.0)
    t, floor = model_points(
        np.array([0.0]), np.array([math.cos(down)]), np.array([-math.sin(down)]), 1.2, profile, step
    )
    assert floor[0]
    assert math.isclose(float(t[0]) * math.sin(down), 1.2, rel_tol=1e-5)
    profile[:] = 1.0
    t, floor = model_points(
        np.array([0.0]), np.array([math.cos(down)]), np.array([-math.sin(down)]), 1.2, profile, step
    )
    assert not floor[0]
    assert math.isclose(float(t[0]) * math.cos(down), 1.0, rel_tol=1e-5)


def test_scan_endpoints_in_the_world() -> None:
    g = LaserGeometry(num_beams=3, angle_min=-math.pi / 2, angle_increment=math.pi / 2, max_range=10.0)
    scan = Scan(0.0, np.array([1.0, 2.0, 10.0]), g)
    ep, ok = scan_endpoints(scan, np.array([1.0, 1.0, math.pi / 2]))
    assert np.allclose(ep[:2], [[2.0, 1.0], [1.0, 3.0]])
    assert ok.tolist() == [True, True, False]


def test_back_projection_through_the_same_camera_is_the_identity() -> None:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (40, 60)).astype(np.uint8)
    fx = fy = 50.0
    cx, cy = 29.5, 19.5
    vv, uu = np.mgrid[0:40, 0:60]
    pts = (
        np.stack([(uu - cx) / fx, (vv - cy) / fy, np.ones_like(uu, float)], axis=-1).astype(np.float32) * 2.0
    )
    warped, ok = back_project(img, pts, np.eye(3), np.zeros(3), fx, fy, cx, cy)
    assert ok.all()
    assert np.allclose(warped, img, atol=1e-3)
