"""Scan-to-map alignment by hill climbing on a smoothed occupancy map (Burgard et al., Sec. 2.1).

The pose of scan ``t`` maximizes (Eq. 1)

    p(s_t | l_t, m(l^{t-1}, s^{t-1})) * p(l_t | u_{t-1}, l_{t-1})

The first factor is read from a map "computed integrating over small Gaussian errors in the robot
pose", which makes it smooth: the occupied cells blurred with a Gaussian kernel
(:class:`SmoothedMap`); each beam endpoint contributes ``w * log(eps + field(endpoint))``
(``w < 1`` accounts for neighbouring beams not being independent). The second factor is a
Gaussian around the pose predicted by odometry, its spread growing with the motion. The maximum is
found by hill climbing (:func:`hill_climb`): try a step along each of x, y and theta in both
directions, take the best improvement, halve the steps when none improves; coarse-to-fine over
a stack of smoothing widths.

How certain the alignment is, direction by direction, is the curvature of the objective at its
best (:func:`curvature`): a scan of a corridor's two walls scores the same anywhere along it, so
the curvature, the information of the match, is large across the corridor and near zero along it
(the covariance as the inverse Hessian of the matching cost at the optimum: Censi, "An accurate
closed-form estimate of ICP's covariance", ICRA 2007; Olson, "Real-time correlative scan
matching", ICRA 2009, from the cost surface around the best match).

:func:`score_reference` is the plain-numpy twin of the numba score kernel, compared by property
tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "MatchParams",
    "curvature",
    "hill_climb",
    "score",
    "score_reference",
]

FloatArray = NDArray[np.float64]
Float32Array = NDArray[np.float32]


@dataclass(frozen=True)
class MatchParams:
    """Parameters of the alignment (Burgard et al. Sec. 2.1; values tuned on the Intel log).

    ``beam_weight`` scales each beam's log likelihood (beams are not independent);
    ``eps`` is the floor of the smoothed map (a beam ending in free space is unlikely, not
    impossible). The odometry prior has standard deviations ``sigma_xy + k_xy * |translation|``
    and ``sigma_theta + k_theta * |rotation| + k_theta_xy * |translation|``.
    ``steps`` are the initial hill-climbing steps (m, m, rad); ``halvings`` how often they halve.
    """

    beam_weight: float = 0.5
    eps: float = 0.02
    sigma_xy: float = 0.05
    k_xy: float = 0.05
    sigma_theta: float = 0.02
    k_theta: float = 0.3
    k_theta_xy: float = 0.1
    steps: tuple[float, float, float] = (0.1, 0.1, 0.05)
    halvings: int = 6
    max_iterations: int = 200


@numba.njit(cache=True)
def _field_at(field: np.ndarray, gx: float, gy: float) -> float:
    """Bilinear interpolation of ``field`` at continuous cell coordinates (cell centres at +0.5),
    capped at 1 (where walls meet, their smoothed values add up)."""
    rows, cols = field.shape
    fx = gx - 0.5
    fy = gy - 0.5
    c0 = math.floor(fx)
    r0 = math.floor(fy)
    if c0 < 0 or r0 < 0 or c0 + 1 >= cols or r0 + 1 >= rows:
        return 0.0
    ax = fx - c0
    ay = fy - r0
    v00 = field[r0, c0]
    v01 = field[r0, c0 + 1]
    v10 = field[r0 + 1, c0]
    v11 = field[r0 + 1, c0 + 1]
    v = (v00 * (1.0 - ax) + v01 * ax) * (1.0 - ay) + (v10 * (1.0 - ax) + v11 * ax) * ay
    return min(v, 1.0)


@numba.njit(cache=True)
def _score(
    field: np.ndarray,
    inv_res: float,
    x: float,
    y: float,
    theta: float,
    ex: np.ndarray,
    ey: np.ndarray,
    weights: np.ndarray,
    eps: float,
) -> float:
    c = math.cos(theta)
    s = math.sin(theta)
    total = 0.0
    for j in range(ex.shape[0]):
        wx = x + c * ex[j] - s * ey[j]
        wy = y + s * ex[j] + c * ey[j]
        v = _field_at(field, wx * inv_res, wy * inv_res)
        total += weights[j] * math.log(eps + (1.0 - eps) * v)
    return total


def score(
    field: Float32Array,
    resolution: float,
    pose: FloatArray,
    endpoints: FloatArray,
    weights: FloatArray,
    eps: float,
) -> float:
    """Weighted log likelihood of scan ``endpoints`` (robot frame, ``(B, 2)``) at ``pose``.

    ``pose`` is in the field's frame (metres, origin at the corner of cell (0, 0)); the field is
    read with bilinear interpolation and is 0 outside the grid.
    """
    return float(
        _score(
            field,
            1.0 / resolution,
            float(pose[0]),
            float(pose[1]),
            float(pose[2]),
            np.ascontiguousarray(endpoints[:, 0], dtype=np.float64),
            np.ascontiguousarray(endpoints[:, 1], dtype=np.float64),
            np.ascontiguousarray(weights, dtype=np.float64),
            eps,
        )
    )


def score_reference(
    field: Float32Array,
    resolution: float,
    pose: FloatArray,
    endpoints: FloatArray,
    weights: FloatArray,
    eps: float,
) -> float:
    """Plain-numpy twin of :func:`score`."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    wx = pose[0] + c * endpoints[:, 0] - s * endpoints[:, 1]
    wy = pose[1] + s * endpoints[:, 0] + c * endpoints[:, 1]
    fx = wx / resolution - 0.5
    fy = wy / resolution - 0.5
    c0 = np.floor(fx).astype(np.int64)
    r0 = np.floor(fy).astype(np.int64)
    rows, cols = field.shape
    ok = (c0 >= 0) & (r0 >= 0) & (c0 + 1 < cols) & (r0 + 1 < rows)
    ax, ay = fx - c0, fy - r0
    v = np.zeros(len(wx))
    r, c_ = r0[ok], c0[ok]
    f = field.astype(np.float64)
    v[ok] = (f[r, c_] * (1 - ax[ok]) + f[r, c_ + 1] * ax[ok]) * (1 - ay[ok]) + (
        f[r + 1, c_] * (1 - ax[ok]) + f[r + 1, c_ + 1] * ax[ok]
    ) * ay[ok]
    v = np.minimum(v, 1.0)
    return float(np.sum(weights * np.log(eps + (1.0 - eps) * v)))


