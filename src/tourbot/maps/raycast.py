"""Ray casting on an occupancy grid (plus moving circles: people's legs), batched over poses x beams.

One ray caster for all of tourbot: localization (beam model), the simulator's laser, the crowd
overlay and the object-state estimator (Schulz et al. 2001, the "sensor simulation" of their
Table 1 loop) all call the casters here.

What blocks a ray
    Cells with ``prob > grid.occupied_thresh`` block. Unknown cells (``prob < 0``) block too by
    default (``unknown_blocks=True``, as Nav2 AMCL's ``map_calc_range`` does): a laser sees the
    wall that the map could not see behind. Everything outside the grid counts as unknown, so with
    ``unknown_blocks=True`` a ray stops where it leaves the grid and a pose outside the grid reads
    0; with ``unknown_blocks=False`` the outside is empty and such rays read ``max_range``.

What a range is
    The distance from the laser to where the ray *enters* the first blocking cell (cells are
    squares, the exact Amanatides & Woo traversal of :mod:`tourbot.maps.traversal`, its cast
    mode), ``max_range`` where nothing blocks within
    ``max_range``. Ranges are float32 metres, ``(N, B)`` for ``N`` laser poses and ``B`` beam
    angles.

Methods
    - :func:`cast_rays_reference`: plain numpy, vectorised over rays; it cuts each ray at every
      grid line it crosses and tests the cell under each piece's midpoint. The property tests
      compare every kernel against it.
    - :class:`DDACaster`: the numba Amanatides & Woo (1987) DDA, one cell per step (the
      "Bresenham" baseline of range_libc, Walsh & Karaman 2018).
    - :class:`DistanceCaster`: the same DDA accelerated by a distance transform: where the nearest
      blocking cell is ``D`` cells away, a ray can safely jump ``D - sqrt(2)`` cells at once
      (ray marching / sphere tracing, range_libc "RM"), and it falls back to exact DDA steps near
      obstacles, so it returns the DDA's ranges (not an approximation within a threshold).

An approximate caster on a compressed directional distance transform (CDDT, Walsh & Karaman 2018)
was measured and removed: replaying every cast of MCL with the novelty filter on FHW (5000
samples, 119 updates) took 0.104 s with :class:`DistanceCaster` and 0.058 s with it, against a
21.7 s table build (1.2 s for the distance transform), and its ranges are off the DDA's where
beams graze walls (``docs/results/layers.md``; the code is in the git history).
"""

from __future__ import annotations

import math
from typing import Protocol

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.maps.grid import MapError, OccupancyGrid

# numba inlines the traversal into this file's cached kernels: it recompiles them only when
# this file changes (clear __pycache__/*.nbi after a change of traversal.py)
from tourbot.maps.traversal import BLOCKED, MAX_JUMP, OUTSIDE, cast_ray, cast_start, cast_step, snap

__all__ = [
    "DDACaster",
    "DistanceCaster",
    "RangeCaster",
    "RayCaster",
    "beam_angles",
    "blocking_mask",
    "cast_circles_reference",
    "cast_rays_kernel",
    "cast_rays_reference",
    "circle_ranges",
    "padded_table",
    "rays_in_cells",
]

FloatArray = NDArray[np.float64]
Float32Array = NDArray[np.float32]

_SQRT2 = math.sqrt(2.0)


def blocking_mask(grid: OccupancyGrid, unknown_blocks: bool = True) -> NDArray[np.bool_]:
    """Cells that stop a ray: occupied ones, and unknown ones when ``unknown_blocks``."""
    mask = grid.occupied()
    if unknown_blocks:
        mask = mask | grid.unknown()
    return mask


