"""The reference map of a corrected log: a log-odds occupancy grid built from the reference poses.

Occupancy grid mapping with known poses (Moravec and Elfes 1985, the grid maps of Burgard et al.
Sec. 2.1; Thrun, Burgard and Fox, *Probabilistic Robotics*, Ch. 9, Table 9.1): every cell keeps
the log odds ``l = n_hit * l_occ + n_miss * l_free`` of the beams that ended in it (hits) and
passed through it (misses), and its probability is ``1 - 1 / (1 + exp(l))`` (a 0.5 prior).
Clearing free space along every beam removes what moved: the visitors' legs that polluted the
FHW log are hit a few times and passed through many more times.

Which cell a beam hits
    A map's ranges are read by ray casting (:mod:`tourbot.maps.raycast`), which returns where a
    ray *enters* the first blocking cell. Marking the cell that contains the endpoint makes every
    cast range short by the distance from that cell's entry to the endpoint (half a cell on
    average). With ``hit="crossing"`` (the default) the hit cell is the one the beam enters at the
    cell-boundary crossing nearest to the measured endpoint, and the cells before it are the
    misses, so a ray cast along the beam through the map returns the measured range to within
    half a cell crossing. ``hit="endpoint"`` marks the endpoint's own cell (the textbook model;
    better for likelihood fields, which measure distances to cell centres).

:func:`trace_beams` is the numba kernel: one pass over all beams, each walked by the trace mode of
the grid traversal (:func:`tourbot.maps.traversal.trace_ray`, Amanatides and Woo).
:func:`trace_beams_reference` is its plain-numpy twin, compared by property tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numba
import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose
from tourbot.maps.grid import UNKNOWN, MapError, OccupancyGrid

# numba inlines the traversal into this file's cached kernels: it recompiles them only when
# this file changes (clear __pycache__/*.nbi after a change of traversal.py)
from tourbot.maps.traversal import AXIS, EPS, trace_ray
from tourbot.records import LaserGeometry, RobotLog, Scan

__all__ = [
    "ReferenceMapParams",
    "beam_rays",
    "build_reference_map",
    "grid_from_counts",
    "map_quality",
    "trace_beams",
    "trace_beams_reference",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int32]


@dataclass(frozen=True)
class ReferenceMapParams:
    """How the reference map is built (defaults: Probabilistic Robotics Table 9.1 conventions).

    ``l_occ``/``l_free`` are the log odds a hit/miss adds: p = 0.7 and p = 0.4 (``log(0.7/0.3)``,
    ``log(0.4/0.6)``), the usual inverse sensor model values. ``max_free_range`` caps how far
    free space is cleared along "no return" beams (a laser's maximum reading also comes from glass
    and black surfaces, so they clear only the nearby space). ``margin`` pads the map around the
    endpoints and poses. ``min_hits`` keeps a cell from being occupied on fewer hits (one stray
    return is not a wall).
    """

    resolution: float = 0.05
    l_occ: float = math.log(0.7 / 0.3)
    l_free: float = math.log(0.4 / 0.6)
    max_free_range: float = 10.0
    margin: float = 1.0
    hit: Literal["crossing", "endpoint"] = "crossing"
    min_hits: int = 1
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196


# --------------------------------------------------------------------------------------------------
# Beam tracing: numba kernel and numpy reference


@numba.njit(cache=True)
def _trace_all(
    ox: np.ndarray,
    oy: np.ndarray,
    theta: np.ndarray,
    length: np.ndarray,
    is_hit: np.ndarray,
    crossing: bool,
    hits: np.ndarray,
    misses: np.ndarray,
) -> None:
    rows, cols = hits.shape
    for i in range(ox.shape[0]):
        trace_ray(
            ox[i], oy[i], math.cos(theta[i]), math.sin(theta[i]), length[i], is_hit[i], crossing,
            rows, cols, hits, misses,
        )  # fmt: skip


def trace_beams(
    ox: FloatArray,
    oy: FloatArray,
    theta: FloatArray,
    length: FloatArray,
    is_hit: NDArray[np.bool_],
    shape: tuple[int, int],
    *,
    crossing: bool = True,
) -> tuple[IntArray, IntArray]:
    """Hit and miss counts ``(rows, cols)`` of beams given in cell units (numba kernel).

    Beam ``i`` starts at ``(ox[i], oy[i])`` (x along columns, y along rows, in cells), heads
    ``theta[i]`` and is ``length[i]`` cells long; ``is_hit[i]`` says whether it ended on an
    obstacle (else every cell it crosses is a miss).
    """
    hits = np.zeros(shape, dtype=np.int32)
    misses = np.zeros(shape, dtype=np.int32)
    _trace_all(
        np.ascontiguousarray(ox, dtype=np.float64),
        np.ascontiguousarray(oy, dtype=np.float64),
        np.ascontiguousarray(theta, dtype=np.float64),
        np.ascontiguousarray(length, dtype=np.float64),
        np.ascontiguousarray(is_hit, dtype=np.bool_),
        crossing,
        hits,
        misses,
    )
    return hits, misses


def trace_beams_reference(
    ox: FloatArray,
    oy: FloatArray,
    theta: FloatArray,
    length: FloatArray,
    is_hit: NDArray[np.bool_],
    shape: tuple[int, int],
    *,
    crossing: bool = True,
) -> tuple[IntArray, IntArray]:
    """Plain-numpy twin of :func:`trace_beams`: cut every beam at every grid line it crosses.

    The pieces between consecutive crossings are the cells the beam visits (the cell under each
    piece's midpoint). With ``crossing``, the hit cell is the piece starting at the crossing
    nearest to the endpoint; otherwise the piece holding the endpoint.
    """
    rows, cols = shape
    x0 = np.asarray(ox, dtype=np.float64)
    y0 = np.asarray(oy, dtype=np.float64)
    th = np.asarray(theta, dtype=np.float64)
    ln = np.asarray(length, dtype=np.float64)
    hit_flag = np.asarray(is_hit, dtype=bool)
    hits = np.zeros(shape, dtype=np.int32)
    misses = np.zeros(shape, dtype=np.int32)
    m = x0.size
    if m == 0:
        return hits, misses
    dx, dy = np.cos(th), np.sin(th)
    dx[np.abs(dx) < AXIS] = 0.0
    dy[np.abs(dy) < AXIS] = 0.0
    # look beyond the endpoint: the nearest crossing and the piece after it may lie past it
    reach = ln + 3.0

    def crossings(a0: FloatArray, d: FloatArray) -> FloatArray:
        a1 = a0 + reach * d
        lo = np.floor(np.minimum(a0, a1))
        n = int(np.max(np.ceil(np.maximum(a0, a1)) - lo)) + 2
        k = lo[:, None] + np.arange(n)[None, :]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = (k - a0[:, None]) * (1.0 / d[:, None])  # the kernel's floats: times 1 / d
        ok = np.isfinite(t) & (t > 0.0) & (t <= reach[:, None])
        return np.where(ok, t, np.inf)

    t = np.concatenate([np.zeros((m, 1)), crossings(x0, dx), crossings(y0, dy)], axis=1)
    t.sort(axis=1)
    # a crossing through a cell corner appears twice (or almost): keep one
    with np.errstate(invalid="ignore"):  # inf - inf past the last crossing
        dup = np.diff(t, axis=1) <= EPS
    t[:, 1:][dup] = np.inf
    t.sort(axis=1)
    start = t[:, :-1]
    end = t[:, 1:]
    valid = np.isfinite(end)
    mid = np.where(valid, 0.5 * (start + np.where(valid, end, 0.0)), 0.0)
    cx = np.floor(x0[:, None] + mid * dx[:, None]).astype(np.int64)
    cy = np.floor(y0[:, None] + mid * dy[:, None]).astype(np.int64)
    lnc = ln[:, None]
    contains = valid & (start <= lnc) & (end > lnc)
    j_end = np.argmax(contains, axis=1)  # the piece holding the endpoint
    if crossing:
        rr = np.arange(m)
        near_start = (ln - start[rr, j_end]) <= (end[rr, j_end] - ln)
        j_hit = np.where(near_start, j_end, j_end + 1)
    else:
        j_hit = j_end
    piece = np.arange(start.shape[1])[None, :]
    is_miss = valid & np.where(hit_flag[:, None], piece < j_hit[:, None], start < lnc)
    is_hit_piece = hit_flag[:, None] & (piece == j_hit[:, None])
    inside = (cx >= 0) & (cx < cols) & (cy >= 0) & (cy < rows)
    for mask, counts in ((is_miss & inside, misses), (is_hit_piece & inside, hits)):
        np.add.at(counts, (cy[mask], cx[mask]), 1)
    return hits, misses


# --------------------------------------------------------------------------------------------------
# From a log to a map


def beam_rays(
    log: RobotLog, *, use_reference: bool = True
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
    """Every beam of ``log`` as world rays: origins x, y, headings, ranges, and "ended on a hit".

    Beams start at the laser (pose ``compose(robot pose, geometry.offset)``); readings at or above
    ``max_range`` are "no return" (not hits); readings at or below ``min_range`` are left out.
    Scans without a pose are skipped.
    """
    xs, ys, ths, rs, hs = [], [], [], [], []
    for scan in log.scans:
        pose = scan.reference if use_reference else scan.odom
        if pose is None:
            continue
        g = scan.geometry
        laser = compose(pose, g.offset)
        xs.append(np.full(g.num_beams, laser[0]))
        ys.append(np.full(g.num_beams, laser[1]))
        ths.append(laser[2] + g.angles)
        hit = (scan.ranges < g.max_range) & (scan.ranges > g.min_range)
        keep = hit | (scan.ranges >= g.max_range)  # readings below min_range say nothing
        xs[-1], ys[-1], ths[-1] = xs[-1][keep], ys[-1][keep], ths[-1][keep]
        rs.append(scan.ranges[keep])
        hs.append(hit[keep])
    if not xs:
        raise MapError(f"{log.source}: no scan has a {'reference' if use_reference else 'odometry'} pose")
    return (
        np.concatenate(xs),
        np.concatenate(ys),
        np.concatenate(ths),
        np.concatenate(rs).astype(np.float64),
        np.concatenate(hs),
    )


def build_reference_map(
    log: RobotLog,
    resolution: float | None = None,
    params: ReferenceMapParams | None = None,
    *,
    use_reference: bool = True,
) -> OccupancyGrid:
    """The log-odds occupancy grid of ``log`` from its reference poses (see the module docstring).

    ``resolution`` (metres) overrides ``params.resolution``; by default 0.05 m. Cells no beam
    reached are unknown (-1). ``use_reference=False`` maps with the odometry poses instead (to see
    how much the odometry smears a map).
    """
    p = params or ReferenceMapParams()
    if resolution is not None and resolution != p.resolution:
        p = replace(p, resolution=resolution)
    if not p.resolution > 0:
        raise MapError(f"resolution must be positive, got {p.resolution}")
    x, y, th, r, is_hit = beam_rays(log, use_reference=use_reference)
    length = np.where(is_hit, r, np.minimum(r, p.max_free_range))
    ex, ey = x + length * np.cos(th), y + length * np.sin(th)
    pts_x = np.concatenate([x, ex[is_hit]])
    pts_y = np.concatenate([y, ey[is_hit]])
    x0 = math.floor((pts_x.min() - p.margin) / p.resolution) * p.resolution
    y0 = math.floor((pts_y.min() - p.margin) / p.resolution) * p.resolution
    cols = math.ceil((pts_x.max() + p.margin - x0) / p.resolution)
    rows = math.ceil((pts_y.max() + p.margin - y0) / p.resolution)
    if rows * cols > 400_000_000:
        raise MapError(f"the map would have {rows} x {cols} cells; use a coarser resolution")
    inv = 1.0 / p.resolution
    hits, misses = trace_beams(
        (x - x0) * inv, (y - y0) * inv, th, length * inv, is_hit, (rows, cols), crossing=p.hit == "crossing"
    )
    return grid_from_counts(hits, misses, (x0, y0), p)


def grid_from_counts(
    hits: IntArray, misses: IntArray, corner: tuple[float, float], params: ReferenceMapParams
) -> OccupancyGrid:
    """The occupancy grid of hit and miss counts (log odds ``n_hit * l_occ + n_miss * l_free``).

    ``corner`` is the world position of cell (0, 0)'s corner; cells no beam reached are unknown.
    """
    p = params
    logodds = hits * p.l_occ + misses * p.l_free
    prob = (1.0 - 1.0 / (1.0 + np.exp(np.clip(logodds, -50.0, 50.0)))).astype(np.float32)
    prob[(hits > 0) & (hits < p.min_hits) & (prob > p.occupied_thresh)] = 0.5
    prob[(hits == 0) & (misses == 0)] = UNKNOWN
    return OccupancyGrid(
        prob=prob,
        resolution=p.resolution,
        origin=(corner[0], corner[1], 0.0),
        occupied_thresh=p.occupied_thresh,
        free_thresh=p.free_thresh,
    )


def map_quality(
    grid: OccupancyGrid, log: RobotLog, *, max_scans: int | None = None, shorter_ignored: float | None = None
) -> dict[str, float]:
    """How well ``grid`` explains ``log``: ray casts from the reference poses against the ranges.

    Over every beam with a return (``min_range < r < max_range``): the median, mean and 90th
    percentile of ``|cast - measured|`` in metres, and the fraction within 5 and 10 cm. Casting uses
    the project's ray caster (:class:`tourbot.maps.raycast.DistanceCaster`). ``shorter_ignored``:
    beams shorter than the cast by more than this (m) are left out (a crowd only shortens beams).
    """
    from tourbot.maps.raycast import DistanceCaster

    scans = [s for s in log.scans if s.reference is not None]
    if not scans:
        raise MapError(f"{log.source}: no scan has a reference pose to measure the map from")
    if max_scans is not None and len(scans) > max_scans:
        scans = [scans[i] for i in np.linspace(0, len(scans) - 1, max_scans).round().astype(int)]
    errors = []
    returns = 0
    by_geometry: dict[LaserGeometry, list[Scan]] = {}
    for scan in scans:
        by_geometry.setdefault(scan.geometry, []).append(scan)
    for g, group in by_geometry.items():
        caster = DistanceCaster(grid, g.max_range)
        robot = np.array([s.reference for s in group], dtype=np.float64)
        lasers = compose(robot, np.broadcast_to(np.asarray(g.offset, dtype=np.float64), robot.shape))
        cast = np.asarray(caster.cast(lasers, g.angles), dtype=np.float64)
        ranges = np.stack([s.ranges for s in group])
        valid = (ranges < g.max_range) & (ranges > g.min_range)
        returns += int(valid.sum())
        if shorter_ignored is not None:
            valid &= ranges >= cast - shorter_ignored
        errors.append(np.abs(cast[valid] - ranges[valid]))
    err = np.concatenate(errors)
    if not err.size:
        nan = float("nan")
        stats = dict.fromkeys(("median_abs_error", "mean_abs_error", "p90_abs_error"), nan)
        return stats | {"within_5cm": 0.0, "within_10cm": 0.0, "beams": 0.0, "kept": 0.0}
    return {
        "median_abs_error": float(np.median(err)),
        "mean_abs_error": float(err.mean()),
        "p90_abs_error": float(np.percentile(err, 90)),
        "within_5cm": float(np.mean(err <= 0.05)),
        "within_10cm": float(np.mean(err <= 0.10)),
        "beams": float(err.size),
        "kept": err.size / max(returns, 1),  # of the beams with a return, those measured
    }
