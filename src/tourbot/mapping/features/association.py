"""Data association of a scan's segments to the map's by dynamic-programming string search.

Burgard et al. (Sec. 2.2) match features "based on a dynamic programming string-search algorithm
(Baltzakis and Trahanias 2002). This algorithm exploits information contained in the spatial
ordering of the features": the scan's segments, in their angular order, and the map lines that
should be in view, predicted into the robot frame and put in the same order, are two strings;
a match is an order-preserving pairing of the two (a crossing pairing is impossible for a laser
sweeping once around the robot). The best pairing maximises the summed pair gains by the edit
distance recursion

    D[i, j] = max(D[i-1, j], D[i, j-1], D[i-1, j-1] + g(i, j)),

``O(n m)`` for ``n`` scan and ``m`` map features, with ``g(i, j) = gate - d2(i, j)`` for a pair
whose squared Mahalanobis distance ``d2`` of ``(alpha, r)`` is inside the chi-square ``gate`` and
whose extents overlap, and no pairing otherwise.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["string_match", "string_match_reference"]

FloatArray = NDArray[np.float64]


def string_match(gain: FloatArray) -> list[tuple[int, int]]:
    """The order-preserving pairing ``[(i, j), ...]`` (both increasing) of maximum total gain.

    ``gain`` ``(n, m)``: the gain of pairing scan feature ``i`` with map feature ``j``; ``-inf``
    (or any value <= 0) where they cannot be paired.
    """
    g = np.asarray(gain, dtype=np.float64)
    n, m = g.shape
    if n == 0 or m == 0:
        return []
    d = np.zeros((n + 1, m + 1))
    for i in range(1, n + 1):
        row, prev = d[i], d[i - 1]
        gi = g[i - 1]
        diag = prev[:-1] + np.where(gi > 0, gi, -np.inf)
        best = np.maximum(prev[1:], diag)
        # the left neighbour of the same row: a running maximum along the row
        row[1:] = np.maximum.accumulate(best)
    pairs: list[tuple[int, int]] = []
    i, j = n, m
    while i > 0 and j > 0:
        if d[i, j] == d[i - 1, j]:
            i -= 1
        elif d[i, j] == d[i, j - 1]:
            j -= 1
        else:
            pairs.append((i - 1, j - 1))
            i, j = i - 1, j - 1
    return pairs[::-1]


def string_match_reference(gain: FloatArray) -> float:
    """The best total gain by brute force over all order-preserving pairings (small inputs only):
    the test twin of :func:`string_match`."""
    g = np.asarray(gain, dtype=np.float64)
    n, m = g.shape

    def best(i: int, j: int) -> float:
        if i == n or j == m:
            return 0.0
        skip = max(best(i + 1, j), best(i, j + 1))
        if g[i, j] > 0 and math.isfinite(g[i, j]):
            return max(skip, g[i, j] + best(i + 1, j + 1))
        return skip

    return best(0, 0)
