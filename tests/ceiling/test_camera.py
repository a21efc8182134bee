"""Camera models: round trips, the paper's radial law, and agreement with ``cv2.fisheye``."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.ceiling.camera import KannalaBrandt, PajdlaBakstein, Pinhole, fit_pajdla_bakstein

KB = KannalaBrandt(fx=193.2595, fy=192.6833, cx=347.8275, cy=245.5299, k1=0.0092507)


def _rays(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)


@given(
    theta=st.floats(0.0, math.radians(92.0)),
    phi=st.floats(-math.pi, math.pi),
    dist=st.floats(0.1, 50.0),
)
@settings(max_examples=100, deadline=None)
def test_pajdla_bakstein_round_trip(theta: float, phi: float, dist: float) -> None:
    cam = PajdlaBakstein(beta=1.02)
    p = dist * _rays(np.array([theta]), np.array([phi]))
    uv, valid = cam.project(p)
    assert valid.all()
    back = cam.unproject(uv)
    assert np.allclose(back, p / dist, atol=1e-7)


def test_pajdla_bakstein_is_eq_1_and_2() -> None:
    cam = PajdlaBakstein(a=150.0, b=2.0, c=40.0, d=2.0, u0=320.0, v0=240.0, beta=1.1)
    theta, phi = 0.7, 0.4
    r = 150.0 * math.tan(theta / 2.0) + 40.0 * math.sin(theta / 2.0)
    uv, _ = cam.project(_rays(np.array([theta]), np.array([phi])))
    assert uv[0] == pytest.approx([320.0 + r * math.cos(phi), 240.0 + 1.1 * r * math.sin(phi)])
    # beyond the field of view: flagged, not imaged
    _, valid = cam.project(_rays(np.array([math.radians(100.0)]), np.array([0.0])))
    assert not valid[0]


def test_non_monotonic_radial_law_refused() -> None:
    with pytest.raises(ValueError, match="increase"):
        PajdlaBakstein(a=-200.0, c=10.0)


@given(theta=st.floats(0.0, math.radians(90.0)), phi=st.floats(-math.pi, math.pi))
@settings(max_examples=100, deadline=None)
def test_kannala_brandt_round_trip(theta: float, phi: float) -> None:
    p = _rays(np.array([theta]), np.array([phi]))
    uv, _ = KB.project(p)
    assert np.allclose(KB.unproject(uv), p, atol=1e-7)


def test_kannala_brandt_agrees_with_cv2_fisheye() -> None:
    rng = np.random.default_rng(0)
    theta = rng.uniform(0.0, math.radians(85.0), 500)
    phi = rng.uniform(-math.pi, math.pi, 500)
    pts = _rays(theta, phi) * rng.uniform(1.0, 20.0, (500, 1))
    k, d = KB.opencv()
    ref, _ = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), k, d)
    uv, _ = KB.project(pts)
    assert np.abs(uv - ref.reshape(-1, 2)).max() < 1e-6
    # and unproject agrees with cv2.fisheye.undistortPoints (normalized coordinates x/z, y/z)
    front = theta < math.radians(80.0)
    und = cv2.fisheye.undistortPoints(uv[front].reshape(-1, 1, 2), k, d).reshape(-1, 2)
    rays = KB.unproject(uv[front])
    assert np.abs(rays[:, :2] / rays[:, 2:3] - und).max() < 1e-4


def test_pajdla_bakstein_fitted_to_kannala_brandt_agrees_with_cv2() -> None:
    pb = fit_pajdla_bakstein(KB)
    rng = np.random.default_rng(1)
    theta = rng.uniform(0.0, math.radians(88.0), 400)
    phi = rng.uniform(-math.pi, math.pi, 400)
    pts = _rays(theta, phi)
    k, d = KB.opencv()
    ref, _ = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), k, d)
    uv, _ = pb.project(pts)
    assert np.abs(uv - ref.reshape(-1, 2)).max() < 0.5  # pixels
    assert pb.beta == pytest.approx(KB.fy / KB.fx)


def test_pinhole_projects_and_unprojects() -> None:
    cam = Pinhole(fx=500.0, fy=500.0, cx=320.0, cy=240.0)
    p = np.array([[0.5, -0.2, 2.0], [0.0, 0.0, 1.0]])
    uv, valid = cam.project(p)
    assert valid.all()
    assert uv[0] == pytest.approx([320.0 + 125.0, 240.0 - 50.0])
    assert np.allclose(cam.unproject(uv), p / np.linalg.norm(p, axis=1, keepdims=True))
    _, behind = cam.project(np.array([[0.0, 0.0, -1.0]]))
    assert not behind[0]