@numba.njit(cache=True)
def _objective(
    field: np.ndarray,
    inv_res: float,
    x: float,
    y: float,
    theta: float,
    ex: np.ndarray,
    ey: np.ndarray,
    weights: np.ndarray,
    eps: float,
    prior: np.ndarray,
    inv_sigma: np.ndarray,
) -> float:
    dx = (x - prior[0]) * inv_sigma[0]
    dy = (y - prior[1]) * inv_sigma[1]
    dth = theta - prior[2]
    dth = math.atan2(math.sin(dth), math.cos(dth)) * inv_sigma[2]
    return _score(field, inv_res, x, y, theta, ex, ey, weights, eps) - 0.5 * (dx * dx + dy * dy + dth * dth)


@numba.njit(cache=True)
def _hill_climb(
    field: np.ndarray,
    inv_res: float,
    start: np.ndarray,
    ex: np.ndarray,
    ey: np.ndarray,
    weights: np.ndarray,
    eps: float,
    prior: np.ndarray,
    inv_sigma: np.ndarray,
    steps: np.ndarray,
    halvings: int,
    max_iterations: int,
) -> tuple[np.ndarray, float]:
    best = start.copy()
    best_val = _objective(field, inv_res, best[0], best[1], best[2], ex, ey, weights, eps, prior, inv_sigma)
    step = steps.copy()
    halved = 0
    it = 0
    while halved <= halvings and it < max_iterations:
        it += 1
        cand_best = best_val
        cand = best.copy()
        for k in range(3):
            for sign in (-1.0, 1.0):
                trial = best.copy()
                trial[k] += sign * step[k]
                v = _objective(
                    field, inv_res, trial[0], trial[1], trial[2], ex, ey, weights, eps, prior, inv_sigma
                )
                if v > cand_best:
                    cand_best = v
                    cand = trial
        if cand_best > best_val:
            best = cand
            best_val = cand_best
        else:
            step *= 0.5
            halved += 1
    return best, best_val


