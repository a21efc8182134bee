"""The E-step's Kalman filter over the robot's pose and its Rauch-Tung-Striebel smoother.

Burgard et al. (Sec. 2.2): "The first step (forward step) is the Extended Kalman Filter (EKF)
forward recursions. For each time instant t, it estimates the mean and covariance using an EKF.
The second step is a backward recursion": with the filtered ``mu_t, Sigma_t``, the predicted
``mu_{t+1}^-, Sigma_{t+1}^-`` and the smoothed ``t + 1``,

    S       = Sigma_t  dF_x^T  (Sigma_{t+1}^-)^-1                        (Eq. 5)
    Sigma_t = Sigma_t + S [Sigma_{t+1} - Sigma_{t+1}^-] S^T              (Eq. 3)
    mu_t    = mu_t    + S [mu_{t+1}    - mu_{t+1}^-]                     (Eq. 4)

(Rauch, Tung and Striebel 1965). The state is the pose ``(x, y, theta)``; the transition ``F``
composes the odometry increment onto it; the map lines are the dynamical system's parameters, so
a line measurement ``(alpha, r)`` of a world line ``(alpha_w, r_w)`` seen from the pose is

    alpha = alpha_w - theta,    r = r_w - x cos(alpha_w) - y sin(alpha_w),

linear in the pose (one EKF update is exact up to the normal form's sign flip).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, wrap_angle

__all__ = ["MotionNoise", "line_measurement", "line_measurements", "predict", "rts_smooth", "update"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class MotionNoise:
    """Odometry noise: standard deviations ``sigma_xy + k_xy * |translation|`` (m, each axis of
    the robot frame) and ``sigma_theta + k_theta * |rotation| + k_theta_xy * |translation|`` (rad)
    per step between scans. The paper gives none; these are the errors of the rebuilt odometry
    against the reference between consecutive scans of the CARMEN logs (Intel, ACES, FHW: about
    0.03 m + 4 % of the step, and 0.05 rad per step whatever the motion, the scans' times falling
    between odometry readings)."""

    sigma_xy: float = 0.03
    k_xy: float = 0.05
    sigma_theta: float = 0.04
    k_theta: float = 0.05
    k_theta_xy: float = 0.01


def predict(
    mean: FloatArray, cov: FloatArray, step: FloatArray, noise: MotionNoise
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """EKF prediction by the odometry increment ``step`` (robot frame): mean, covariance and the
    Jacobian ``dF_x`` of the transition with respect to the pose."""
    c, s = math.cos(mean[2]), math.sin(mean[2])
    dx, dy = float(step[0]), float(step[1])
    jac = np.array([[1.0, 0.0, -s * dx - c * dy], [0.0, 1.0, c * dx - s * dy], [0.0, 0.0, 1.0]])
    trans, rot = math.hypot(dx, dy), abs(float(wrap_angle(step[2])))
    sxy = noise.sigma_xy + noise.k_xy * trans
    sth = noise.sigma_theta + noise.k_theta * rot + noise.k_theta_xy * trans
    g = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    q = g @ np.diag([sxy**2, sxy**2, sth**2]) @ g.T
    return compose(mean, step), jac @ cov @ jac.T + q, jac


def line_measurement(
    pose: FloatArray, alpha_w: float, r_w: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The predicted robot-frame line ``(alpha, r)`` of the world line, its Jacobian ``H`` (2 x 3)
    with respect to the pose and ``J`` (2 x 2) with respect to the world line; ``r >= 0``."""
    z, h, j = line_measurements(pose, np.array([alpha_w]), np.array([r_w]))
    return z[0], h[0], j[0]


def line_measurements(
    pose: FloatArray, alpha_w: FloatArray, r_w: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`line_measurement` of many world lines at once: ``(m, 2)``, ``(m, 2, 3)``, ``(m, 2, 2)``."""
    ca, sa = np.cos(alpha_w), np.sin(alpha_w)
    alpha = alpha_w - pose[2]
    r = r_w - pose[0] * ca - pose[1] * sa
    m = len(alpha_w)
    h = np.zeros((m, 2, 3))
    h[:, 0, 2] = -1.0
    h[:, 1, 0], h[:, 1, 1] = -ca, -sa
    j = np.zeros((m, 2, 2))
    j[:, 0, 0] = j[:, 1, 1] = 1.0
    j[:, 1, 0] = pose[0] * sa - pose[1] * ca
    flip = r < 0  # the robot is on the other side of the line's origin: flip the normal
    alpha = np.where(flip, alpha + np.pi, alpha)
    r = np.abs(r)
    h[flip, 1] *= -1.0
    j[flip, 1] *= -1.0
    return np.stack([wrap_angle(alpha), r], axis=1), h, j


def update(
    mean: FloatArray, cov: FloatArray, residual: FloatArray, h: FloatArray, noise: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """A Kalman update with the stacked ``residual`` (measured minus predicted, angles wrapped),
    Jacobian ``h`` (k x 3) and measurement covariance ``noise`` (k x k); Joseph form."""
    s = h @ cov @ h.T + noise
    gain = np.linalg.solve(s, h @ cov).T
    out = mean + gain @ residual
    out[2] = float(wrap_angle(out[2]))
    ikh = np.eye(3) - gain @ h
    new = ikh @ cov @ ikh.T + gain @ noise @ gain.T
    return out, 0.5 * (new + new.T)


def rts_smooth(
    filtered: FloatArray, filtered_cov: FloatArray, predicted: FloatArray, predicted_cov: FloatArray,
    jacobians: FloatArray,
) -> tuple[FloatArray, FloatArray]:  # fmt: skip
    """The Rauch-Tung-Striebel backward recursion (Eq. 3-5): smoothed means ``(T, 3)`` and
    covariances ``(T, 3, 3)`` from the filtered ones, the predicted ones (index ``t``: the
    prediction of ``t`` from ``t - 1``; index 0 unused) and the transition Jacobians (index ``t``:
    from ``t - 1`` to ``t``)."""
    n = len(filtered)
    mean = np.array(filtered, dtype=np.float64)
    cov = np.array(filtered_cov, dtype=np.float64)
    for t in range(n - 2, -1, -1):
        gain = np.linalg.solve(predicted_cov[t + 1].T, (filtered_cov[t] @ jacobians[t + 1].T).T).T  # Eq. 5
        diff = mean[t + 1] - predicted[t + 1]
        diff[2] = float(wrap_angle(diff[2]))
        mean[t] = filtered[t] + gain @ diff  # Eq. 4
        mean[t, 2] = float(wrap_angle(mean[t, 2]))
        c = filtered_cov[t] + gain @ (cov[t + 1] - predicted_cov[t + 1]) @ gain.T  # Eq. 3
        cov[t] = 0.5 * (c + c.T)
    return mean, cov
