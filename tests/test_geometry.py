from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tourbot.geometry import (
    compose,
    interpolate_pose,
    interpolate_poses,
    invert,
    relative,
    transform_points,
    wrap_angle,
)

coord = st.floats(-100, 100, allow_nan=False)
angle = st.floats(-20, 20, allow_nan=False)


def test_wrap_angle_range() -> None:
    a = wrap_angle(np.array([-np.pi, np.pi, 3 * np.pi, -3 * np.pi + 1e-9, 0.0]))
    assert np.all(a <= np.pi)
    assert np.all(a > -np.pi)
    assert np.isclose(a[0], np.pi)
    assert np.isclose(a[1], np.pi)


@given(coord, coord, angle, coord, coord, angle)
def test_compose_relative_roundtrip(x1: float, y1: float, t1: float, x2: float, y2: float, t2: float) -> None:
    a = np.array([x1, y1, t1])
    b = np.array([x2, y2, wrap_angle(t2)])
    back = compose(a, relative(a, b))
    assert np.allclose(back[:2], b[:2], atol=1e-6)
    assert abs(wrap_angle(back[2] - b[2])) < 1e-9


@given(coord, coord, angle)
def test_invert_is_identity(x: float, y: float, t: float) -> None:
    a = np.array([x, y, t])
    assert np.allclose(compose(a, invert(a)), 0.0, atol=1e-9)


def test_transform_points() -> None:
    pts = transform_points([1.0, 2.0, np.pi / 2], np.array([[1.0, 0.0]]))
    assert np.allclose(pts, [[1.0, 3.0]])


def test_interpolate_pose_turns_the_short_way_across_pi() -> None:
    a, b = (0.0, 0.0, np.pi - 0.1), (2.0, 4.0, -np.pi + 0.1)  # 0.2 rad apart across +-pi
    x, y, th = interpolate_pose(a, b, 0.25)
    assert (x, y) == pytest.approx((0.5, 1.0))
    assert float(wrap_angle(th - (np.pi - 0.05))) == pytest.approx(0.0, abs=1e-12)
    assert interpolate_pose(a, b, -1.0) == a
    assert interpolate_pose(a, b, 2.0) == b


def test_interpolate_poses_matches_one_by_one_and_clamps() -> None:
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.uniform(0.05, 0.2, 30))
    poses = np.column_stack([rng.normal(size=30), rng.normal(size=30), wrap_angle(rng.uniform(-4, 4, 30))])
    at = np.r_[times[0] - 1.0, rng.uniform(times[0], times[-1], 50), times[7], times[-1] + 1.0]
    out = interpolate_poses(times, poses, at)
    for t, got in zip(at, out, strict=True):
        i = int(np.clip(np.searchsorted(times, t), 1, len(times) - 1))
        f = (t - times[i - 1]) / (times[i] - times[i - 1])
        want = interpolate_pose(tuple(poses[i - 1]), tuple(poses[i]), f)
        assert got[:2] == pytest.approx(want[:2], abs=1e-12)
        assert float(wrap_angle(got[2] - want[2])) == pytest.approx(0.0, abs=1e-12)
    assert np.array_equal(out[-2], poses[7])  # a reading's own time gives the reading
    assert np.array_equal(out[0], poses[0])
    assert np.allclose(out[-1], poses[-1])
