from __future__ import annotations

import math

import numpy as np

from tourbot.geometry import relative
from tourbot.mapping.features.smoother import MotionNoise, line_measurement, predict, rts_smooth, update


def test_line_measurement_matches_the_geometry() -> None:
    rng = np.random.default_rng(0)
    for _ in range(50):
        pose = rng.uniform([-5, -5, -math.pi], [5, 5, math.pi])
        alpha_w, r_w = rng.uniform(-math.pi, math.pi), rng.uniform(0.5, 10.0)
        z, h, _ = line_measurement(pose, alpha_w, r_w)
        # a point of the world line, seen from the pose, lies on the measured line
        n = np.array([math.cos(alpha_w), math.sin(alpha_w)])
        p = r_w * n + 3.0 * np.array([-n[1], n[0]])
        local = relative(pose, np.array([p[0], p[1], 0.0]))[:2]
        assert abs(local @ np.array([math.cos(z[0]), math.sin(z[0])]) - z[1]) < 1e-9
        assert z[1] >= 0
        # the Jacobian by finite differences
        eps = 1e-6
        for k in range(3):
            d = np.zeros(3)
            d[k] = eps
            z2, _, _ = line_measurement(pose + d, alpha_w, r_w)
            diff = (z2 - z) / eps
            diff[0] = math.remainder(diff[0] * eps, 2 * math.pi) / eps
            assert np.allclose(diff, h[:, k], atol=1e-4)


def test_rts_smoother_is_exact_on_a_linear_chain() -> None:
    """A straight drive (F = identity in x) with one absolute fix at the end: the smoothed poses
    equal the batch least-squares answer."""
    noise = MotionNoise(sigma_xy=0.1, k_xy=0.0, sigma_theta=1e-3, k_theta=0.0, k_theta_xy=0.0)
    n = 6
    step = np.array([1.0, 0.0, 0.0])
    mean, cov = np.zeros(3), np.eye(3) * 1e-10
    filt, fcov, pred, pcov, jac = [mean], [cov], [mean], [cov], [np.eye(3)]
    for t in range(1, n):
        mean, cov, f = predict(mean, cov, step, noise)
        pred.append(mean)
        pcov.append(cov)
        jac.append(f)
        if t == n - 1:  # an absolute fix of x 0.5 m ahead of the odometry
            mean, cov = update(mean, cov, np.array([0.5]), np.array([[1.0, 0.0, 0.0]]), np.array([[0.01]]))
        filt.append(mean)
        fcov.append(cov)
    smooth, _ = rts_smooth(np.array(filt), np.array(fcov), np.array(pred), np.array(pcov), np.array(jac))
    # batch: x_t = t + c t (equal random-walk steps share the correction), c from the fix
    q, r = 0.1**2, 0.01
    c = 0.5 * (n - 1) * q / ((n - 1) * q + r) / (n - 1)
    assert np.allclose(smooth[:, 0], np.arange(n) * (1.0 + c), atol=1e-6)
