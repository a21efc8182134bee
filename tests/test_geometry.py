from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from tourbot.geometry import compose, invert, relative, transform_points, wrap_angle

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
