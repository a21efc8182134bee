"""Compressed directional distance transform (CDDT) ray casting: an approximate, table-driven caster.

After Walsh & Karaman (2018), "CDDT: Fast Approximate 2D Ray Casting for Accelerated
Localization". Headings are discretized into ``directions`` bins over the full circle; for each
of the ``directions / 2`` line directions ``phi_k = 2 pi k / directions`` in ``[0, pi)`` the plane
is cut into parallel *lanes* ``lane_width`` cells wide, and each lane stores, sorted, where its
centre line enters and leaves blocking cells. A ray is answered by one search in one lane instead
of a walk through the grid:

- heading bin ``d = round(theta / (2 pi / directions))``, ``k = d mod directions / 2``, and the
  beam's angle to its bin ``delta = theta - 2 pi d / directions``;
- in direction ``k``'s frame the laser is at ``u = x cos phi + y sin phi`` along the lanes and
  ``v = -x sin phi + y cos phi`` across them (cell units); the lane is the one the beam is in
  ``aim`` cells out, ``floor((v +- aim delta - v_min_k) / lane_width)`` (``-`` backwards);
- forwards (``d < directions / 2``) the range is ``start - u`` of the first run of blocking cells
  ahead of ``u``, backwards the same lane is read the other way, ``u - end`` of the last run
  behind ``u``; ``u`` inside a run reads 0, no run ``max_range``.

The lane is the paper's "compressed" directional distance transform: of the distance along the
lane to the next blocking cell only the zero points are kept, here as merged ``[start, end)`` runs,
so a lane holds only the points where a ray enters (or, read backwards, leaves) blocking cells,
which is what the paper's pruned variant (PCDDT) keeps; and the reverse heading reuses the lane,
as the paper's ``theta`` and ``theta + pi`` share one. Run ends are stored as ``uint16`` in steps
of ``1 / steps`` cell (``steps`` 16 on maps up to about 200 m across); a lane is ``[0, s_0, e_0,
s_1, e_1, ..., 65535]``, so the count ``p`` of its values below ``u`` gives everything: ``p`` even
means ``u`` is inside a run, otherwise the run ends around ``u`` are the ``p - 1``-th and
``p``-th values.

What it approximates: a range is the exact range (to one step, runs rounded outwards) of the
*lane ray*, cast along the bin's direction from the laser moved sideways onto the lane's centre
line. That ray is off the beam by at most half a bin in angle (``pi / directions``) and crosses it
``aim`` cells out, give or take half a lane; ``aim`` defaults to the mean range of the map's beams
(:meth:`CDDTCaster.typical_range`), where the hits gather. Ranges differ from the DDA's where a
beam grazes a wall or passes an edge (``tourbot bench kernels`` reports by how much). The blocking
conventions are those of :mod:`tourbot.maps.raycast`: unknown cells block when
``unknown_blocks``, and the outside of the grid counts as unknown (a ring of blocking cells
around the grid, and beyond it everything blocks; a laser outside the grid or in a blocking cell
reads 0); with ``unknown_blocks=False`` the outside is empty.

Speed (why the kernel is staged): a query is a handful of reads in a table of megabytes, so its
cost is memory latency. :func:`cddt_kernel` handles the beams of one pose in three passes (lanes,
then lane bounds, then the searches), so that the slow reads of different beams do not wait for
one another (1.5-1.8x over one beam at a time, side by side on FHW).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.maps.grid import MapError, OccupancyGrid
from tourbot.maps.raycast import Float32Array, FloatArray, RayCaster, _angles, _rays_in_cells

__all__ = ["CDDTCaster", "LaneTable", "build_lanes", "cddt_kernel", "cddt_reference"]

IntArray = NDArray[np.int64]
Uint16Array = NDArray[np.uint16]

LOW = 0  # sentinel before a lane's first run end
HIGH = 65535  # sentinel after its last run start
_STEPS = 16.0  # stored steps per cell, at most (fewer on grids too large for uint16)
_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class LaneTable:
    """The lanes of a CDDT, flat.

    ``params[k]`` holds, for line direction ``k``: ``(a, b, c)`` with the laser's stored
    coordinate along the lanes ``x a + y b + c``, ``(d, e, f)`` with its lane coordinate
    ``x d + y e + f`` (lane ``floor`` of it), the number of lanes and ``1 / lane_width``. Lane
    ``j`` of direction ``k`` is ``lane_base[k] + j``; its values are ``bounds[ptr[g]:ptr[g + 1]]``.
    ``ring``: the grid is surrounded by blocking cells, and so is everything beside the lanes.
    """

    directions: int
    ring: bool
    lane_width: float
    steps: float
    params: FloatArray
    lane_base: IntArray
    ptr: NDArray[np.int32]
    bounds: Uint16Array

    @property
    def nbytes(self) -> int:
        return int(self.params.nbytes + self.lane_base.nbytes + self.ptr.nbytes + self.bounds.nbytes)

    @property
    def runs(self) -> int:
        return int((self.bounds.size - (self.ptr.size - 1) * 2) // 2)


def _edge_cells(blocked: NDArray[np.bool_], ring: bool) -> tuple[IntArray, IntArray]:
    """``(x, y)`` cell coordinates (unpadded) of the blocking cells next to a non-blocking one.

    Only these cells bound the runs: a centre line passes from a non-blocking cell into a blocking
    one, or back, through a cell with a non-blocking neighbour (one of the eight). The cells deep
    inside walls and unknown areas are left out, and the gaps they leave in the runs are filled
    again (:func:`_fill_inner_gaps`, and the ring's runs extended to the lanes' ends). With
    ``ring`` the grid is surrounded by a ring of blocking cells (the outside as unknown).
    """
    if ring:
        mask = np.pad(blocked, 1, constant_values=True)
        around = np.pad(mask, 1, constant_values=True)
        off = 1
    else:
        mask = blocked
        around = np.pad(mask, 1, constant_values=False)
        off = 0
    rows, cols = mask.shape
    inner = np.ones(mask.shape, dtype=bool)
    for dy in range(3):
        for dx in range(3):
            inner &= around[dy : dy + rows, dx : dx + cols]
    ys, xs = np.nonzero(mask & ~inner)
    return xs.astype(np.int64) - off, ys.astype(np.int64) - off


def _lane_runs(
    x: FloatArray, y: FloatArray, c: float, s: float, v0: float, width: float
) -> tuple[IntArray, FloatArray, FloatArray]:
    """Merged runs ``(lane, start, end)`` of unit squares ``[x, x + 1) x [y, y + 1)`` on the lane
    centre lines ``v = v0 + (j + 1/2) width`` of direction ``(c, s)``, sorted by lane then start."""
    v_sq = -x * s + y * c  # v of the square's corner (x, y); the others add -s and/or c
    vlo = v_sq + min(0.0, -s) + min(0.0, c)
    vhi = v_sq + max(0.0, -s) + max(0.0, c)
    first = np.ceil((vlo - v0) / width - 0.5).astype(np.int64)  # lowest centre line >= vlo
    span = math.ceil((abs(s) + abs(c)) / width) + 1
    lanes, lo_all, hi_all = [], [], []
    for extra in range(span):
        j = first + extra
        vc = v0 + (j + 0.5) * width
        ok = vc < vhi
        # points u (c, s) + vc (-s, c) of the line inside the square: one slab per axis
        px, py = -vc * s, vc * c
        lo = np.full(x.shape, -np.inf)
        hi = np.full(x.shape, np.inf)
        if abs(c) > 1e-12:
            a, b = (x - px) / c, (x + 1.0 - px) / c
            lo, hi = np.maximum(lo, np.minimum(a, b)), np.minimum(hi, np.maximum(a, b))
        else:
            ok &= (px >= x) & (px < x + 1.0)
        if abs(s) > 1e-12:
            a, b = (y - py) / s, (y + 1.0 - py) / s
            lo, hi = np.maximum(lo, np.minimum(a, b)), np.minimum(hi, np.maximum(a, b))
        else:
            ok &= (py >= y) & (py < y + 1.0)
        ok &= hi - lo > 1e-9  # a line through a corner does not enter the square
        lanes.append(j[ok])
        lo_all.append(lo[ok])
        hi_all.append(hi[ok])
    lane = np.concatenate(lanes)
    ua = np.concatenate(lo_all)
    ub = np.concatenate(hi_all)
    order = np.lexsort((ua, lane))
    lane, ua, ub = lane[order], ua[order], ub[order]
    if lane.size == 0:
        return lane, ua, ub
    # a run starts where an interval begins after all earlier ones of its lane have ended; the
    # offset per lane keeps lanes apart in one running maximum
    shift = lane * (2.0 * (np.abs(ua).max() + np.abs(ub).max()) + 8.0)
    reach = np.maximum.accumulate(shift + ub)
    head = np.ones(lane.size, dtype=bool)
    head[1:] = (lane[1:] != lane[:-1]) | (shift[1:] + ua[1:] > reach[:-1])
    heads = np.flatnonzero(head)
    tails = np.append(heads[1:], lane.size) - 1
    return lane[heads], ua[heads], reach[tails] - shift[heads]


def _fill_inner_gaps(
    lane: IntArray,
    ua: FloatArray,
    ub: FloatArray,
    c: float,
    s: float,
    v0: float,
    width: float,
    solid: NDArray[np.bool_],
    off: int,
    outside_blocks: bool,
) -> tuple[IntArray, FloatArray, FloatArray]:
    """Merge runs of a lane separated only by left-out (deep) blocking cells.

    Between two runs, a centre line is either in non-blocking cells or in blocking cells left out
    by :func:`_edge_cells` (to get from one to the other it would cross a kept cell), so the cell
    under the middle of the gap tells which. ``solid`` is the blocking mask with its ring, its
    cell ``(0, 0)`` at ``(-off, -off)``; beyond it, cells block when ``outside_blocks``.
    """
    if lane.size < 2:
        return lane, ua, ub
    inner = lane[1:] == lane[:-1]
    mid = 0.5 * (ub[:-1] + ua[1:])
    vc = v0 + (lane[:-1] + 0.5) * width
    cx = np.floor(mid * c - vc * s).astype(np.int64) + off
    cy = np.floor(mid * s + vc * c).astype(np.int64) + off
    rows, cols = solid.shape
    inside = (cx >= 0) & (cx < cols) & (cy >= 0) & (cy < rows)
    deep = np.full(mid.shape, outside_blocks)
    deep[inside] = solid[cy[inside], cx[inside]]
    head = np.ones(lane.size, dtype=bool)
    head[1:] = ~(inner & deep)
    heads = np.flatnonzero(head)
    tails = np.append(heads[1:], lane.size) - 1
    return lane[heads], ua[heads], ub[tails]


def build_lanes(
    blocked: NDArray[np.bool_], directions: int = 256, ring: bool = True, lane_width: float = 1.0
) -> LaneTable:
    """The CDDT of a ``blocked[row, col]`` mask (plain numpy, vectorised per direction).

    ``directions`` heading bins over the circle, a power of two >= 4; ``ring``: the grid is
    surrounded by blocking cells (the outside blocks). Each edge cell adds, to every lane whose
    centre line crosses it, the interval where it does (the slab method); the intervals of a lane
    are merged into runs (touching ones merge) and stored in steps of ``1 / steps`` cell.
    """
    if directions < 4 or directions & (directions - 1):
        raise MapError(f"directions must be a power of two >= 4, got {directions}")
    if not 0.0 < lane_width <= 2.0:
        raise MapError(f"lane_width must be in (0, 2] cells, got {lane_width}")
    rows, cols = blocked.shape
    half = directions // 2
    pad = 1.0 if ring else 0.0
    box_x = np.array([-pad, cols + pad, -pad, cols + pad])
    box_y = np.array([-pad, -pad, rows + pad, rows + pad])
    steps = min(_STEPS, (HIGH - 2) / (math.hypot(rows, cols) + 2 * pad + 4.0))
    xs, ys = _edge_cells(blocked, ring)
    solid = np.pad(blocked, 1, constant_values=True) if ring else blocked
    x, y = xs.astype(np.float64), ys.astype(np.float64)
    params = np.zeros((half, 8))
    lanes = np.zeros(half, dtype=np.int64)
    counts: list[IntArray] = []
    values: list[Uint16Array] = []
    for k in range(half):
        phi = k * _TWO_PI / directions
        c, s = math.cos(phi), math.sin(phi)
        u0 = math.floor(float((box_x * c + box_y * s).min())) - 1.0
        box_v = -box_x * s + box_y * c
        v0 = math.floor(float(box_v.min()))
        lanes[k] = math.ceil((float(box_v.max()) - v0) / lane_width) + 1
        along = (steps * c, steps * s, 1.0 - steps * u0)
        across = (-s / lane_width, c / lane_width, -v0 / lane_width)
        params[k] = (*along, *across, lanes[k], 1.0 / lane_width)
        lane, ua, ub = _lane_runs(x, y, c, s, v0, lane_width)
        lane, ua, ub = _fill_inner_gaps(lane, ua, ub, c, s, v0, lane_width, solid, int(pad), ring)
        keep = (lane >= 0) & (lane < lanes[k])
        lane, ua, ub = lane[keep], ua[keep], ub[keep]
        qa = np.clip(np.floor((ua - u0) * steps + 1.0), 1, HIGH - 1)
        qb = np.clip(np.ceil((ub - u0) * steps + 1.0), 1, HIGH - 1)
        if lane.size > 1:  # runs rounded outwards into each other (gaps under a step) merge
            head = np.ones(lane.size, dtype=bool)
            head[1:] = (lane[1:] != lane[:-1]) | (qa[1:] > qb[:-1])
            heads = np.flatnonzero(head)
            tails = np.append(heads[1:], lane.size) - 1
            lane, qa, qb = lane[heads], qa[heads], qb[tails]
        n = np.bincount(lane, minlength=int(lanes[k])).astype(np.int64)
        if ring:
            # a lane beside the ring is off the grid, which blocks: one run over all of it
            empty = np.flatnonzero(n == 0)
            order = np.argsort(np.concatenate([lane, empty]), kind="stable")
            lane = np.concatenate([lane, empty])[order]
            qa = np.concatenate([qa, np.ones(empty.size)])[order]
            qb = np.concatenate([qb, np.full(empty.size, HIGH - 1.0)])[order]
            n[empty] = 1
        # per lane: LOW, s0, e0, s1, e1, ..., HIGH
        first = np.concatenate([[0], np.cumsum(2 * n + 2)[:-1]])
        out = np.empty(int(2 * n.sum() + 2 * lanes[k]), dtype=np.uint16)
        out[first] = LOW
        out[first + 2 * n + 1] = HIGH
        rank = np.arange(lane.size) - np.repeat(np.cumsum(n) - n, n)
        at = first[lane] + 1 + 2 * rank
        out[at] = qa
        out[at + 1] = qb
        if ring:
            # a lane ends in the ring, which blocks: its first run reaches back to where the lane
            # begins and its last one on to where it ends, even where deep cells were left out
            out[first + 1] = 1
            out[first + 2 * n] = HIGH - 1
        counts.append(2 * n + 2)
        values.append(out)
    lane_base = np.concatenate([[0], np.cumsum(lanes)[:-1]]).astype(np.int64)
    ptr = np.concatenate([[0], np.cumsum(np.concatenate(counts))])
    if ptr[-1] >= 2**31:
        raise MapError(f"the CDDT of this grid needs {ptr[-1]} values, more than int32 indexes")
    return LaneTable(directions, ring, lane_width, steps, params, lane_base, ptr.astype(np.int32),
                     np.concatenate(values))  # fmt: skip


# --------------------------------------------------------------------------------------------
# queries
# --------------------------------------------------------------------------------------------


def _wrapped(theta: ArrayLike) -> FloatArray:
    return np.asarray(np.mod(np.asarray(theta, dtype=np.float64), _TWO_PI), dtype=np.float64)


def cddt_reference(
    table: LaneTable,
    origin_blocked: ArrayLike,
    ox: ArrayLike,
    oy: ArrayLike,
    heading: ArrayLike,
    angle: ArrayLike,
    max_cells: float,
    aim: float = 0.0,
) -> FloatArray:
    """Ranges in cells of flat rays ``(M,)`` (plain numpy): origins in cell units, laser headings
    and beam angles (both wrapped to ``[0, 2 pi)``), each laser's ``origin_blocked`` (reads 0),
    lanes taken where the rays are ``aim`` cells out.

    The same arithmetic as :func:`cddt_kernel`, the lane search as a count over every lane padded
    to the longest one.
    """
    x = np.asarray(ox, dtype=np.float64).ravel()
    y = np.asarray(oy, dtype=np.float64).ravel()
    per_rad = table.directions / _TWO_PI
    fb = (np.asarray(heading, dtype=np.float64) * per_rad + 0.5) + np.asarray(angle) * per_rad
    d = fb.astype(np.int64)
    half = table.directions // 2
    back = (d & half) != 0
    k = d & (half - 1)
    p = table.params[k]
    uq = x * p[:, 0] + y * p[:, 1] + p[:, 2]
    sway = aim * ((fb - 0.5 - d) * (_TWO_PI / table.directions)) * p[:, 7]
    jf = x * p[:, 3] + y * p[:, 4] + p[:, 5] + np.where(back, -sway, sway)
    ok = (jf >= 0.0) & (jf < p[:, 6])
    g = np.where(ok, table.lane_base[k] + np.where(ok, jf, 0.0).astype(np.int64), 0)
    lo = table.ptr[g].astype(np.int64)
    m = table.ptr[g + 1] - lo
    width = int(m.max()) if m.size else 1
    idx = lo[:, None] + np.arange(width)[None, :]
    valid = np.arange(width)[None, :] < m[:, None]
    vals = np.where(valid, table.bounds[np.where(valid, idx, 0)], HIGH).astype(np.int64)
    ui = np.ceil(np.clip(uq, 1.0, HIGH - 1.0)).astype(np.int64)  # integer b < ui exactly when b < uq
    cnt = np.sum(vals < ui[:, None], axis=1)
    at = lo + cnt - 1
    prev_end = table.bounds[at].astype(np.float64)
    next_start = table.bounds[np.minimum(at + 1, table.bounds.size - 1)].astype(np.float64)
    max_q = max_cells * table.steps
    fwd = np.where(next_start < HIGH, next_start - uq, max_q)
    bwd = np.where(prev_end > LOW, uq - prev_end, max_q)
    r = np.where(back, bwd, fwd)
    r = np.where(cnt % 2 == 0, 0.0, np.clip(r, 0.0, max_q))
    r = np.where(ok, r, 0.0 if table.ring else max_q)  # beside every lane: off the grid
    r = np.where(np.asarray(origin_blocked, dtype=bool).ravel(), 0.0, r)
    return np.asarray(r / table.steps, dtype=np.float64)


@numba.njit(cache=True)
def cddt_kernel(
    directions: int,
    steps: float,
    params: FloatArray,
    lane_base: IntArray,
    ptr: NDArray[np.int32],
    bounds: Uint16Array,
    origin_blocked: NDArray[np.bool_],
    ox: FloatArray,
    oy: FloatArray,
    heading: FloatArray,
    angles: FloatArray,
    max_cells: float,
    scale: float,
    aim: float,
    outside_blocks: bool,
    out: Float32Array,
) -> int:
    """Fill ``out[i, b]`` with ``scale *`` the CDDT range in cells of beam ``b`` from pose ``i``.

    Headings and angles wrapped to ``[0, 2 pi)``. The query of :func:`cddt_reference`, per pose in
    three passes over its beams: (1) bin, lane and position along it, (2) the lane's bounds in
    ``ptr`` and a read of its first and last values, (3) a branch-free binary search for the count
    of values below the position. The reads of pass 2 do not depend on each other, so the CPU
    keeps many in flight, and pass 3 finds its lanes in cache. Returns a checksum of the pass-2
    reads (they are done for their effect on the cache). Not parallel: one core, by design.
    """
    n = ox.shape[0]
    nb = angles.shape[0]
    half = directions // 2
    kmask = half - 1
    per_rad = directions / (2.0 * math.pi)
    a_bins = angles * per_rad
    max_q = max_cells * steps
    beside = 0.0 if outside_blocks else max_q  # range of a ray beside every lane
    to_out = scale / steps
    bin_rad = 2.0 * math.pi / directions
    los = np.empty(nb, dtype=np.int64)
    lens = np.empty(nb, dtype=np.int64)
    pos = np.empty(nb)
    back = np.empty(nb, dtype=np.bool_)
    lane = np.empty(nb, dtype=np.int64)
    touched = 0
    for i in range(n):
        if origin_blocked[i]:
            out[i, :] = 0.0
            continue
        x = ox[i]
        y = oy[i]
        base = heading[i] * per_rad + 0.5
        for b in range(nb):  # pass 1
            fb = base + a_bins[b]
            d = np.int64(fb)
            back[b] = (d & half) != 0
            k = d & kmask
            pos[b] = x * params[k, 0] + y * params[k, 1] + params[k, 2]
            sway = aim * ((fb - 0.5 - d) * bin_rad) * params[k, 7]  # aim * (theta - bin) / lane width
            jf = x * params[k, 3] + y * params[k, 4] + params[k, 5] + (-sway if back[b] else sway)
            lane[b] = lane_base[k] + np.int64(jf) if 0.0 <= jf < params[k, 6] else -1
        for b in range(nb):  # pass 2
            g = max(lane[b], 0)
            lo = np.int64(ptr[g])
            m = np.int64(ptr[g + 1]) - lo
            los[b] = lo
            lens[b] = m if lane[b] >= 0 else 0
            touched += bounds[lo] + bounds[lo + m - 1]
        for b in range(nb):  # pass 3
            m = lens[b]
            r = beside  # lanes have two values at least; none: no lane
            if m > 0:
                uq = pos[b]
                ui = np.uint16(math.ceil(min(max(uq, 1.0), HIGH - 1.0)))  # b < ui iff b < uq
                lo = los[b]
                at = lo  # last value below ui: bounds[lo] = LOW is, bounds[lo + m - 1] = HIGH is not
                while m > 1:
                    h = m >> 1
                    at += h * np.int64(bounds[at + h] < ui)
                    m -= h
                prev_end = np.float64(bounds[at])
                next_start = np.float64(bounds[at + 1])
                if back[b]:
                    r = uq - prev_end if prev_end > LOW else max_q
                else:
                    r = next_start - uq if next_start < HIGH else max_q
                r = min(max(r, 0.0), max_q) if ((at - lo) & 1) == 0 else 0.0
            out[i, b] = to_out * r
    return touched


class CDDTCaster(RayCaster):
    """Approximate caster on a compressed directional distance transform (Walsh & Karaman 2018).

    ``directions`` heading bins over the full circle (a power of two; default 256, 1.4 degree),
    lanes ``lane_width`` cells wide, each beam's lane taken where the beam is ``aim_range`` metres
    out (default: the mean range of beams cast from the grid's non-blocking cells, see
    :meth:`typical_range`). The table does not depend on ``max_range``. See the module docstring
    for the query and what it approximates.
    """

    def __init__(
        self,
        grid: OccupancyGrid,
        max_range: float,
        unknown_blocks: bool = True,
        directions: int = 256,
        lane_width: float = 1.0,
        aim_range: float | None = None,
    ) -> None:
        super().__init__(grid, max_range, unknown_blocks)
        self.lanes = build_lanes(self.blocked, directions, ring=unknown_blocks, lane_width=lane_width)
        if aim_range is not None and not 0.0 <= aim_range < math.inf:
            raise MapError(f"aim_range must be a finite distance >= 0, got {aim_range}")
        self.aim_cells = self.typical_range() if aim_range is None else aim_range / grid.resolution

    def typical_range(self, lasers: int = 256, beams: int = 64) -> float:
        """Mean range in cells (capped at ``max_range``) of ``beams`` beams around each of
        ``lasers`` non-blocking cells drawn with a fixed seed, lanes taken at the laser.

        The lane ray meets the true ray where its lane is taken; the hits are spread around the
        mean range, which is where the lane should be taken to keep it closest to the beam where
        the beam ends (least squares over the hit distances).
        """
        free = np.flatnonzero(~self.blocked.ravel())
        if free.size == 0:
            return 0.0
        rng = np.random.default_rng(0)
        cells = rng.choice(free, size=min(lasers, free.size), replace=False)
        cols = self.grid.shape[1]
        ox = (cells % cols + 0.5).astype(np.float64)
        oy = (cells // cols + 0.5).astype(np.float64)
        heading = rng.uniform(0.0, _TWO_PI, cells.size)
        angles = np.linspace(0.0, _TWO_PI, beams, endpoint=False)
        out = np.empty((cells.size, beams), dtype=np.float32)
        self._kernel(np.zeros(cells.size, dtype=np.bool_), ox, oy, heading, angles, 1.0, 0.0, out)
        return float(out.mean())

    def _kernel(
        self,
        blocked: NDArray[np.bool_],
        ox: FloatArray,
        oy: FloatArray,
        heading: FloatArray,
        angles: FloatArray,
        scale: float,
        aim: float,
        out: Float32Array,
    ) -> None:
        t = self.lanes
        cddt_kernel(
            t.directions, t.steps, t.params, t.lane_base, t.ptr, t.bounds, blocked, ox, oy, heading,
            angles, self.max_cells, scale, aim, t.ring, out,
        )  # fmt: skip

    @property
    def nbytes(self) -> int:
        return self.lanes.nbytes

    def _lasers(self, poses: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
        """Origins in cell units, wrapped headings, and whether each laser reads 0 everywhere."""
        ox, oy, oth = _rays_in_cells(self.grid, poses)
        rows, cols = self.grid.shape
        cx = np.floor(ox).astype(np.int64)
        cy = np.floor(oy).astype(np.int64)
        inside = (cx >= 0) & (cx < cols) & (cy >= 0) & (cy < rows)
        blocked = np.full(ox.shape, self.unknown_blocks)
        blocked[inside] = self.blocked[cy[inside], cx[inside]]
        return ox, oy, _wrapped(oth), blocked

    def cast(self, poses: ArrayLike, angles: ArrayLike) -> Float32Array:
        ox, oy, heading, blocked = self._lasers(poses)
        a = _wrapped(_angles(angles))
        out = np.empty((ox.shape[0], a.shape[0]), dtype=np.float32)
        if out.size:
            self._kernel(blocked, ox, oy, heading, a, self.grid.resolution, self.aim_cells, out)
        return out

    def cast_cddt_reference(self, poses: ArrayLike, angles: ArrayLike) -> Float32Array:
        """:meth:`cast` computed by :func:`cddt_reference` (slow; for tests)."""
        ox, oy, heading, blocked = self._lasers(poses)
        a = _wrapped(_angles(angles))
        n, nb = ox.shape[0], a.shape[0]
        r = cddt_reference(
            self.lanes,
            np.repeat(blocked, nb),
            np.repeat(ox, nb),
            np.repeat(oy, nb),
            np.repeat(heading, nb),
            np.tile(a, n),
            self.max_cells,
            self.aim_cells,
        )
        return (r * self.grid.resolution).astype(np.float32).reshape(n, nb)
