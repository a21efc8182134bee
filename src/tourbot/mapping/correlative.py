"""Correlative scan-to-submap matching by branch and bound (loop-closure verification).

A loop closure is proposed where the pose graph says the robot may be back near a submap it built
long ago; whether it really is, and where, is decided by searching a whole window of poses around
the guess (Olson, "Real-time correlative scan matching", ICRA 2009; the branch-and-bound search of
Hess et al., "Real-time loop closure in 2D LIDAR SLAM", ICRA 2016, Sec. V).

The submap is a likelihood grid: ``exp(-d^2 / 2 sigma^2)`` with ``d`` the distance from a cell to
the nearest cell a beam ended in. A candidate pose ``(theta_k, dx, dy)`` (a rotation of the scan
and a whole-cell shift of it) scores the mean grid value under the scan's endpoints, in [0, 1].
The window is searched exactly but without visiting every candidate: for a block of ``2^h x 2^h``
shifts, the mean of the *max-pooled* grid ``M_h[r, c] = max G[r..r+2^h-1, c..c+2^h-1]`` under the
endpoints bounds every shift of the block from above, so blocks whose bound is below the best score
found so far (or below the acceptance threshold) are pruned, the rest split in four, depth first,
most promising first. :func:`search_reference` is the exhaustive plain-numpy twin; both return the
same best score.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

__all__ = [
    "Match",
    "SearchWindow",
    "Submap",
    "angular_step",
    "refine",
    "search",
    "search_reference",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SearchWindow:
    """Half-widths of the searched window: ``linear`` m in x and y, ``angular`` rad in heading."""

    linear: float
    angular: float


@dataclass(frozen=True)
class Match:
    """The best pose of a scan in the submap's frame and its score (mean likelihood, 0 to 1)."""

    pose: FloatArray
    score: float


class Submap:
    """A likelihood grid of world points (the submap's frame) with its max-pooled pyramid."""

    def __init__(self, points: FloatArray, resolution: float, sigma: float, levels: int = 6) -> None:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if len(pts) == 0:
            raise ValueError("a submap needs at least one point")
        self.resolution = resolution
        margin = 4.0 * sigma + resolution
        # the low side gets 2^levels cells more, so that a block of shifts that starts off the
        # grid but reaches into it is bounded by the pyramid (a block wholly off it scores 0)
        lo = pts.min(axis=0) - margin - (1 << levels) * resolution
        hi = pts.max(axis=0) + margin
        self.origin = np.floor(lo / resolution) * resolution  # world (x, y) of cell (0, 0)'s corner
        shape = (
            math.ceil((hi[1] - self.origin[1]) / resolution) + 1,
            math.ceil((hi[0] - self.origin[0]) / resolution) + 1,
        )
        cells = np.floor((pts - self.origin) / resolution).astype(np.int64)
        hit = np.zeros(shape, bool)
        hit[cells[:, 1], cells[:, 0]] = True
        d = np.asarray(ndimage.distance_transform_edt(~hit)) * resolution
        self.grid = np.exp(-0.5 * (d / sigma) ** 2)
        self.pyramid = max_pyramid(self.grid, levels)
        self.centre = pts.mean(axis=0)
        self.radius = float(np.max(np.hypot(*(pts - self.centre).T)))


def max_pyramid(grid: FloatArray, levels: int) -> FloatArray:
    """``(levels + 1, rows, cols)``: level ``h`` holds the max of ``grid`` over the ``2^h`` square
    of cells starting at each cell (0 past the edge)."""
    out = np.zeros((levels + 1, *grid.shape))
    out[0] = grid
    for h in range(1, levels + 1):
        s = 1 << (h - 1)
        prev = out[h - 1]
        cur = prev.copy()
        cur[:-s, :] = np.maximum(cur[:-s, :], prev[s:, :])
        shifted = cur.copy()
        cur[:, :-s] = np.maximum(cur[:, :-s], shifted[:, s:])
        out[h] = cur
    return out


