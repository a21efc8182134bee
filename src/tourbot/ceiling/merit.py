"""The merit function of a pose (Gamallo et al., Sec. IV-A, Alg. 2 and Eq. 5).

For a pose P the ceiling map projection Map(P) (Alg. 1) is compared with the detected lights. A
detected light ``B_j`` and a projected light ``Proj(B_i^P)`` are associated when (Sec. IV-A):

1. ``|B_j - Proj(B_i^P)| <= THRESHOLD``;
2. ``B_j`` is the detection nearest to ``Proj(B_i^P)``;
3. the association is unique (``B_j`` is associated with its nearest projection only).

Each association adds its pixel error to ``epsilon_P`` and one to ``N_P``; each detection left
without an association adds ``THRESHOLD`` to ``epsilon_P`` (Alg. 2's else branch). The merit is
``M(P) = epsilon_P / N_P`` (Eq. 5), infinite when nothing is associated; lower is better.

Everything is vectorised over poses: ``(P, I, J)`` distances between the I map lights and the J
detections, a few thousand poses in one call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.ceiling.rig import CeilingCamera

__all__ = ["Merit", "associate", "merit", "merit_fast", "merit_kernel"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Merit:
    """Alg. 2's outputs per pose: ``n`` (N_P), ``error`` (epsilon_P), ``value`` (M(P), Eq. 5) and
    ``match`` ``(P, J)``: the map light associated with each detection, -1 for none."""

    n: NDArray[np.int64]
    error: FloatArray
    value: FloatArray
    match: NDArray[np.int64]


def associate(
    proj: FloatArray, seen: NDArray[np.bool_], detected: FloatArray, threshold: float
) -> tuple[NDArray[np.int64], FloatArray]:
    """The associations of Sec. IV-A's conditions 1-3 for projections ``(P, I, 2)`` (``seen``
    ``(P, I)``) and detections ``(J, 2)``: per pose and detection, the map light (or -1) and the
    pixel distance to it."""
    p, i_n = proj.shape[:2]
    j_n = len(detected)
    if j_n == 0 or i_n == 0:
        return np.full((p, j_n), -1, dtype=np.int64), np.full((p, j_n), np.inf)
    diff = proj[:, :, None, :] - detected[None, None, :, :]
    dist = np.sqrt(np.einsum("pijk,pijk->pij", diff, diff))
    dist = np.where(seen[:, :, None], dist, np.inf)
    nearest_det = np.argmin(dist, axis=2)  # condition 2: per map light, its nearest detection
    nearest_map = np.argmin(dist, axis=1)  # condition 3: per detection, its nearest map light
    d_jm = np.take_along_axis(dist, nearest_map[:, None, :], axis=1)[:, 0, :]
    mutual = np.take_along_axis(nearest_det, nearest_map, axis=1) == np.arange(j_n)[None, :]
    ok = mutual & (d_jm <= threshold)  # condition 1
    return np.where(ok, nearest_map, -1).astype(np.int64), np.where(ok, d_jm, np.inf)


def merit(
    camera: CeilingCamera,
    lights: ArrayLike,
    detected: ArrayLike,
    poses: ArrayLike,
    threshold: float,
    swing: tuple[float, float] = (0.0, 0.0),
) -> Merit:
    """Alg. 2 and Eq. 5 for each pose ``(P, 3)``."""
    det = np.asarray(detected, dtype=np.float64).reshape(-1, 2)
    proj, seen = camera.project_lights(poses, lights, swing)
    match, dist = associate(proj, seen, det, threshold)
    matched = match >= 0
    n = matched.sum(axis=1).astype(np.int64)
    err = np.where(matched, dist, threshold).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        value = np.where(n > 0, err / np.maximum(n, 1), np.inf)
    return Merit(n=n, error=err, value=value, match=match)


def merit_fast(
    camera: CeilingCamera, lights: ArrayLike, detected: ArrayLike, poses: ArrayLike, threshold: float
) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """``(N_P, epsilon_P, M(P))`` of :func:`merit` (no swing) by the compiled :func:`merit_kernel`."""
    kind, params, aspect = camera.model.radial()
    rot, t = camera.mount()
    cu, cv = camera.model.centre()
    return merit_kernel(
        np.ascontiguousarray(poses, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(lights, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(detected, dtype=np.float64).reshape(-1, 2),
        np.ascontiguousarray(rot),
        np.ascontiguousarray(t),
        kind,
        params,
        cu,
        cv,
        aspect,
        camera.model.max_theta,
        camera.rim_theta,
        float(camera.width),
        float(camera.height),
        float(threshold),
    )


@numba.njit(cache=True)
def _radius(kind: int, p: FloatArray, theta: float) -> float:
    if kind == 0:  # Eq. 1
        return p[0] * math.tan(theta / p[1]) + p[2] * math.sin(theta / p[3])
    t2 = theta * theta
    return p[0] * theta * (1.0 + t2 * (p[1] + t2 * (p[2] + t2 * (p[3] + t2 * p[4]))))


@numba.njit(cache=True)
def merit_kernel(
    poses: FloatArray,
    lights: FloatArray,
    det: FloatArray,
    rot: FloatArray,
    t: FloatArray,
    kind: int,
    params: FloatArray,
    cu: float,
    cv: float,
    aspect: float,
    max_theta: float,
    rim_theta: float,
    width: float,
    height: float,
    threshold: float,
) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """Alg. 1, Alg. 2 and Eq. 5 pose by pose; the numpy reference is :func:`merit`."""
    n_p, n_i, n_j = poses.shape[0], lights.shape[0], det.shape[0]
    count = np.zeros(n_p, dtype=np.int64)
    error = np.zeros(n_p)
    value = np.full(n_p, np.inf)
    pu = np.empty(n_i)
    pv = np.empty(n_i)
    seen = np.zeros(n_i, dtype=np.bool_)
    dist = np.empty((n_i, n_j))
    cos_rim = math.cos(rim_theta)
    for p in range(n_p):
        c, s = math.cos(poses[p, 2]), math.sin(poses[p, 2])
        for i in range(n_i):
            dx = lights[i, 0] - poses[p, 0]
            dy = lights[i, 1] - poses[p, 1]
            v0 = c * dx + s * dy - t[0]
            v1 = -s * dx + c * dy - t[1]
            v2 = lights[i, 2] - t[2]
            norm = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
            x = v0 * rot[0, 0] + v1 * rot[1, 0] + v2 * rot[2, 0]
            y = v0 * rot[0, 1] + v1 * rot[1, 1] + v2 * rot[2, 1]
            z = v0 * rot[0, 2] + v1 * rot[1, 2] + v2 * rot[2, 2]
            seen[i] = False
            if norm <= 0.0 or v2 / norm < cos_rim:
                continue
            rho = math.sqrt(x * x + y * y)
            theta = math.atan2(rho, z)
            if theta > max_theta:
                continue
            r = _radius(kind, params, theta)
            cphi, sphi = (x / rho, y / rho) if rho > 0.0 else (1.0, 0.0)
            u = cu + r * cphi
            w = cv + aspect * r * sphi
            if u < 0.0 or u > width - 1 or w < 0.0 or w > height - 1:
                continue
            pu[i], pv[i], seen[i] = u, w, True
        for i in range(n_i):
            for j in range(n_j):
                if seen[i]:
                    du, dv = pu[i] - det[j, 0], pv[i] - det[j, 1]
                    dist[i, j] = math.sqrt(du * du + dv * dv)
                else:
                    dist[i, j] = np.inf
        n = 0
        err = 0.0
        for j in range(n_j):
            best_i, best = -1, np.inf
            for i in range(n_i):
                if dist[i, j] < best:
                    best, best_i = dist[i, j], i
            ok = best_i >= 0 and best <= threshold
            if ok:
                for jj in range(n_j):  # condition 2: j is the nearest detection of light best_i
                    if dist[best_i, jj] < best or (dist[best_i, jj] == best and jj < j):
                        ok = False
                        break
            if ok:
                err += best
                n += 1
            else:
                err += threshold
        count[p] = n
        error[p] = err
        if n > 0:
            value[p] = err / n
    return count, error, value