def hill_climb(
    field: Float32Array,
    resolution: float,
    start: FloatArray,
    endpoints: FloatArray,
    weights: FloatArray,
    prior: FloatArray,
    prior_sigma: FloatArray,
    params: MatchParams,
    steps_scale: float = 1.0,
    halvings: int | None = None,
) -> tuple[FloatArray, float]:
    """The pose (field frame) maximizing map likelihood times the odometry prior, from ``start``.

    ``halvings`` overrides ``params.halvings`` (a coarse level needs less precision).
    """
    best, val = _hill_climb(
        field,
        1.0 / resolution,
        np.asarray(start, dtype=np.float64).copy(),
        np.ascontiguousarray(endpoints[:, 0], dtype=np.float64),
        np.ascontiguousarray(endpoints[:, 1], dtype=np.float64),
        np.ascontiguousarray(weights, dtype=np.float64),
        params.eps,
        np.asarray(prior, dtype=np.float64),
        1.0 / np.asarray(prior_sigma, dtype=np.float64),
        np.asarray(params.steps, dtype=np.float64) * steps_scale,
        params.halvings if halvings is None else halvings,
        params.max_iterations,
    )
    # wrapped as the numba objective wraps (atan2 of sin and cos); tourbot.geometry.wrap_angle
    # rounds differently in the last bit, which moved the mapping figures by 1e-15 (issue 14)
    best[2] = math.atan2(math.sin(best[2]), math.cos(best[2]))
    return best, float(val)


def _quadratic_design() -> tuple[FloatArray, FloatArray]:
    """The 27 offsets of the ``{-1, 0, 1}^3`` stencil and the pseudo-inverse of the design matrix
    of ``f(u) = c + g.u + 1/2 u^T A u`` over them (10 coefficients: c, g, A's diagonal, A's upper
    triangle)."""
    k = np.array([-1.0, 0.0, 1.0])
    u = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)
    design = np.column_stack(
        [
            np.ones(len(u)),
            u,
            0.5 * u**2,
            u[:, 0] * u[:, 1],
            u[:, 0] * u[:, 2],
            u[:, 1] * u[:, 2],
        ]
    )
    return u, np.linalg.pinv(design)


_STENCIL, _FIT = _quadratic_design()


def curvature(
    field: Float32Array,
    resolution: float,
    pose: FloatArray,
    endpoints: FloatArray,
    weights: FloatArray,
    eps: float,
    steps: FloatArray,
) -> FloatArray:
    """The information (negative Hessian, ``(3, 3)``, in ``x, y, theta`` of the field's frame) of
    the score (:func:`score`) at ``pose``: the Laplace approximation of the match's uncertainty,
    its covariance the inverse (Censi 2007; Olson 2009).

    The Hessian is the second-order term of a least-squares quadratic fit of the score over the
    27 poses ``pose + u * steps``, ``u`` in ``{-1, 0, 1}^3`` (a fit over a whole cell rather than a
    finite difference: the bilinearly interpolated field is piecewise linear inside a cell). A
    direction in which the score does not fall off (a negative curvature, from noise or a ridge)
    gets no information: the matrix is projected onto the positive semidefinite ones.
    """
    h = np.asarray(steps, dtype=np.float64)
    base = np.asarray(pose, dtype=np.float64)
    values = np.array([score(field, resolution, base + u * h, endpoints, weights, eps) for u in _STENCIL])
    coef = _FIT @ values
    a = np.empty((3, 3))
    a[0, 0], a[1, 1], a[2, 2] = coef[4:7]
    a[0, 1] = a[1, 0] = coef[7]
    a[0, 2] = a[2, 0] = coef[8]
    a[1, 2] = a[2, 1] = coef[9]
    hess = -a / np.outer(h, h)
    vals, vecs = np.linalg.eigh(hess)
    return np.asarray((vecs * np.maximum(vals, 0.0)) @ vecs.T, dtype=np.float64)