def angular_step(points: FloatArray, resolution: float) -> float:
    """The rotation that moves the farthest point by about one cell (Hess et al. Eq. 7)."""
    far = float(np.max(np.hypot(points[:, 0], points[:, 1]))) if len(points) else 1.0
    far = max(far, resolution)
    return float(math.acos(max(-1.0, 1.0 - resolution**2 / (2.0 * far**2))))


def _candidates(
    submap: Submap, points: FloatArray, guess: FloatArray, window: SearchWindow
) -> tuple[FloatArray, NDArray[np.int64], int]:
    """The searched rotations ``(K,)``, each rotation's endpoint cells at zero shift ``(K, N, 2)``
    (column, row) and the half-width of the shifts in cells."""
    res = submap.resolution
    step = angular_step(points, res)
    n_rot = math.ceil(window.angular / step)
    thetas = guess[2] + step * np.arange(-n_rot, n_rot + 1)
    c, s = np.cos(thetas)[:, None], np.sin(thetas)[:, None]
    wx = guess[0] + c * points[None, :, 0] - s * points[None, :, 1]
    wy = guess[1] + s * points[None, :, 0] + c * points[None, :, 1]
    cols = np.floor((wx - submap.origin[0]) / res).astype(np.int64)
    rows = np.floor((wy - submap.origin[1]) / res).astype(np.int64)
    half = math.ceil(window.linear / res)
    return thetas, np.stack([cols, rows], axis=-1), half


def _pose(submap: Submap, guess: FloatArray, theta: float, dx: int, dy: int) -> FloatArray:
    res = submap.resolution
    return np.array([guess[0] + dx * res, guess[1] + dy * res, math.atan2(math.sin(theta), math.cos(theta))])


def search(
    submap: Submap, points: FloatArray, guess: FloatArray, window: SearchWindow, min_score: float = 0.0
) -> Match | None:
    """The best pose of the scan ``points`` (robot frame, ``(N, 2)``) within ``window`` of ``guess``
    (submap frame), by branch and bound; None when no pose scores above ``min_score``."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return None
    thetas, cells, half = _candidates(submap, pts, np.asarray(guess, dtype=np.float64), window)
    levels = submap.pyramid.shape[0] - 1
    top = min(levels, max(0, math.ceil(math.log2(2 * half + 1))))
    k, dx, dy, best = _branch_and_bound(submap.pyramid, cells, half, top, float(min_score))
    if k < 0:
        return None
    return Match(_pose(submap, np.asarray(guess, dtype=np.float64), float(thetas[k]), dx, dy), best)


def search_reference(
    submap: Submap, points: FloatArray, guess: FloatArray, window: SearchWindow, min_score: float = 0.0
) -> Match | None:
    """Plain-numpy twin of :func:`search`: every rotation and shift of the window scored."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return None
    g = np.asarray(guess, dtype=np.float64)
    thetas, cells, half = _candidates(submap, pts, g, window)
    grid = submap.grid
    rows_n, cols_n = grid.shape
    best, arg = min_score, None
    shifts = np.arange(-half, half + 1)
    for k in range(len(thetas)):
        c = cells[k, :, 0][None, None, :] + shifts[None, :, None]  # (1, dx, N)
        r = cells[k, :, 1][None, None, :] + shifts[:, None, None]  # (dy, 1, N)
        c, r = np.broadcast_arrays(c, r)
        ok = (c >= 0) & (c < cols_n) & (r >= 0) & (r < rows_n)
        v = np.where(ok, grid[np.clip(r, 0, rows_n - 1), np.clip(c, 0, cols_n - 1)], 0.0)
        scores = v.mean(axis=2)  # (dy, dx)
        iy, ix = np.unravel_index(int(np.argmax(scores)), scores.shape)
        if scores[iy, ix] > best:
            best, arg = float(scores[iy, ix]), (k, int(shifts[ix]), int(shifts[iy]))
    if arg is None:
        return None
    return Match(_pose(submap, g, float(thetas[arg[0]]), arg[1], arg[2]), best)


