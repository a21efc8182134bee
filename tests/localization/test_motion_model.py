from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.geometry import compose, relative, wrap_angle
from tourbot.localization.motion_model import (
    OdometryMotionModel,
    decompose,
    sample_reference,
    sample_with_noise,
)

coord = st.floats(-20.0, 20.0, allow_nan=False)
angle = st.floats(-math.pi, math.pi, allow_nan=False)
pose = st.tuples(coord, coord, angle)


@settings(max_examples=60, deadline=None)
@given(pose, pose, st.integers(1, 40), st.integers(0, 2**31 - 1))
def test_kernel_matches_reference(odom_prev: tuple, odom_now: tuple, n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(-5, 5, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
    noise = rng.standard_normal((n, 3))
    model = OdometryMotionModel()
    fast = sample_with_noise(model, poses, odom_prev, odom_now, noise)
    ref = sample_reference(model, poses, odom_prev, odom_now, noise)
    np.testing.assert_allclose(fast[:, :2], ref[:, :2], atol=1e-9)
    assert np.all(np.abs(wrap_angle(fast[:, 2] - ref[:, 2])) < 1e-9)


@settings(max_examples=60, deadline=None)
@given(pose, pose, pose)
def test_noise_free_motion_is_the_odometry_displacement(
    start: tuple, odom_prev: tuple, odom_now: tuple
) -> None:
    model = OdometryMotionModel()
    moved = sample_with_noise(model, np.array([start]), odom_prev, odom_now, np.zeros((1, 3)))[0]
    # Without noise the robot moves by exactly the relative odometry motion, in its own frame.
    expected = compose(start, relative(np.array(odom_prev), np.array(odom_now)))
    np.testing.assert_allclose(moved[:2], expected[:2], atol=1e-6)
    assert abs(float(wrap_angle(moved[2] - expected[2]))) < 1e-6


def test_backward_motion_is_negative_translation() -> None:
    rot1, trans, rot2 = decompose((0.0, 0.0, 0.0), (-1.0, 0.0, 0.0))
    assert trans == -1.0
    assert abs(rot1) < 1e-12
    assert abs(rot2) < 1e-12


def test_sample_spread_matches_model() -> None:
    model = OdometryMotionModel()
    rng = np.random.default_rng(0)
    poses = np.zeros((20000, 3))
    out = model.sample(poses, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), rng)
    _, s_trans, _ = model.stds(0.0, 1.0, 0.0)
    assert abs(out[:, 0].mean() - 1.0) < 0.01
    assert abs(out[:, 0].std() - s_trans) < 0.01 * s_trans + 0.003
    cov = model.covariance((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    emp = np.cov(np.column_stack([out[:, 0], out[:, 1], out[:, 2]]).T)
    np.testing.assert_allclose(np.diag(emp), np.diag(cov), rtol=0.1)


def test_sample_is_reproducible_for_a_seed() -> None:
    model = OdometryMotionModel()
    poses = np.zeros((50, 3))
    a = model.sample(poses, (0, 0, 0), (0.5, 0.1, 0.2), np.random.default_rng(3))
    b = model.sample(poses, (0, 0, 0), (0.5, 0.1, 0.2), np.random.default_rng(3))
    assert np.array_equal(a, b)


def test_convolution_kernel_mean_and_mass() -> None:
    model = OdometryMotionModel()
    res, ares = 0.15, math.radians(2.0)
    heading = 0.5
    k = model.kernel((0, 0, 0), (0.9, 0.0, 0.1), res, ares, heading=heading)
    assert abs(k.weights.sum() - 1.0) < 1e-12
    t, r, c = np.meshgrid(*[np.arange(n) for n in k.weights.shape], indexing="ij")
    mean = [float((k.weights * (a + o)).sum()) for a, o in zip((t, r, c), k.offset, strict=True)]
    # The kernel's mean is the displacement of a robot heading `heading`, in cells.
    assert abs(mean[2] - 0.9 * math.cos(heading) / res) < 0.05
    assert abs(mean[1] - 0.9 * math.sin(heading) / res) < 0.05
    assert abs(mean[0] - 0.1 / ares) < 0.05


def test_convolution_kernel_agrees_with_samples() -> None:
    """The convolution form and the sampling form describe the same distribution."""
    model = OdometryMotionModel()
    res, ares = 0.15, math.radians(2.0)
    k = model.kernel((0, 0, 0), (2.0, 0.3, 0.4), res, ares, heading=0.0)
    rng = np.random.default_rng(1)
    s = model.sample(np.zeros((40000, 3)), (0, 0, 0), (2.0, 0.3, 0.4), rng)
    _, r, c = np.meshgrid(*[np.arange(n) for n in k.weights.shape], indexing="ij")
    kx = float((k.weights * (c + k.offset[2])).sum()) * res
    ky = float((k.weights * (r + k.offset[1])).sum()) * res
    var_x = float((k.weights * ((c + k.offset[2]) * res - kx) ** 2).sum())
    assert abs(kx - s[:, 0].mean()) < 0.04  # linearization ignores the shortening by heading noise
    assert abs(ky - s[:, 1].mean()) < 0.03
    # Spread agrees up to the linearization and the half-cell floor.
    assert 0.6 < var_x / s[:, 0].var() < 1.6
