"""KLD-sampling: the number of samples that keeps the sample-based belief close to the true one.

Fox 2003, "Adapting the sample size in particle filters through KLD-sampling" (also Fox 2001,
Probabilistic Robotics Table 4.4's companion, Table 8.4): samples are drawn until their count
reaches the bound of Eq. 13 for the number ``k`` of histogram bins they occupy.
"""

from __future__ import annotations

import functools
import math
from statistics import NormalDist

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["bin_keys", "kld_bounds", "kld_sample_count"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def bin_keys(samples: FloatArray, cell: float, cell_theta: float) -> tuple[IntArray, int, int]:
    """Integer bins ``(ix, iy, it)`` of ``cell x cell x cell_theta`` packed in one key per sample
    (all >= 0, with a free margin of one bin), with the strides ``ny`` and ``n_theta``."""
    return _bin_keys_kernel(np.ascontiguousarray(samples, dtype=np.float64), cell, cell_theta)


@numba.njit(cache=True)
def _bin_keys_kernel(samples: FloatArray, cell: float, cell_theta: float) -> tuple[IntArray, int, int]:
    n = samples.shape[0]
    n_th = max(1, round(2.0 * math.pi / cell_theta))
    ix = np.empty(n, np.int64)
    iy = np.empty(n, np.int64)
    it = np.empty(n, np.int64)
    for i in range(n):
        ix[i] = math.floor(samples[i, 0] / cell)
        iy[i] = math.floor(samples[i, 1] / cell)
        t = math.floor((samples[i, 2] + math.pi) / (2.0 * math.pi) * n_th) % n_th
        it[i] = t
    x0 = ix.min() - 1 if n else 0
    y0 = iy.min() - 1 if n else 0
    ny = (iy.max() - y0 + 2) if n else 1
    keys = np.empty(n, np.int64)
    for i in range(n):
        keys[i] = ((ix[i] - x0) * ny + (iy[i] - y0)) * n_th + it[i]
    return keys, ny, n_th


def kld_bounds(k_max: int, epsilon: float, quantile: float) -> IntArray:
    """Fox 2003, Eq. 13, for ``k = 0 .. k_max``: samples needed so that, with probability
    ``quantile``, the KL divergence between the sample-based and the true belief stays below
    ``epsilon`` when the samples fall in ``k`` bins."""
    z = NormalDist().inv_cdf(quantile)
    k = np.arange(k_max + 1, dtype=np.float64)
    km1 = np.maximum(k - 1.0, 1.0)
    a = 2.0 / (9.0 * km1)
    n = np.ceil(km1 / (2.0 * epsilon) * (1.0 - a + np.sqrt(a) * z) ** 3)
    return np.where(k <= 1, 1, n).astype(np.int64)


@functools.lru_cache(maxsize=8)
def _kld_bounds_cached(k_max: int, epsilon: float, quantile: float) -> IntArray:
    return kld_bounds(k_max, epsilon, quantile)


@numba.njit(cache=True)
def _kld_count_kernel(keys: IntArray, bounds: IntArray, n_min: int, n_max: int) -> int:
    seen = set()
    seen.add(keys[0])
    k = 1
    for i in range(1, keys.shape[0]):
        if keys[i] not in seen:
            seen.add(keys[i])
            k += 1
        n = i + 1
        if n >= n_min and n >= bounds[min(k, bounds.shape[0] - 1)]:
            return n
        if n >= n_max:
            return n_max
    return keys.shape[0]


def kld_sample_count(
    drawn: FloatArray,
    kld_bin: tuple[float, float, float],
    epsilon: float,
    quantile: float,
    n_min: int,
    n_max: int,
) -> int:
    """KLD-sampling (Fox 2003, Table 1): how many of the samples ``drawn`` (in random order) to keep.

    Walks the samples, counting occupied bins ``k``, and stops as soon as the count reaches the
    bound of Eq. 13 for ``k`` (and ``n_min``), or ``n_max``.
    """
    n = drawn.shape[0]
    if n == 0:
        return 0
    keys, _, _ = bin_keys(drawn, kld_bin[0], kld_bin[2])
    bounds = _kld_bounds_cached(n + 1, epsilon, quantile)
    return int(min(_kld_count_kernel(keys, bounds, n_min, min(n, n_max)), n))