def refine(submap: Submap, points: FloatArray, pose: FloatArray) -> FloatArray:
    """The branch-and-bound pose (whole cells, whole angular steps) refined to continuous values by
    hill climbing on the interpolated likelihood grid (:func:`tourbot.mapping.scan_matching.
    hill_climb`, no prior to speak of)."""
    from tourbot.mapping.scan_matching import MatchParams, hill_climb

    res = submap.resolution
    origin = np.array([submap.origin[0], submap.origin[1], 0.0])
    start = np.asarray(pose, dtype=np.float64) - origin
    params = MatchParams(steps=(res / 2, res / 2, 0.005), halvings=5)
    wide = np.array([1e3, 1e3, 1e3])
    best, _ = hill_climb(submap.grid, res, start, points, np.ones(len(points)), start, wide, params)
    return best + origin


@numba.njit(cache=True)
def _block_score(level: np.ndarray, cells: np.ndarray, dx: int, dy: int) -> float:
    rows_n, cols_n = level.shape
    total = 0.0
    for i in range(cells.shape[0]):
        c = cells[i, 0] + dx
        r = cells[i, 1] + dy
        if 0 <= c < cols_n and 0 <= r < rows_n:
            total += level[r, c]
    return total / cells.shape[0]


@numba.njit(cache=True)
def _branch_and_bound(
    pyramid: np.ndarray, cells: np.ndarray, half: int, top: int, min_score: float
) -> tuple[int, int, int, float]:
    """Depth-first branch and bound over (rotation, shift block); returns the best rotation index
    and shift (-1 when nothing beats ``min_score``) and its score."""
    n_rot = cells.shape[0]
    side = 1 << top
    per = (2 * half + side) // side
    cap = n_rot * per * per + 4 * (top + 1) * 64 + 16
    st_k = np.empty(cap, np.int64)
    st_x = np.empty(cap, np.int64)
    st_y = np.empty(cap, np.int64)
    st_h = np.empty(cap, np.int64)
    st_b = np.empty(cap, np.float64)
    # the top blocks, pushed in increasing bound so that the best is popped first
    n = 0
    for k in range(n_rot):
        for bx in range(per):
            for by in range(per):
                x = -half + bx * side
                y = -half + by * side
                st_k[n] = k
                st_x[n] = x
                st_y[n] = y
                st_h[n] = top
                st_b[n] = _block_score(pyramid[top], cells[k], x, y)
                n += 1
    order = np.argsort(st_b[:n])
    st_k[:n] = st_k[:n][order]
    st_x[:n] = st_x[:n][order]
    st_y[:n] = st_y[:n][order]
    st_b[:n] = st_b[:n][order]
    best = min_score
    bk, bx_, by_ = -1, 0, 0
    ck = np.empty(4, np.int64)
    cx = np.empty(4, np.int64)
    cy = np.empty(4, np.int64)
    cb = np.empty(4, np.float64)
    while n > 0:
        n -= 1
        k, x, y, h, b = st_k[n], st_x[n], st_y[n], st_h[n], st_b[n]
        if b <= best:
            continue
        if h == 0:
            if x <= half and y <= half:
                best = b
                bk, bx_, by_ = k, x, y
            continue
        s = 1 << (h - 1)
        m = 0
        for ox in range(2):
            for oy in range(2):
                xx = x + ox * s
                yy = y + oy * s
                if xx > half or yy > half:
                    continue
                ck[m] = k
                cx[m] = xx
                cy[m] = yy
                cb[m] = _block_score(pyramid[h - 1], cells[k], xx, yy)
                m += 1
        # push the children in increasing bound (the best ends on top)
        for _ in range(m):
            lo = -1
            for q in range(m):
                if cb[q] > -1.0 and (lo < 0 or cb[q] < cb[lo]):
                    lo = q
            if cb[lo] > best:
                st_k[n] = ck[lo]
                st_x[n] = cx[lo]
                st_y[n] = cy[lo]
                st_h[n] = h - 1
                st_b[n] = cb[lo]
                n += 1
            cb[lo] = -2.0
    return bk, bx_, by_, best
