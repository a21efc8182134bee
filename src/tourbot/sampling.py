"""Systematic (low-variance) resampling, the one resampler of the project.

Probabilistic Robotics (Thrun, Burgard & Fox 2005), Table 4.4: one uniform number ``u0`` in
``[0, 1)`` places ``n`` equally spaced pointers ``(u0 + i) / n`` of the total weight; the ``i``-th
draw is the sample whose cumulative weight first exceeds the ``i``-th pointer. Used by Monte Carlo
localization (:mod:`tourbot.localization.mcl`) and by the people tracker's bootstrap step
(:mod:`tourbot.people.association`).
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "systematic_resample",
    "systematic_resample_reference",
    "systematic_resample_rows",
    "systematic_resample_rows_reference",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@numba.njit(cache=True)
def _systematic_kernel(weights: FloatArray, n: int, u0: float, out: IntArray) -> None:
    m = weights.shape[0]
    total = 0.0
    for j in range(m):
        total += weights[j]
    step = total / n
    c = weights[0]
    j = 0
    for i in range(n):
        u = (u0 + i) * step
        while u >= c and j < m - 1:
            j += 1
            c += weights[j]
        out[i] = j


def systematic_resample(weights: ArrayLike, n: int, u0: float) -> IntArray:
    """``n`` indices drawn by ``weights`` (any positive total) with the one uniform ``u0`` in
    ``[0, 1)``. A numba kernel; :func:`systematic_resample_reference` is its numpy reference."""
    w = np.ascontiguousarray(weights, dtype=np.float64).ravel()
    out = np.empty(n, dtype=np.int64)
    if n and w.size:
        _systematic_kernel(w, n, float(u0), out)
    return out


def systematic_resample_reference(weights: ArrayLike, n: int, u0: float) -> IntArray:
    """Plain-numpy reference of :func:`systematic_resample`."""
    w = np.asarray(weights, dtype=np.float64).ravel()
    cum = np.cumsum(w)
    pointers = (u0 + np.arange(n)) * (cum[-1] / n)
    cum[-1] = np.inf  # the last sample takes whatever rounding leaves over
    return np.asarray(np.searchsorted(cum, pointers, side="right"), dtype=np.int64)


def systematic_resample_rows(weights: ArrayLike, offsets: ArrayLike) -> IntArray:
    """Row-wise :func:`systematic_resample`: ``(K, N)`` indices, row ``k`` drawn by ``weights[k]``
    with the uniform ``offsets[k]`` (one particle set per row, e.g. one per tracked person)."""
    w = np.ascontiguousarray(weights, dtype=np.float64)
    u = np.asarray(offsets, dtype=np.float64).ravel()
    k, n = w.shape
    out = np.empty((k, n), dtype=np.int64)
    for r in range(k):
        if n:
            _systematic_kernel(w[r], n, float(u[r]), out[r])
    return out


def systematic_resample_rows_reference(weights: ArrayLike, offsets: ArrayLike) -> IntArray:
    """Plain-numpy reference of :func:`systematic_resample_rows`."""
    w = np.asarray(weights, dtype=np.float64)
    u = np.asarray(offsets, dtype=np.float64).ravel()
    return np.array(
        [systematic_resample_reference(w[r], w.shape[1], float(u[r])) for r in range(w.shape[0])],
        dtype=np.int64,
    ).reshape(w.shape)
