"""The likelihood-field range-finder model, as a precomputed log-likelihood table.

Probabilistic Robotics (Thrun, Burgard & Fox 2005), Section 6.4, Table 6.3 (``likelihood_field_
range_finder_model``): the endpoint of each beam is projected into the map and scored by its
distance ``dist`` to the nearest occupied cell,

    p(z_k | x, m) = z_hit * prob(dist, sigma_hit) + z_rand / z_max,

``prob(d, sigma)`` the zero-mean normal density. Beams at the maximum range (no return) are
skipped, as in the book. ``dist`` is capped at ``max_dist`` (Nav2 AMCL's
``laser_likelihood_max_dist``); endpoints off the grid score as at ``max_dist``. Since the whole
expression depends on the cell only, it is tabulated once per map as ``log p`` and a beam costs a
table look-up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.geometry import compose, invert
from tourbot.maps.grid import MapError, OccupancyGrid
from tourbot.records import LaserGeometry

__all__ = [
    "LikelihoodField",
    "LikelihoodFieldParams",
    "beam_log_likelihoods_reference",
    "endpoint_log_likelihoods",
    "padded_table",
    "sum_log_likelihoods",
    "surface_distance",
    "used_beams",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LikelihoodFieldParams:
    """Parameters of the likelihood field (Probabilistic Robotics Table 6.3).

    Defaults are Nav2 AMCL's for its ``likelihood_field`` model: ``sigma_hit`` 0.2 m, ``z_hit``
    0.95 (the book's mixture weight of the Gaussian), ``z_rand`` 0.05, ``max_dist`` 2.0 m
    (``laser_likelihood_max_dist``); ``max_range`` (``z_max`` in the book) is the laser's, 8 m
    here unless given. ``distance``: ``"centre"`` (the book's) or ``"surface"`` (see
    :func:`surface_distance`).
    """

    sigma_hit: float = 0.2
    z_hit: float = 0.95
    z_rand: float = 0.05
    max_dist: float = 2.0
    max_range: float = 8.0
    distance: Literal["centre", "surface"] = "centre"

    def __post_init__(self) -> None:
        if self.distance not in ("centre", "surface"):
            raise MapError(f"likelihood field: distance must be 'centre' or 'surface', got {self.distance!r}")
        for name in ("sigma_hit", "max_dist", "max_range"):
            if not getattr(self, name) > 0:
                raise MapError(f"likelihood field: {name} must be positive, got {getattr(self, name)}")
        if self.z_hit < 0 or self.z_rand < 0 or self.z_hit + self.z_rand <= 0:
            raise MapError(f"likelihood field: bad weights z_hit={self.z_hit}, z_rand={self.z_rand}")

    def log_p(self, dist: ArrayLike) -> FloatArray:
        """``log(z_hit * N(dist; 0, sigma_hit^2) + z_rand / max_range)``, ``dist`` capped."""
        d = np.minimum(np.asarray(dist, dtype=np.float64), self.max_dist)
        s = self.sigma_hit
        gauss = np.exp(-0.5 * (d / s) ** 2) / (s * math.sqrt(2.0 * math.pi))
        return np.asarray(np.log(self.z_hit * gauss + self.z_rand / self.max_range), dtype=np.float64)


def surface_distance(grid: OccupancyGrid, to_occupied: FloatArray | None = None) -> FloatArray:
    """Per cell, the distance (m) to the surface between the known free space and the rest.

    ``to_occupied``: the distance of each cell centre to the nearest occupied cell centre (computed
    here when not given). Free cells: that distance; occupied and unknown cells: the larger of it
    and the distance to the nearest free cell centre; both less half a cell, floored at zero.
    Without free cells, ``to_occupied`` less half a cell.
    """
    from scipy import ndimage

    res = grid.resolution
    if to_occupied is None:
        occ = grid.occupied()
        to_occupied = ndimage.distance_transform_edt(~occ) * res if occ.any() else np.full(occ.shape, np.inf)
    free = grid.free()
    if free.any():
        to_free = ndimage.distance_transform_edt(~free) * res
        dist = np.where(free, to_occupied, np.maximum(to_occupied, to_free))
    else:
        dist = to_occupied
    return np.asarray(np.maximum(dist - 0.5 * res, 0.0), dtype=np.float64)


def used_beams(
    ranges: ArrayLike, geometry: LaserGeometry, beam_mask: ArrayLike | None = None
) -> NDArray[np.bool_]:
    """Beams that carry a return: finite, ``>= min_range``, ``< max_range``, and in ``beam_mask``."""
    r = np.asarray(ranges, dtype=np.float64)
    use = np.isfinite(r) & (r >= geometry.min_range) & (r < geometry.max_range)
    if beam_mask is not None:
        use &= np.asarray(beam_mask, dtype=bool)
    return np.asarray(use, dtype=np.bool_)


@numba.njit(cache=True, inline="always")
def _laser_pose_in_cells(pose: FloatArray, frame: FloatArray, i: int) -> tuple[float, float, float, float]:
    """Robot pose ``i`` -> laser position in grid cells and the laser's (cos, sin).

    ``frame = (ox, oy, cos o, sin o, gx, gy, cos g, sin g, 1/res)``: the laser offset on the
    robot and the inverse of the grid origin, as rotations and translations.
    """
    c = math.cos(pose[i, 2])
    s = math.sin(pose[i, 2])
    # laser in the world: pose (+) offset
    wx = pose[i, 0] + c * frame[0] - s * frame[1]
    wy = pose[i, 1] + s * frame[0] + c * frame[1]
    lc = c * frame[2] - s * frame[3]
    ls = s * frame[2] + c * frame[3]
    # laser in the grid frame: inverse(origin) (+) laser, then in cells
    gx = (frame[4] + frame[6] * wx - frame[7] * wy) * frame[8]
    gy = (frame[5] + frame[7] * wx + frame[6] * wy) * frame[8]
    return gx, gy, frame[6] * lc - frame[7] * ls, frame[7] * lc + frame[6] * ls


def padded_table(table: NDArray[np.float32], outside: float) -> NDArray[np.float32]:
    """``table`` framed by one cell of ``outside`` on every side, ``(rows + 2, cols + 2)``.

    The kernels clamp an endpoint's cell to the frame, so every look-up is in bounds: off-grid
    endpoints read ``outside`` with no branch, and the beams of every pose go through one
    branch-free loop (vector gathers), wherever the pose is.
    """
    rows, cols = table.shape
    if (rows + 2) * (cols + 2) >= 2**31:
        raise MapError(f"likelihood field: a {rows} x {cols} grid is too large for 32-bit cell indices")
    out = np.full((rows + 2, cols + 2), outside, dtype=np.float32)
    out[1:-1, 1:-1] = table
    return out


@numba.njit(cache=True, inline="always")
def _cell_index(ex: float, ey: float, fc: float, fr: float, pcols: np.int32) -> np.uint32:
    """Flat index in the padded table of the cell under the endpoint ``(ex, ey)`` (in cells).

    ``floor`` of the endpoint clamped to ``[-1, cols]`` x ``[-1, rows]``: the exact cell on the
    grid, the frame cell off it (``floor`` is exact, the clamp changes only off-grid endpoints).
    32-bit indices (:func:`padded_table` checks that they suffice): half the conversions and
    gathers of twice the width of 64-bit ones.
    """
    col = np.int32(math.floor(min(max(ex, -1.0), fc)))
    row = np.int32(math.floor(min(max(ey, -1.0), fr)))
    return np.uint32((row + np.int32(1)) * pcols + col + np.int32(1))


@numba.njit(cache=True, fastmath=True)
def endpoint_log_likelihoods(
    padded: NDArray[np.float32],
    poses: FloatArray,
    frame: FloatArray,
    lx: FloatArray,
    ly: FloatArray,
    beams: NDArray[np.int64],
    out: NDArray[np.float32],
) -> None:
    """``out[i, beams[k]]`` = table value under endpoint ``k`` seen from robot pose ``i``.

    ``padded``: the table framed by the value off the grid (:func:`padded_table`); ``(lx, ly)``
    the beam endpoints in the laser frame, in cells; ``frame`` as in :func:`_laser_pose_in_cells`.
    """
    pcols = np.int32(padded.shape[1])
    fr = float(padded.shape[0] - 2)
    fc = float(padded.shape[1] - 2)
    flat = padded.ravel()
    for i in range(poses.shape[0]):
        x, y, c, s = _laser_pose_in_cells(poses, frame, i)
        for k in range(lx.shape[0]):
            ex = x + c * lx[k] - s * ly[k]
            ey = y + s * lx[k] + c * ly[k]
            out[i, beams[k]] = flat[_cell_index(ex, ey, fc, fr, pcols)]


@numba.njit(cache=True, fastmath=True)
def sum_log_likelihoods(
    padded: NDArray[np.float32],
    poses: FloatArray,
    frame: FloatArray,
    lx: FloatArray,
    ly: FloatArray,
    out: FloatArray,
) -> None:
    """``out[i]`` = sum of the table values under the endpoints seen from robot pose ``i``.

    ``padded`` as in :func:`endpoint_log_likelihoods`. One branch-free loop over the beams for
    every pose, on the grid or near its edges (the compiler turns it into vector gathers), two
    poses at a time (two independent chains of look-ups); the endpoint maths is float64.
    """
    pcols = np.int32(padded.shape[1])
    fr = float(padded.shape[0] - 2)
    fc = float(padded.shape[1] - 2)
    flat = padded.ravel()
    n = poses.shape[0]
    i = 0
    while i + 1 < n:
        x, y, c, s = _laser_pose_in_cells(poses, frame, i)
        x2, y2, c2, s2 = _laser_pose_in_cells(poses, frame, i + 1)
        acc = 0.0
        acc2 = 0.0
        for k in range(lx.shape[0]):
            ex = x + c * lx[k] - s * ly[k]
            ey = y + s * lx[k] + c * ly[k]
            ex2 = x2 + c2 * lx[k] - s2 * ly[k]
            ey2 = y2 + s2 * lx[k] + c2 * ly[k]
            acc += flat[_cell_index(ex, ey, fc, fr, pcols)]
            acc2 += flat[_cell_index(ex2, ey2, fc, fr, pcols)]
        out[i] = acc
        out[i + 1] = acc2
        i += 2
    if i < n:
        x, y, c, s = _laser_pose_in_cells(poses, frame, i)
        acc = 0.0
        for k in range(lx.shape[0]):
            ex = x + c * lx[k] - s * ly[k]
            ey = y + s * lx[k] + c * ly[k]
            acc += flat[_cell_index(ex, ey, fc, fr, pcols)]
        out[i] = acc


def beam_log_likelihoods_reference(
    grid: OccupancyGrid,
    params: LikelihoodFieldParams,
    poses: ArrayLike,
    ranges: ArrayLike,
    geometry: LaserGeometry,
) -> FloatArray:
    """Plain numpy Table 6.3 per beam ``(N, B)``, computing the distance from scratch (no table).

    Unused beams (see :func:`used_beams`) give 0. Slow: for tests, on small grids.
    """
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(ranges, dtype=np.float64)
    laser = compose(p, np.asarray(geometry.offset))
    ang = laser[:, 2:3] + geometry.angles[None, :]
    use = used_beams(r, geometry)
    rr = np.where(use, r, 0.0)
    ends = np.stack([laser[:, 0:1] + rr * np.cos(ang), laser[:, 1:2] + rr * np.sin(ang)], axis=-1)
    cells = grid.world_to_cell(ends)
    occ = np.argwhere(grid.occupied())
    if occ.size:
        diff = cells[:, :, None, :] - occ[None, None, :, :]
        dist = np.sqrt((diff.astype(np.float64) ** 2).sum(-1)).min(-1) * grid.resolution
    else:
        dist = np.full(cells.shape[:2], np.inf)
    dist = np.where(grid.inside(cells), dist, np.inf)
    return np.where(use[None, :], params.log_p(dist), 0.0)


@dataclass
class LikelihoodField:
    """A map's likelihood field: ``table[row, col] = log p`` of a beam ending in that cell.

    ``outside``: the value off the grid, rounded to float32 as the table is. ``padded``: the
    table framed by ``outside`` (:func:`padded_table`), which the kernels read; ``table`` is a
    view of its inside.
    """

    grid: OccupancyGrid
    params: LikelihoodFieldParams
    padded: NDArray[np.float32]
    outside: float

    @property
    def table(self) -> NDArray[np.float32]:
        return self.padded[1:-1, 1:-1]

    @classmethod
    def from_grid(
        cls,
        grid: OccupancyGrid,
        params: LikelihoodFieldParams | None = None,
        *,
        sigma_hit: float | None = None,
        max_dist: float | None = None,
        z_hit: float | None = None,
        z_rand: float | None = None,
        max_range: float | None = None,
    ) -> LikelihoodField:
        """Tabulate the field of ``grid`` (Euclidean distance transform, scipy.ndimage).

        Keyword values override those of ``params`` (default :class:`LikelihoodFieldParams`).
        """
        from scipy import ndimage

        base = params or LikelihoodFieldParams()
        prm = replace(
            base,
            sigma_hit=base.sigma_hit if sigma_hit is None else sigma_hit,
            max_dist=base.max_dist if max_dist is None else max_dist,
            z_hit=base.z_hit if z_hit is None else z_hit,
            z_rand=base.z_rand if z_rand is None else z_rand,
            max_range=base.max_range if max_range is None else max_range,
        )
        occ = grid.occupied()
        if occ.any():
            dist = ndimage.distance_transform_edt(~occ) * grid.resolution
        else:
            dist = np.full(occ.shape, np.inf)
        if prm.distance == "surface":
            dist = surface_distance(grid, dist)
        outside = float(np.float32(prm.log_p(np.inf)))
        padded = padded_table(prm.log_p(dist).astype(np.float32), outside)
        return cls(grid=grid, params=prm, padded=padded, outside=outside)

    @property
    def nbytes(self) -> int:
        return int(self.padded.nbytes)

    def _frame(self, poses: ArrayLike, geometry: LaserGeometry) -> tuple[FloatArray, FloatArray]:
        p = np.ascontiguousarray(np.asarray(poses, dtype=np.float64))
        if p.ndim != 2 or p.shape[1] != 3:
            raise MapError(f"poses must be (N, 3), got shape {p.shape}")
        if not np.isfinite(p).all():
            # the kernels clamp endpoints to the padded table, which a NaN would slip through
            raise MapError("poses must be finite")
        ox, oy, oth = geometry.offset
        inv = invert(self.grid.origin)
        frame = np.array(
            [
                ox,
                oy,
                math.cos(oth),
                math.sin(oth),
                inv[0],
                inv[1],
                math.cos(inv[2]),
                math.sin(inv[2]),
                1.0 / self.grid.resolution,
            ]
        )
        return p, frame

    def _endpoints(
        self, ranges: ArrayLike, geometry: LaserGeometry, use: NDArray[np.bool_]
    ) -> tuple[FloatArray, FloatArray]:
        r = np.asarray(ranges, dtype=np.float64)[use] / self.grid.resolution
        a = geometry.angles[use]
        return np.ascontiguousarray(r * np.cos(a)), np.ascontiguousarray(r * np.sin(a))

    def _check(self, ranges: ArrayLike, geometry: LaserGeometry) -> None:
        n = np.asarray(ranges).shape
        if n != (geometry.num_beams,):
            raise MapError(f"ranges must be ({geometry.num_beams},) for this laser, got shape {n}")

    def beam_log_likelihoods(
        self,
        poses: ArrayLike,
        ranges: ArrayLike,
        geometry: LaserGeometry,
        beam_mask: ArrayLike | None = None,
    ) -> NDArray[np.float32]:
        """``log p(z_k | x_i, m)`` per robot pose ``(N, 3)`` and beam, ``(N, B)`` float32.

        Beams without a return (or outside ``beam_mask``) give 0, so ``.sum(axis=1)`` is
        :meth:`log_likelihood`.
        """
        self._check(ranges, geometry)
        p, frame = self._frame(poses, geometry)
        use = used_beams(ranges, geometry, beam_mask)
        lx, ly = self._endpoints(ranges, geometry, use)
        out = np.zeros((p.shape[0], geometry.num_beams), dtype=np.float32)
        if out.size and lx.size:
            beams = np.flatnonzero(use).astype(np.int64)
            endpoint_log_likelihoods(self.padded, p, frame, lx, ly, beams, out)
        return out

    def log_likelihood(
        self,
        poses: ArrayLike,
        ranges: ArrayLike,
        geometry: LaserGeometry,
        beam_mask: ArrayLike | None = None,
    ) -> FloatArray:
        """``log p(z | x_i, m)`` of the whole scan (sum over used beams) per robot pose, ``(N,)``."""
        self._check(ranges, geometry)
        p, frame = self._frame(poses, geometry)
        use = used_beams(ranges, geometry, beam_mask)
        lx, ly = self._endpoints(ranges, geometry, use)
        out = np.zeros(p.shape[0], dtype=np.float64)
        if lx.shape[0] and out.size:
            sum_log_likelihoods(self.padded, p, frame, lx, ly, out)
        return out
