"""The free space of a scan between its beams: the sectors a laser saw through.

A beam crosses the cells on its line; a cell lying between two neighbouring beams is crossed by
neither, although the laser saw past it on both sides. Far from the robot the gap is wide: at
1 deg, 17 cm at 10 m, more than three 5 cm cells. An object that stood there (a visitor's leg, hit
by one beam of one scan) is then never seen through by a later scan, and its cell stays occupied
although the laser saw the space around it empty many times.

A sector between beams ``i`` and ``i + 1`` is free up to the nearer of their two ranges, less a
``margin``: whatever the laser saw there lies beyond both beams' ends (a wall seen at a grazing
angle is never inside: along the wall the ranges of the two beams bracket every wall point).
``width`` keeps only the cells within that lateral distance of one of the two beams (the beam's
footprint, a thick ray), so that a thin object standing between two far beams (a pole) is not
taken for free space; ``inf`` is the whole sector.

The kernel is :func:`free_sectors` (numba), with the plain-numpy twin
:func:`free_sectors_reference`.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["free_sectors", "free_sectors_reference"]

FloatArray = NDArray[np.float64]
_TWO_PI = 2.0 * math.pi


@numba.njit(cache=True)
def _free_sectors_kernel(
    rows: int,
    cols: int,
    ox: float,
    oy: float,
    theta0: float,
    step: float,
    lengths: np.ndarray,
    margin: float,
    width: float,
    cap: float,
    wrap: bool,
) -> np.ndarray:
    out = np.zeros((rows, cols), np.bool_)
    n = lengths.shape[0]
    sectors = n if wrap else n - 1
    if sectors <= 0:
        return out
    for r in range(rows):
        y = r + 0.5 - oy
        if abs(y) > cap:
            continue
        half = min(math.sqrt(cap * cap - y * y), cols + abs(ox) + 1.0)  # finite with no cap
        c_lo = max(0, math.floor(ox - half - 0.5))
        c_hi = min(cols - 1, math.ceil(ox + half - 0.5))
        for c in range(c_lo, c_hi + 1):
            x = c + 0.5 - ox
            rho = math.sqrt(x * x + y * y)
            if rho > cap:
                continue
            u = ((math.atan2(y, x) - theta0) % _TWO_PI) / step
            i = math.floor(u)
            if i < 0 or i >= sectors:
                continue
            j = i + 1 if i + 1 < n else 0
            if rho >= min(lengths[i], lengths[j]) - margin:
                continue
            f = u - i
            if rho * math.sin(min(f, 1.0 - f) * step) > width:
                continue
            out[r, c] = True
    return out


def free_sectors(
    shape: tuple[int, int],
    ox: float,
    oy: float,
    theta0: float,
    step: float,
    lengths: FloatArray,
    *,
    margin: float,
    width: float = math.inf,
    cap: float = math.inf,
) -> NDArray[np.bool_]:
    """Which cells of a ``shape`` box lie in the free sectors of a scan (all in cell units).

    The laser is at ``(ox, oy)`` (x along columns, y along rows; cell ``(r, c)`` spans
    ``[c, c + 1) x [r, r + 1)``); beam ``i`` heads ``theta0 + i * step`` and saw free space for
    ``lengths[i]`` cells (0: nothing known along it). A cell is free when its centre lies between
    two neighbouring beams (the last and the first too when the beams go round the full circle),
    nearer than both beams' lengths less ``margin``, within ``width`` of one of the two beams and
    within ``cap`` of the laser.
    """
    lengths = np.ascontiguousarray(lengths, dtype=np.float64)
    wrap = bool(len(lengths) * step >= _TWO_PI - 1e-6)
    return np.asarray(
        _free_sectors_kernel(
            int(shape[0]),
            int(shape[1]),
            float(ox),
            float(oy),
            float(theta0),
            float(step),
            lengths,
            float(margin),
            float(width),
            float(cap),
            wrap,
        )
    )


def free_sectors_reference(
    shape: tuple[int, int],
    ox: float,
    oy: float,
    theta0: float,
    step: float,
    lengths: FloatArray,
    *,
    margin: float,
    width: float = math.inf,
    cap: float = math.inf,
) -> NDArray[np.bool_]:
    """Plain-numpy twin of :func:`free_sectors`."""
    lengths = np.asarray(lengths, dtype=np.float64)
    n = len(lengths)
    wrap = bool(n * step >= _TWO_PI - 1e-6)
    sectors = n if wrap else n - 1
    rows, cols = int(shape[0]), int(shape[1])
    if sectors <= 0:
        return np.zeros((rows, cols), dtype=bool)
    y = np.arange(rows, dtype=np.float64)[:, None] + 0.5 - oy
    x = np.arange(cols, dtype=np.float64)[None, :] + 0.5 - ox
    y, x = np.broadcast_arrays(y, x)
    rho = np.sqrt(x * x + y * y)
    u = np.mod(np.arctan2(y, x) - theta0, _TWO_PI) / step
    i = np.floor(u).astype(np.int64)
    inside = (rho <= cap) & (i >= 0) & (i < sectors)
    ii = np.where(inside, i, 0)
    jj = np.where(ii + 1 < n, ii + 1, 0)
    reach = np.minimum(lengths[ii], lengths[jj]) - margin
    f = u - ii
    lateral = rho * np.sin(np.minimum(f, 1.0 - f) * step)
    return np.asarray(inside & (rho < reach) & (lateral <= width))
