"""Dijkstra's algorithm on a grid: the cost-to-go from one cell over 8-connected cells.

One implementation for every part that walks a grid: the planner's navigation function (Latombe
1991; the cost-to-go of the museum robots' planners, Burgard et al. 1999, computed by value
iteration there) and the crowd's geodesic distance fields (visitors walk around walls to the robot
or an exhibit). Moving between neighbours costs the mean of the two cells' costs times the step
length (1 or sqrt 2 cells); a cell of infinite cost is forbidden. A field of unit costs gives the
geodesic distance in cells.

:func:`grid_dijkstra` is the numba kernel, :func:`grid_dijkstra_reference` its plain-Python twin
(:mod:`heapq`), compared by property tests.
"""

from __future__ import annotations

import heapq
import math

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["grid_dijkstra", "grid_dijkstra_reference", "unit_costs"]

FloatArray = NDArray[np.float64]
_SQRT2 = math.sqrt(2.0)


def unit_costs(passable: NDArray[np.bool_]) -> FloatArray:
    """Costs for geodesic distances: 1 on passable cells, infinite elsewhere."""
    return np.where(passable, 1.0, np.inf)


@numba.njit(cache=True)
def grid_dijkstra(cost: FloatArray, source_r: int, source_c: int, max_cost: float = np.inf) -> FloatArray:
    """Cost-to-go ``(rows, cols)`` from ``(source_r, source_c)`` (numba kernel).

    Cells farther than ``max_cost`` or unreachable are ``inf`` (and the search stops expanding past
    ``max_cost``); a source outside the grid or on a forbidden cell reaches nothing.
    """
    rows, cols = cost.shape
    dist = np.full((rows, cols), np.inf)
    if source_r < 0 or source_r >= rows or source_c < 0 or source_c >= cols:
        return dist
    if not np.isfinite(cost[source_r, source_c]):
        return dist
    # binary heap of (distance, flat index) in two arrays; stale entries are skipped when popped
    cap = rows * cols * 8 + 1
    hk = np.empty(cap, dtype=np.float64)
    hv = np.empty(cap, dtype=np.int64)
    done = np.zeros((rows, cols), dtype=np.bool_)
    dist[source_r, source_c] = 0.0
    hk[0] = 0.0
    hv[0] = source_r * cols + source_c
    n = 1
    drs = (-1, -1, -1, 0, 0, 1, 1, 1)
    dcs = (-1, 0, 1, -1, 1, -1, 0, 1)
    while n > 0:
        d = hk[0]
        v = hv[0]
        n -= 1
        if n > 0:  # move the last to the root and sift down
            hk[0] = hk[n]
            hv[0] = hv[n]
            i = 0
            while True:
                left = 2 * i + 1
                if left >= n:
                    break
                small = left
                if left + 1 < n and hk[left + 1] < hk[left]:
                    small = left + 1
                if hk[small] < hk[i]:
                    hk[i], hk[small] = hk[small], hk[i]
                    hv[i], hv[small] = hv[small], hv[i]
                    i = small
                else:
                    break
        r = v // cols
        c = v % cols
        if done[r, c] or d > max_cost:
            continue
        done[r, c] = True
        for k in range(8):
            nr = r + drs[k]
            nc = c + dcs[k]
            if nr < 0 or nr >= rows or nc < 0 or nc >= cols or done[nr, nc]:
                continue
            cn = cost[nr, nc]
            if not np.isfinite(cn):
                continue
            step = 1.0 if (drs[k] == 0 or dcs[k] == 0) else 1.4142135623730951
            nd = d + step * 0.5 * (cost[r, c] + cn)
            if nd < dist[nr, nc]:
                dist[nr, nc] = nd
                # push and sift up
                j = n
                hk[j] = nd
                hv[j] = nr * cols + nc
                n += 1
                while j > 0:
                    p = (j - 1) // 2
                    if hk[j] < hk[p]:
                        hk[j], hk[p] = hk[p], hk[j]
                        hv[j], hv[p] = hv[p], hv[j]
                        j = p
                    else:
                        break
    for r in range(rows):
        for c in range(cols):
            if dist[r, c] > max_cost:
                dist[r, c] = np.inf
    return dist


def grid_dijkstra_reference(
    cost: FloatArray, source_r: int, source_c: int, max_cost: float = math.inf
) -> FloatArray:
    """Plain-Python :func:`grid_dijkstra` with :mod:`heapq`, for the property tests."""
    rows, cols = cost.shape
    dist = np.full((rows, cols), np.inf)
    if not (0 <= source_r < rows and 0 <= source_c < cols) or not np.isfinite(cost[source_r, source_c]):
        return dist
    dist[source_r, source_c] = 0.0
    heap = [(0.0, source_r, source_c)]
    done = np.zeros((rows, cols), dtype=bool)
    while heap:
        d, r, c = heapq.heappop(heap)
        if done[r, c] or d > max_cost:
            continue
        done[r, c] = True
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                nr, nc = r + dr, c + dc
                if (dr, dc) == (0, 0) or not (0 <= nr < rows and 0 <= nc < cols) or done[nr, nc]:
                    continue
                if not np.isfinite(cost[nr, nc]):
                    continue
                step = 1.0 if dr == 0 or dc == 0 else _SQRT2
                nd = d + step * 0.5 * (cost[r, c] + cost[nr, nc])
                if nd < dist[nr, nc]:
                    dist[nr, nc] = nd
                    heapq.heappush(heap, (nd, nr, nc))
    dist[dist > max_cost] = np.inf
    return dist
