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

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.ceiling.rig import CeilingCamera

__all__ = ["Merit", "associate", "merit"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Merit:
    """Alg. 2's outputs per pose: ``n`` (N_P), ``error`` (epsilon_P), ``value`` (M(P), Eq. 5) and
    ``match`` ``(P, J)``: the map light associated with each detection, -1 for none."""

    n: NDArray[np.int64]
    error: FloatArray
    value: FloatArray
    match: NDArray[np.int64]


def associate(proj: FloatArray, seen: NDArray[np.bool_], detected: FloatArray, threshold: float) -> tuple[NDArray[np.int64], FloatArray]:
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