def rays_in_cells(grid: OccupancyGrid, poses: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """World laser poses ``(N, 3)`` -> origins in cell units (x along columns) and headings."""
    p = np.asarray(poses, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise MapError(f"poses must be (N, 3), got shape {p.shape}")
    if not np.isfinite(p).all():
        raise MapError(
            f"poses must be finite; rows {np.flatnonzero(~np.isfinite(p).all(axis=1))[:5]} are not"
        )
    g = grid.world_to_grid(p)
    inv = 1.0 / grid.resolution
    return (
        np.ascontiguousarray(g[:, 0] * inv),
        np.ascontiguousarray(g[:, 1] * inv),
        np.ascontiguousarray(g[:, 2]),
    )


def beam_angles(angles: ArrayLike) -> FloatArray:
    """Beam angles (relative to the laser) as a contiguous 1-D float array; a clear error otherwise."""
    a = np.ascontiguousarray(np.asarray(angles, dtype=np.float64))
    if a.ndim != 1:
        raise MapError(f"beam angles must be (B,), got shape {a.shape}")
    if not np.isfinite(a).all():
        raise MapError("beam angles must be finite")
    return a


# --------------------------------------------------------------------------------------------
# numpy reference
# --------------------------------------------------------------------------------------------


def cast_rays_reference(
    blocked: NDArray[np.bool_],
    ox: ArrayLike,
    oy: ArrayLike,
    theta: ArrayLike,
    max_cells: float,
    outside_blocks: bool = True,
) -> FloatArray:
    """Exact range, in cells, of each ray on a ``blocked[row, col]`` mask (plain numpy).

    Rays are given flat: origins ``(ox, oy)`` in cell units (``x`` along columns, ``y`` along
    rows) and absolute headings ``theta``, all ``(M,)``. Each ray is cut at every grid line it
    crosses before ``max_cells``; the first piece whose midpoint lies in a blocking cell (or
    outside the grid when ``outside_blocks``) gives the range, the parameter where that piece
    starts. Rays with no blocking piece give ``max_cells``. Pieces shorter than 1e-9 cells (a ray
    through a cell corner) are skipped.
    """
    x0 = np.asarray(ox, dtype=np.float64).ravel()
    y0 = np.asarray(oy, dtype=np.float64).ravel()
    th = np.asarray(theta, dtype=np.float64).ravel()
    m = x0.size
    if m == 0:
        return np.zeros(0)
    rows, cols = blocked.shape
    dx, dy = np.cos(th), np.sin(th)
    x1, y1 = x0 + max_cells * dx, y0 + max_cells * dy

    def crossings(a0: FloatArray, a1: FloatArray, d: FloatArray) -> FloatArray:
        lo = np.floor(np.minimum(a0, a1))
        n = int(np.max(np.ceil(np.maximum(a0, a1)) - lo)) + 1
        k = lo[:, None] + np.arange(n)[None, :]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (k - a0[:, None]) / d[:, None]
        ok = np.isfinite(t) & (t > 0.0) & (t < max_cells)
        return np.where(ok, t, np.inf)

    t = np.concatenate(
        [np.zeros((m, 1)), crossings(x0, x1, dx), crossings(y0, y1, dy), np.full((m, 1), max_cells)],
        axis=1,
    )
    t.sort(axis=1)
    t = np.where(np.isinf(t), max_cells, t)
    start, end = t[:, :-1], t[:, 1:]
    mid = 0.5 * (start + end)
    cx = np.floor(x0[:, None] + mid * dx[:, None]).astype(np.int64)
    cy = np.floor(y0[:, None] + mid * dy[:, None]).astype(np.int64)
    inside = (cx >= 0) & (cx < cols) & (cy >= 0) & (cy < rows)
    hit = np.full(cx.shape, outside_blocks)
    hit[inside] = blocked[cy[inside], cx[inside]]
    hit &= (end - start) > 1e-9
    first = np.argmax(hit, axis=1)
    any_hit = hit[np.arange(m), first]
    return np.where(any_hit, start[np.arange(m), first], max_cells)


def cast_circles_reference(
    x: ArrayLike, y: ArrayLike, theta: ArrayLike, cx: ArrayLike, cy: ArrayLike, radii: ArrayLike
) -> FloatArray:
    """Distance along each ray ``(M,)`` to the nearest of ``K`` circles (inf if none), numpy.

    A ray starting inside a circle reads 0. Any consistent length unit.
    """
    x0 = np.asarray(x, dtype=np.float64).ravel()[:, None]
    y0 = np.asarray(y, dtype=np.float64).ravel()[:, None]
    th = np.asarray(theta, dtype=np.float64).ravel()[:, None]
    ccx = np.asarray(cx, dtype=np.float64).ravel()[None, :]
    ccy = np.asarray(cy, dtype=np.float64).ravel()[None, :]
    r = np.asarray(radii, dtype=np.float64).ravel()[None, :]
    fx, fy = x0 - ccx, y0 - ccy
    b = fx * np.cos(th) + fy * np.sin(th)
    c = fx * fx + fy * fy - r * r
    disc = b * b - c
    with np.errstate(invalid="ignore"):
        t = -b - np.sqrt(disc)
    t = np.where((disc >= 0.0) & (t >= 0.0), t, np.inf)
    t = np.where(c <= 0.0, 0.0, t)
    if t.shape[1] == 0:
        return np.full(x0.shape[0], np.inf)
    return np.asarray(t.min(axis=1), dtype=np.float64)


# --------------------------------------------------------------------------------------------
# numba kernels
# --------------------------------------------------------------------------------------------
#
# The casts are the cast mode of the grid traversal (tourbot.maps.traversal). They read a flat,
# row-major uint8 *padded* table (:func:`padded_table`): the grid's cells shifted by one inside a
# ring of ``OUTSIDE`` cells. ``BLOCKED`` marks blocking cells; in free cells the value is how many
# whole cells a ray may jump from there (0 for the plain DDA).


@numba.njit(cache=True)
def cast_rays_kernel(
    table: NDArray[np.uint8],
    width: int,
    rows: int,
    cols: int,
    ox: FloatArray,
    oy: FloatArray,
    oth: FloatArray,
    angles: FloatArray,
    max_cells: float,
    scale: float,
    outside_blocks: bool,
    out: Float32Array,
) -> None:
    """Fill ``out[i, b]`` with ``scale *`` the range in cells of beam ``b`` from pose ``i``.

    ``table`` is the flat padded table (see :func:`padded_table`, row length ``width = cols +
    2``) of a ``rows x cols`` grid; origins ``(ox, oy)`` in unpadded cell units, headings
    ``oth``. Each ray is the cast mode of the grid traversal
    (:mod:`tourbot.maps.traversal`): the plain Amanatides & Woo DDA on a table without jumps
    (Amanatides & Woo 1987, "A fast voxel traversal algorithm for ray tracing"), the
    distance-transform accelerated DDA of :class:`DistanceCaster` on one with jumps. Beams
    ``b`` to ``b + 3`` are cast side by side, one table read each in turn
    (:func:`tourbot.maps.traversal.cast_step`): their reads do not depend on each other, so
    the CPU overlaps them (four beams measured 1.15-1.26x faster than two, three about as fast
    as four, five to eight slower: the state of more rays no longer fits the registers).
    Not parallel: one core, by design.
    """
    # fmt: off
    n = ox.shape[0]
    nb = angles.shape[0]
    ca = np.cos(angles)
    sa = np.sin(angles)
    zero = np.int64(0)
    for i in range(n):
        ct = math.cos(oth[i])
        st = math.sin(oth[i])
        x0 = ox[i]
        y0 = oy[i]
        b = 0
        while b + 3 < nb:  # four beams side by side
            dxa = snap(ct * ca[b] - st * sa[b])
            dya = snap(st * ca[b] + ct * sa[b])
            dxb = snap(ct * ca[b + 1] - st * sa[b + 1])
            dyb = snap(st * ca[b + 1] + ct * sa[b + 1])
            dxc = snap(ct * ca[b + 2] - st * sa[b + 2])
            dyc = snap(st * ca[b + 2] + ct * sa[b + 2])
            dxd = snap(ct * ca[b + 3] - st * sa[b + 3])
            dyd = snap(st * ca[b + 3] + ct * sa[b + 3])
            da, ra, ta, cxa, cya, va = cast_start(
                table, width, rows, cols, x0, y0, dxa, dya, max_cells, outside_blocks
            )
            db, rb, tb, cxb, cyb, vb = cast_start(
                table, width, rows, cols, x0, y0, dxb, dyb, max_cells, outside_blocks
            )
            dc, rc, tc, cxc, cyc, vc = cast_start(
                table, width, rows, cols, x0, y0, dxc, dyc, max_cells, outside_blocks
            )
            dd, rd, td, cxd, cyd, vd = cast_start(
                table, width, rows, cols, x0, y0, dxd, dyd, max_cells, outside_blocks
            )
            fxa, fya, fxb, fyb, fxc, fyc, fxd, fyd = zero, zero, zero, zero, zero, zero, zero, zero
            ffa, ffb, ffc, ffd = False, False, False, False
            while not (da and db and dc and dd):
                if not da:
                    da, ra, ta, cxa, cya, va, fxa, fya, ffa = cast_step(
                        table, width, x0, y0, dxa, dya, max_cells, outside_blocks,
                        da, ra, ta, cxa, cya, va, fxa, fya, ffa,
                    )
                if not db:
                    db, rb, tb, cxb, cyb, vb, fxb, fyb, ffb = cast_step(
                        table, width, x0, y0, dxb, dyb, max_cells, outside_blocks,
                        db, rb, tb, cxb, cyb, vb, fxb, fyb, ffb,
                    )
                if not dc:
                    dc, rc, tc, cxc, cyc, vc, fxc, fyc, ffc = cast_step(
                        table, width, x0, y0, dxc, dyc, max_cells, outside_blocks,
                        dc, rc, tc, cxc, cyc, vc, fxc, fyc, ffc,
                    )
                if not dd:
                    dd, rd, td, cxd, cyd, vd, fxd, fyd, ffd = cast_step(
                        table, width, x0, y0, dxd, dyd, max_cells, outside_blocks,
                        dd, rd, td, cxd, cyd, vd, fxd, fyd, ffd,
                    )
            out[i, b] = scale * ra
            out[i, b + 1] = scale * rb
            out[i, b + 2] = scale * rc
            out[i, b + 3] = scale * rd
            b += 4
        while b < nb:  # the last beams (fewer than four) one at a time
            dx = ct * ca[b] - st * sa[b]
            dy = st * ca[b] + ct * sa[b]
            out[i, b] = scale * cast_ray(table, width, rows, cols, x0, y0, dx, dy, max_cells, outside_blocks)
            b += 1
    # fmt: on


def padded_table(blocked: NDArray[np.bool_], jumps: NDArray[np.uint8] | None = None) -> NDArray[np.uint8]:
    """The kernels' flat table: ``jumps`` (default 0) with ``BLOCKED`` cells, in an ``OUTSIDE`` ring."""
    rows, cols = blocked.shape
    table = np.full((rows + 2, cols + 2), OUTSIDE, dtype=np.uint8)
    body = np.zeros(blocked.shape, dtype=np.uint8) if jumps is None else jumps.astype(np.uint8)
    table[1:-1, 1:-1] = np.where(blocked, np.uint8(BLOCKED), body)
    return table.ravel()


@numba.njit(cache=True)
def circle_ranges(
    x: FloatArray,
    y: FloatArray,
    theta: FloatArray,
    angles: FloatArray,
    cx: FloatArray,
    cy: FloatArray,
    radii: FloatArray,
    out: Float32Array,
) -> None:
    """Lower ``out[i, b]`` to the distance to the nearest circle hit by beam ``b`` from pose ``i``.

    Ray-circle intersection ``|o + t d - c| = r``, smallest ``t >= 0``; a ray starting inside a
    circle reads 0. World units (metres).
    """
    n = x.shape[0]
    nb = angles.shape[0]
    k = cx.shape[0]
    ca = np.cos(angles)
    sa = np.sin(angles)
    for i in range(n):
        ct = math.cos(theta[i])
        st = math.sin(theta[i])
        for j in range(k):
            fx = x[i] - cx[j]
            fy = y[i] - cy[j]
            c = fx * fx + fy * fy - radii[j] * radii[j]
            if c <= 0.0:  # the laser is inside this circle
                out[i, :] = 0.0
                continue
            for b in range(nb):
                dx = ct * ca[b] - st * sa[b]
                dy = st * ca[b] + ct * sa[b]
                bb = fx * dx + fy * dy
                if bb >= 0.0:
                    continue  # circle behind the laser (and the laser outside it)
                disc = bb * bb - c
                if disc < 0.0:
                    continue
                t = -bb - math.sqrt(disc)
                out[i, b] = min(out[i, b], t)


# --------------------------------------------------------------------------------------------
# casters
# --------------------------------------------------------------------------------------------


class RangeCaster(Protocol):
    """The one caster interface: world laser poses ``(N, 3)`` and beam angles ``(B,)`` (laser
    frame) in, float32 ranges ``(N, B)`` in metres out, up to ``max_range``. Every caster of the
    project (:class:`RayCaster` and its kinds) satisfies it; what needs only ranges (the
    expected-range table, the grid localizer) asks for it."""

    max_range: float

    def cast(self, poses: ArrayLike, angles: ArrayLike) -> Float32Array: ...


class RayCaster:
    """Common front of the casters (a :class:`RangeCaster`): world poses and beam angles in,
    float32 metres out.

    A caster snapshots the grid when it is built: after the grid changes (a door closes, the
    mapper adds a wall) build a new one. :class:`DDACaster` builds in milliseconds;
    :class:`DistanceCaster` needs a distance transform (about 0.5-0.9 s for the 1765 x 564 FHW map
    at 5 cm on the shared machine) and is 4-5x faster per ray. Moving round things (legs,
    visitors) go through :meth:`cast_with_circles`, not into the grid.
    """

    table: NDArray[np.uint8]

    def __init__(self, grid: OccupancyGrid, max_range: float, unknown_blocks: bool = True) -> None:
        if not max_range > 0:
            raise MapError(f"max_range must be positive, got {max_range}")
        self.grid = grid
        self.max_range = float(max_range)
        self.unknown_blocks = unknown_blocks
        self.blocked = blocking_mask(grid, unknown_blocks)
        self.max_cells = self.max_range / grid.resolution

    @property
    def nbytes(self) -> int:
        """Memory held by the caster's precomputed table."""
        return int(self.table.nbytes)

    def cast(self, poses: ArrayLike, angles: ArrayLike) -> Float32Array:
        """Ranges ``(N, B)`` of beams at ``angles`` (laser frame) from laser ``poses`` ``(N, 3)``."""
        ox, oy, oth = rays_in_cells(self.grid, poses)
        a = beam_angles(angles)
        out = np.empty((ox.shape[0], a.shape[0]), dtype=np.float32)
        if out.size:
            rows, cols = self.grid.shape
            cast_rays_kernel(
                self.table,
                cols + 2,
                rows,
                cols,
                ox,
                oy,
                oth,
                a,
                self.max_cells,
                self.grid.resolution,
                self.unknown_blocks,
                out,
            )
        return out

    def cast_with_circles(
        self, poses: ArrayLike, angles: ArrayLike, circles_xy: ArrayLike, radii: ArrayLike
    ) -> Float32Array:
        """Like :meth:`cast`, with ``K`` circles (people's legs) ``circles_xy (K, 2)``, ``radii (K,)``
        in the world also blocking the beams."""
        out = self.cast(poses, angles)
        self.lower_to_circles(out, poses, angles, circles_xy, radii)
        return out

    def lower_to_circles(
        self, out: Float32Array, poses: ArrayLike, angles: ArrayLike, circles_xy: ArrayLike, radii: ArrayLike
    ) -> None:
        """Lower the ranges ``out`` ``(N, B)`` of :meth:`cast` in place to ``K`` circles
        ``circles_xy (K, 2)``, ``radii (K,)`` that also block the beams (a minimum: circles may be
        added in several calls with the same result)."""
        c = np.asarray(circles_xy, dtype=np.float64).reshape(-1, 2)
        r = np.ascontiguousarray(np.asarray(radii, dtype=np.float64).ravel())
        if r.shape[0] != c.shape[0]:
            raise MapError(f"{c.shape[0]} circle centres but {r.shape[0]} radii")
        if c.shape[0] and out.size:
            p = np.asarray(poses, dtype=np.float64)
            circle_ranges(
                np.ascontiguousarray(p[:, 0]),
                np.ascontiguousarray(p[:, 1]),
                np.ascontiguousarray(p[:, 2]),
                beam_angles(angles),
                np.ascontiguousarray(c[:, 0]),
                np.ascontiguousarray(c[:, 1]),
                r,
                out,
            )

    def cast_reference(self, poses: ArrayLike, angles: ArrayLike) -> Float32Array:
        """:meth:`cast` computed by :func:`cast_rays_reference` (slow; for tests)."""
        ox, oy, oth = rays_in_cells(self.grid, poses)
        a = beam_angles(angles)
        n, nb = ox.shape[0], a.shape[0]
        r = cast_rays_reference(
            self.blocked,
            np.repeat(ox, nb),
            np.repeat(oy, nb),
            (oth[:, None] + a[None, :]).ravel(),
            self.max_cells,
            self.unknown_blocks,
        )
        return (r * self.grid.resolution).astype(np.float32).reshape(n, nb)


class DDACaster(RayCaster):
    """Cell-by-cell DDA (Amanatides & Woo 1987): the exact baseline, range_libc's "Bresenham"."""

    def __init__(self, grid: OccupancyGrid, max_range: float, unknown_blocks: bool = True) -> None:
        super().__init__(grid, max_range, unknown_blocks)
        self.table = padded_table(self.blocked)


class DistanceCaster(RayCaster):
    """DDA accelerated by a Euclidean distance transform of the blocking cells.

    If the centre of a cell is ``D`` cells from the centre of the nearest blocking cell, every
    point of the cell is farther than ``D - sqrt(2)`` from every point of every blocking cell (two
    half-diagonals), so a ray may jump that far at once (ray marching on a distance transform, as
    range_libc's "RM", Walsh & Karaman 2018). The table keeps ``floor(D - sqrt(2))`` (at most 253)
    as one byte per cell. Near obstacles (no whole-cell jump) the ray takes exact DDA steps, so
    the ranges are the DDA's ones, not a within-epsilon approximation. The ring around the grid
    counts as blocking for the jumps, so a jump never leaves the table.
    """

    def __init__(self, grid: OccupancyGrid, max_range: float, unknown_blocks: bool = True) -> None:
        from scipy import ndimage

        super().__init__(grid, max_range, unknown_blocks)
        walls = np.pad(self.blocked, 1, constant_values=True)
        dist = ndimage.distance_transform_edt(~walls)[1:-1, 1:-1]
        # 1e-3: the bound stays strict whatever the rounding of the fixed-point positions
        safe = np.floor(np.clip(dist - _SQRT2 - 1e-3, 0.0, MAX_JUMP)).astype(np.uint8)
        self.table = padded_table(self.blocked, safe)
