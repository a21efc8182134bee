"""Incremental grid mapping by scan matching (Burgard et al., Sec. 2.1, Eq. 1-2).

At each scan the robot predicts its pose from odometry, aligns the scan to the map built so far
(:mod:`tourbot.mapping.scan_matching`) and extends the map with the scan at the aligned pose. The
map keeps hit and miss counts per cell (beams traced with :func:`tourbot.maps.reference.
trace_beams`), from which the log-odds occupancy follows; for alignment, the occupied cells are
blurred with Gaussians of a few widths (coarse to fine), kept up to date by stamping a Gaussian at
each cell whose state a scan changed.

People filtering (Sec. 5) enters through two per-beam inputs of :meth:`IncrementalMapper.add_scan`:
``match_weights`` (Eq. 12: ``1 - P(hit a person)``) scale each beam during alignment, and
``integrate`` says which beams are written into the map (beams ending on a person are left out).
"""

from __future__ import annotations

import collections
import functools
import math
import time
from dataclasses import dataclass, field, replace
from typing import Literal

import numba
import numpy as np
from numpy.typing import NDArray

from tourbot.errors import TourbotError
from tourbot.geometry import compose, relative, wrap_angle
from tourbot.mapping.free_space import free_sectors
from tourbot.mapping.scan_matching import MatchParams, curvature, hill_climb, score
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.reference import ReferenceMapParams, grid_from_counts, trace_beams
from tourbot.records import Scan

__all__ = ["IncrementalMapper", "MapperParams", "MapperStep", "MappingError"]

FloatArray = NDArray[np.float64]


class MappingError(TourbotError):
    """A log that cannot be mapped (no odometry, no scans)."""


@dataclass(frozen=True)
class MapperParams:
    """Parameters of incremental mapping.

    ``smoothing`` are the standard deviations (m) of the pose errors integrated into the map for
    alignment, coarse to fine (Sec. 2.1: "we integrate over small Gaussian errors in the robot
    pose"). ``max_match_range`` caps the beams used for alignment; ``max_free_range`` how far free
    space is cleared along "no return" beams. ``beam_step`` uses every k-th beam for alignment, and
    ``match_beams`` caps how many beams (evenly spread) align a scan. ``level_halvings`` (one per
    smoothing level) says how often the hill-climbing steps halve at each level (None: the match
    parameters' ``halvings`` at every level); a coarse level needs no millimetres. The defaults
    (180 beams, 3 / 3 / 5 halvings) were chosen on the Intel, ACES and Freiburg 079 logs: as
    accurate as all beams and 6 halvings everywhere, and 1.3-1.4x faster on 360-beam scans.

    ``free_sectors``: a cell inside a scan's free sectors (:mod:`tourbot.mapping.free_space`: between
    two beams, nearer than both, within ``sector_width`` of one of them and ``sector_range`` of the
    laser, ``sector_margin`` short of the nearer end) that no beam of the scan crossed or ended in
    gets one miss too, so that what a laser saw around on both sides is cleared (None: misses
    only along the beams, the default).

    ``unknown_level``: what the smoothed map reads where no beam has been (a wall reads 1, free
    space 0); ``window``: how many of the last scans the map aligned against holds. Chosen on the
    rebuilt odometry of Intel, ACES, FHW and Freiburg 079 by leaving one log out (the values with
    the lowest geometric-mean aligned error on the other three, among 0.05 / 0.1 / 0.15 / 0.25
    and 150 / 300 scans): 0.05 and 300 on three of the four folds. With 0.25 an endpoint cast into
    unexplored space cost little, and a scan could turn by 20-50 degrees to put its returns there
    (Intel's front end lost track at scan 761 so, its odometry within 3 degrees each step);
    Freiburg 079 (a scan every 0.1 m) needs the longer window. ``docs/results/loopclosure.md``.

    ``prior_restart``: the climb is made a second time from the predicted pose, over the levels
    from this one (0 the coarsest) to the finest, and the better of the two on the finest map's
    objective (Eq. 1 there) is kept; None (the default, as measured on the odometry logs): the
    coarse-to-fine climb alone. Matching without odometry needs it (:mod:`tourbot.mapping.
    ego_motion`): a coarse level can pull a scan of parallel shelves one aisle over.
    """

    resolution: float = 0.05
    smoothing: tuple[float, ...] = (0.25, 0.1, 0.05)
    max_match_range: float = 25.0
    max_free_range: float = 10.0
    beam_step: int = 1
    match_beams: int | None = 180
    level_halvings: tuple[int, ...] | None = (3, 3, 5)
    unknown_level: float = 0.05
    window: int | None = 300
    initial_size: float = 40.0
    grow_margin: float = 15.0
    match: MatchParams = field(default_factory=MatchParams)
    cells: ReferenceMapParams = field(default_factory=lambda: ReferenceMapParams(hit="endpoint"))
    free_sectors: bool = False
    sector_margin: float = 0.10
    sector_slope: float = 0.04
    sector_width: float = math.inf
    sector_range: float = 25.0
    prior_restart: int | None = None

    def __post_init__(self) -> None:
        if self.level_halvings is not None and len(self.level_halvings) != len(self.smoothing):
            raise MappingError(
                f"level_halvings has {len(self.level_halvings)} entries for {len(self.smoothing)} "
                "smoothing levels"
            )


@dataclass(frozen=True)
class MapperStep:
    """What one scan did: its aligned pose, the odometry prediction, the alignment's objective,
    the time it took and the alignment's information ``(3, 3)`` (world ``x, y, theta``; zero
    when the scan was not aligned): the curvature of the objective at the aligned pose, map
    likelihood and odometry prior together (:func:`tourbot.mapping.scan_matching.curvature`)."""

    pose: tuple[float, float, float]
    predicted: tuple[float, float, float]
    score: float
    seconds: float
    information: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))


class IncrementalMapper:
    """Builds a grid map and the robot's path from scans and odometry, one scan at a time."""

    def __init__(self, params: MapperParams | None = None, start: FloatArray | None = None) -> None:
        self.params = params or MapperParams()
        self._start = None if start is None else np.asarray(start, dtype=np.float64)
        self._pose: FloatArray | None = None
        self._odom: FloatArray | None = None
        res = self.params.resolution
        n = _PAD_UNIT * math.ceil(self.params.initial_size / res / _PAD_UNIT)
        self._hits = np.zeros((n, n), np.int32)  # every scan: the map that is returned
        self._misses = np.zeros((n, n), np.int32)
        self._near_hits = np.zeros((n, n), np.int32)  # the last ``window`` scans: aligned against
        self._near_misses = np.zeros((n, n), np.int32)
        self._recent: collections.deque[_Footprint] = collections.deque()
        # each smoothed field lives on cells ``factor`` times coarser, so that a wide Gaussian stays
        # a small stamp (a coarse-to-fine pyramid)
        self._factors = [_factor(sig, self.params.resolution) for sig in self.params.smoothing]
        self._fields = [np.full((n // f, n // f), self.params.unknown_level) for f in self._factors]
        self._x0 = self._y0 = math.nan  # world coordinates of cell (0, 0)'s corner
        self.poses: list[tuple[float, float, float]] = []
        self.last: MapperStep | None = None  # the latest scan's step

    # ------------------------------------------------------------------------------------------
    @property
    def pose(self) -> FloatArray | None:
        """The latest aligned pose, or None before the first scan."""
        return None if self._pose is None else self._pose.copy()

    def add_scan(
        self,
        scan: Scan,
        *,
        match_weights: FloatArray | None = None,
        integrate: NDArray[np.bool_] | None = None,
    ) -> MapperStep:
        """Align ``scan`` to the map so far and add it to the map; returns the step's result."""
        step = self.match(scan, match_weights=match_weights)
        self.integrate(scan, np.asarray(step.pose), keep=integrate)
        return step

    def predict(self, scan: Scan) -> FloatArray:
        """The pose of ``scan`` predicted from the last aligned pose and odometry."""
        return self._predict_from(self._odom_of(scan))

    def _predict_from(self, odom: FloatArray) -> FloatArray:
        if self._pose is None or self._odom is None:
            return np.asarray(self._start if self._start is not None else odom, dtype=np.float64).copy()
        return compose(self._pose, relative(self._odom, odom))

    def match(self, scan: Scan, *, match_weights: FloatArray | None = None) -> MapperStep:
        """Align ``scan`` to the map so far (Eq. 1, with beam weights of Eq. 12); the map is unchanged.

        ``match_weights`` (per beam, in [0, 1]) scale each beam's log likelihood: people-filtered
        mapping gives ``1 - P(hit a person)``.
        """
        pts, w = self._matched_beams(scan, match_weights)
        return self.match_points(pts, w, self._odom_of(scan))

    def match_points(self, points: FloatArray, weights: FloatArray, odom: FloatArray) -> MapperStep:
        """:meth:`match` for endpoints ``(N, 2)`` given in the robot frame with their ``weights``
        (each times the match's ``beam_weight``), the robot's odometry pose ``odom`` at their time:
        the returns of several lasers of one robot, each moved to the robot frame, align as one
        scan (:mod:`tourbot.mapping.ego_motion`)."""
        t0 = time.perf_counter()
        odom = np.asarray(odom, dtype=np.float64)
        predicted = self._predict_from(odom)
        info = np.zeros((3, 3))
        if self._pose is None or self._odom is None:
            self._centre_on(predicted)
            best, val = predicted.copy(), 0.0
        else:
            pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
            w = np.asarray(weights, dtype=np.float64) * self.params.match.beam_weight
            best, val, info = self._align(pts, w, predicted, relative(self._odom, odom))
        self._pose = best
        self._odom = odom
        pose = (float(best[0]), float(best[1]), float(best[2]))
        self.poses.append(pose)
        self.last = MapperStep(
            pose=pose,
            predicted=(float(predicted[0]), float(predicted[1]), float(predicted[2])),
            score=val,
            seconds=time.perf_counter() - t0,
            information=info,
        )
        return self.last

    @staticmethod
    def _odom_of(scan: Scan) -> FloatArray:
        if scan.odom is None:
            raise MappingError("incremental mapping needs the odometry pose of every scan")
        return np.asarray(scan.odom, dtype=np.float64)

    def evidence(self, points: FloatArray) -> FloatArray:
        """Log-odds of occupancy (every scan so far) at world ``points`` ``(B, 2)``; 0 outside."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        out = np.zeros(len(pts))
        if math.isnan(self._x0) or len(pts) == 0:
            return out
        res = self.params.resolution
        cols = np.floor((pts[:, 0] - self._x0) / res).astype(np.int64)
        rows = np.floor((pts[:, 1] - self._y0) / res).astype(np.int64)
        ok = (rows >= 0) & (rows < self._hits.shape[0]) & (cols >= 0) & (cols < self._hits.shape[1])
        c = self.params.cells
        out[ok] = self._hits[rows[ok], cols[ok]] * c.l_occ + self._misses[rows[ok], cols[ok]] * c.l_free
        return out

    def grid(self, extra_hits: FloatArray | None = None) -> OccupancyGrid:
        """The map so far as an occupancy grid (cells no beam reached are unknown).

        ``extra_hits``: world points ``(N, 2)`` whose cells count one hit more each in the grid
        returned (not in the map kept here; points outside it are ignored)."""
        cells = replace(self.params.cells, resolution=self.params.resolution)
        hits = self._hits
        pts = (
            np.zeros((0, 2))
            if extra_hits is None
            else np.asarray(extra_hits, dtype=np.float64).reshape(-1, 2)
        )
        if len(pts) and not math.isnan(self._x0):
            res = self.params.resolution
            cols = np.floor((pts[:, 0] - self._x0) / res).astype(np.int64)
            rows = np.floor((pts[:, 1] - self._y0) / res).astype(np.int64)
            ok = (rows >= 0) & (rows < hits.shape[0]) & (cols >= 0) & (cols < hits.shape[1])
            hits = hits.copy()
            np.add.at(hits, (rows[ok], cols[ok]), 1)
        return grid_from_counts(hits, self._misses, (self._x0, self._y0), cells)

    # ------------------------------------------------------------------------------------------
    def _centre_on(self, pose: FloatArray) -> None:
        half = self._hits.shape[0] * self.params.resolution / 2.0
        res = self.params.resolution
        self._x0 = math.floor((pose[0] - half) / res) * res
        self._y0 = math.floor((pose[1] - half) / res) * res

    def _endpoints(self, scan: Scan, cap: float) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
        """Beam endpoints in the robot frame, which beams returned, and the beams' headings."""
        g = scan.geometry
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        hit = (ranges < g.max_range) & (ranges > g.min_range) & (ranges < cap)
        ang = g.offset[2] + g.angles
        ex = g.offset[0] + ranges * np.cos(ang)
        ey = g.offset[1] + ranges * np.sin(ang)
        return np.stack([ex, ey], axis=1), hit, ang

    def _matched_beams(self, scan: Scan, match_weights: FloatArray | None) -> tuple[FloatArray, FloatArray]:
        """The endpoints (robot frame) of the beams that align ``scan`` and their weights."""
        p = self.params
        pts, hit, _ = self._endpoints(scan, p.max_match_range)
        w = np.ones(len(pts))
        if match_weights is not None:
            w = w * np.asarray(match_weights, dtype=np.float64)
        sel = np.zeros(len(pts), bool)
        step = p.beam_step
        if p.match_beams is not None:
            step = max(step, math.ceil(len(pts) / p.match_beams))
        sel[::step] = True
        sel &= hit & (w > 0)
        return pts[sel], w[sel]

    def score_points(self, points: FloatArray, pose: FloatArray) -> float:
        """The log likelihood (Eq. 1's first factor, ``beam_weight`` per endpoint) of endpoints
        ``(N, 2)`` in the robot frame at world ``pose``, on the finest smoothed map."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if math.isnan(self._x0) or len(pts) == 0:
            return 0.0
        m = self.params.match
        origin = np.array([self._x0, self._y0, 0.0])
        res = self.params.resolution * self._factors[-1]
        local = np.asarray(pose, dtype=np.float64) - origin
        return score(self._fields[-1], res, local, pts, np.full(len(pts), m.beam_weight), m.eps)

    def _align(
        self, pts: FloatArray, w: FloatArray, predicted: FloatArray, delta: FloatArray
    ) -> tuple[FloatArray, float, FloatArray]:
        """The aligned pose, its objective and its information (the objective's curvature there,
        on the finest smoothed map, plus the odometry prior's)."""
        p = self.params
        m = p.match
        if len(pts) < 10:
            return predicted, 0.0, np.zeros((3, 3))
        trans = float(np.hypot(delta[0], delta[1]))
        rot = abs(float(wrap_angle(delta[2])))
        sigma_xy = m.sigma_xy + m.k_xy * trans
        sigma = np.array([sigma_xy, sigma_xy, m.sigma_theta + m.k_theta * rot + m.k_theta_xy * trans])
        origin = np.array([self._x0, self._y0, 0.0])
        prior = predicted - origin
        best = prior.copy()
        val = 0.0
        for level, (fieldk, factor) in enumerate(zip(self._fields, self._factors, strict=True)):
            scale = 1.0 / (2**level)
            res = p.resolution * factor
            halve = None if p.level_halvings is None else p.level_halvings[level]
            best, val = hill_climb(fieldk, res, best, pts, w, prior, sigma, m, scale, halve)
        if p.prior_restart is not None:
            # the same climb from the prediction, skipping the coarsest levels; the better of the two
            # on the finest map (Eq. 1 there) wins: a coarse level widens the basin, but on a room
            # of parallel shelves it can also pull the scan one aisle over
            alt = prior.copy()
            for level in range(p.prior_restart, len(self._fields)):
                res = p.resolution * self._factors[level]
                halve = None if p.level_halvings is None else p.level_halvings[level]
                alt, alt_val = hill_climb(
                    self._fields[level], res, alt, pts, w, prior, sigma, m, 1.0 / (2**level), halve
                )
            if alt_val > val:
                best, val = alt, alt_val
        # the curvature over a cell of the finest field, the heading step turning the scan's
        # median endpoint by as much
        res = p.resolution * self._factors[-1]
        reach = max(float(np.median(np.hypot(pts[:, 0], pts[:, 1]))), res)
        info = curvature(self._fields[-1], res, best, pts, w, m.eps, np.array([res, res, res / reach]))
        info = info + np.diag(1.0 / sigma**2)
        best = best + origin
        best[2] = float(wrap_angle(best[2]))
        return best, val, info

    def integrate(
        self,
        scan: Scan,
        pose: FloatArray,
        *,
        keep: NDArray[np.bool_] | None = None,
        free_only: NDArray[np.bool_] | None = None,
        into: Literal["both", "map", "alignment"] = "both",
    ) -> None:
        """Write ``scan`` into the map at ``pose``; only the beams in ``keep`` when given.

        Beams in ``free_only`` add their free space but not their endpoint: the space in front of a
        person the beam hit was seen free, the person's cell is not an obstacle of the map.
        ``into`` says which map gets the scan: the map that :meth:`grid` returns, the map that
        scans are aligned against (the last ``window`` scans), or both (people-filtered mapping
        aligns against each scan at once but writes the map a few scans late).
        """
        if math.isnan(self._x0):
            self._centre_on(np.asarray(pose, dtype=np.float64))
        p = self.params
        g = scan.geometry
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        is_hit = (ranges < g.max_range) & (ranges > g.min_range)
        use = is_hit | (ranges >= g.max_range)
        if keep is not None:
            use &= np.asarray(keep, dtype=bool)
        keep = use
        if not keep.any():
            return
        if free_only is not None:
            # free space up to the cell before the endpoint's (about the misses the hit would add)
            cut = np.asarray(free_only, dtype=bool) & is_hit
            short = np.clip(ranges - 1.5 * p.resolution, 0.0, p.max_free_range)
            ranges = np.where(cut, short, ranges)
            is_hit = is_hit & ~cut
        laser = compose(pose, g.offset)
        th = laser[2] + g.angles[keep]
        length = np.where(is_hit[keep], ranges[keep], np.minimum(ranges[keep], p.max_free_range))
        ex = laser[0] + length * np.cos(th)
        ey = laser[1] + length * np.sin(th)
        margin = 3.0 * max(p.smoothing) + 2 * p.resolution
        xmin, xmax = min(ex.min(), laser[0]) - margin, max(ex.max(), laser[0]) + margin
        ymin, ymax = min(ey.min(), laser[1]) - margin, max(ey.max(), laser[1]) + margin
        self._ensure(xmin, ymin, xmax, ymax)
        res = p.resolution
        c0 = math.floor((xmin - self._x0) / res)
        r0 = math.floor((ymin - self._y0) / res)
        c1 = math.ceil((xmax - self._x0) / res)
        r1 = math.ceil((ymax - self._y0) / res)
        bx, by = self._x0 + c0 * res, self._y0 + r0 * res
        inv = 1.0 / res
        hits, misses = trace_beams(
            np.full(th.shape, (laser[0] - bx) * inv),
            np.full(th.shape, (laser[1] - by) * inv),
            th,
            length * inv,
            is_hit[keep],
            (r1 - r0, c1 - c0),
            crossing=p.cells.hit == "crossing",
        )
        sectors = p.free_sectors and into != "alignment"
        # the beams' own counts, for the map scans are aligned against (not needed for the map alone)
        beam_counts = None if sectors and into == "map" else _counted_cells(hits, misses)
        if sectors:
            # every beam's free length (0 for beams left out), to clear what lies between beams;
            # for the map only: scans are aligned against what the beams themselves saw
            seen = np.where(is_hit, ranges, np.minimum(ranges, p.max_free_range))
            seen = np.where(keep, seen * (1.0 - p.sector_slope), 0.0)
            free = free_sectors(
                hits.shape,
                (laser[0] - bx) * inv,
                (laser[1] - by) * inv,
                laser[2] + float(g.angles[0]),
                g.angle_increment,
                seen * inv,
                margin=p.sector_margin * inv,
                width=p.sector_width * inv,
                cap=p.sector_range * inv,
            )
            misses[free & (misses == 0) & (hits == 0)] = 1  # after the beams' own counts
            mr, mc, mh, mm = _counted_cells(hits, misses)
        else:
            assert beam_counts is not None
            mr, mc, mh, mm = beam_counts
        c = p.cells
        if into != "alignment":  # the whole map
            _apply_counts(self._hits, self._misses, r0 + mr, c0 + mc, mh, mm, c.l_occ, c.l_free)
        if into == "map" or beam_counts is None:
            return
        lr, lc, dh, dm = beam_counts
        rr, cc = r0 + lr, c0 + lc
        self._change(rr, cc, dh, dm)
        if p.window is not None:
            self._recent.append(_Footprint(bx, by, (int(hits.shape[0]), int(hits.shape[1])), lr, lc, dh, dm))
            if len(self._recent) > p.window:
                self._forget(self._recent.popleft())

    def _forget(self, old: _Footprint) -> None:
        """Take an old scan out of the map that scans are aligned against."""
        res = self.params.resolution
        r0 = round((old.y0 - self._y0) / res)
        c0 = round((old.x0 - self._x0) / res)
        self._change(r0 + old.rows, c0 + old.cols, -old.hits, -old.misses)

    def _change(
        self,
        rr: NDArray[np.int64],
        cc: NDArray[np.int64],
        d_hits: NDArray[np.int32],
        d_misses: NDArray[np.int32],
    ) -> None:
        """Add count changes to the aligned-against map and update the smoothed fields.

        Each field is the sum over cells of the cell's value (1 occupied, ``unknown_level`` scaled
        unexplored, 0 free) times a Gaussian stamp normalised so that a wall reads 1; only the cells
        whose category changed are stamped again (their new value minus their old one).
        """
        c = self.params.cells
        before, after = _apply_counts(
            self._near_hits,
            self._near_misses,
            np.asarray(rr, dtype=np.int64),
            np.asarray(cc, dtype=np.int64),
            np.asarray(d_hits, dtype=np.int32),
            np.asarray(d_misses, dtype=np.int32),
            c.l_occ,
            c.l_free,
        )
        changed = before != after
        if not changed.any():
            return
        rows, cols, b, a = rr[changed], cc[changed], before[changed], after[changed]
        levels = zip(self.params.smoothing, self._factors, self._fields, strict=True)
        for sigma, factor, fieldk in levels:
            stamp, unknown = _stamp_of(
                sigma / (self.params.resolution * factor), factor, self.params.unknown_level
            )
            value = np.array([0.0, 1.0, unknown]) / (factor * factor)
            fr, fc, w = rows // factor, cols // factor, value[a] - value[b]
            if factor > 1:  # one stamp per coarse cell, with the changes of its fine cells summed
                key, inverse = np.unique(fr * fieldk.shape[1] + fc, return_inverse=True)
                fr, fc = np.divmod(key, fieldk.shape[1])
                w = np.bincount(inverse, weights=w)
            _stamp_cells(fieldk, fr, fc, w, stamp)

    def _ensure(self, xmin: float, ymin: float, xmax: float, ymax: float) -> None:
        """Grow the grid so that the world box fits, with a margin."""
        res = self.params.resolution
        rows, cols = self._hits.shape
        grow = math.ceil(self.params.grow_margin / res)
        left = max(0, math.ceil((self._x0 - xmin) / res))
        bottom = max(0, math.ceil((self._y0 - ymin) / res))
        right = max(0, math.ceil((xmax - (self._x0 + cols * res)) / res))
        top = max(0, math.ceil((ymax - (self._y0 + rows * res)) / res))
        if not (left or bottom or right or top):
            return

        def up(n: int) -> int:  # whole coarse cells, so that the pyramid stays aligned
            return _PAD_UNIT * math.ceil((n + grow) / _PAD_UNIT) if n else 0

        pad = ((up(bottom), up(top)), (up(left), up(right)))
        self._hits = np.pad(self._hits, pad)
        self._misses = np.pad(self._misses, pad)
        self._near_hits = np.pad(self._near_hits, pad)
        self._near_misses = np.pad(self._near_misses, pad)
        self._fields = [
            np.pad(fk, [(a // f, b // f) for a, b in pad], constant_values=self.params.unknown_level)
            for fk, f in zip(self._fields, self._factors, strict=True)
        ]
        self._x0 -= pad[1][0] * res
        self._y0 -= pad[0][0] * res


_PAD_UNIT = 12  # the grid grows by whole cells of every pyramid level (factors 1, 2, 3, 4)


def _factor(sigma: float, resolution: float) -> int:
    """How much coarser than the map the field smoothed with ``sigma`` can be (1 to 4)."""
    return int(min(4, max(1, math.floor(sigma / (1.5 * resolution)))))


@functools.cache
def _stamp_of(s: float, factor: int, unknown_level: float) -> tuple[NDArray[np.float64], float]:
    """The Gaussian stamp of width ``s`` field cells, for map cells ``factor`` times finer.

    A map cell adds ``value / factor**2`` times the stamp at its field cell; the stamp is scaled
    so that a straight wall one map cell thick reads 1 at its middle, and the returned value of an
    unexplored map cell makes unexplored space read ``unknown_level``.
    """
    radius = math.ceil(3.0 * s)
    k = np.arange(-radius, radius + 1, dtype=np.float64)
    g = np.exp(-0.5 * (k / s) ** 2)
    kernel = np.outer(g, g)
    kernel /= kernel.sum()
    wall = float(kernel[:, radius].sum())
    return factor * kernel / wall, unknown_level * wall / factor


@numba.njit(cache=True)
def _stamp_cells(
    field: np.ndarray, rows: np.ndarray, cols: np.ndarray, weights: np.ndarray, stamp: np.ndarray
) -> None:
    """Add ``weights[i] * stamp`` centred on each cell ``(rows[i], cols[i])`` of ``field``."""
    radius = stamp.shape[0] // 2
    height, width = field.shape
    for i in range(rows.shape[0]):
        w = weights[i]
        for a in range(-radius, radius + 1):
            r = rows[i] + a
            if r < 0 or r >= height:
                continue
            for b in range(-radius, radius + 1):
                c = cols[i] + b
                if 0 <= c < width:
                    field[r, c] += w * stamp[a + radius, b + radius]


def _stamp_cells_reference(
    field: NDArray[np.float64],
    rows: NDArray[np.int64],
    cols: NDArray[np.int64],
    weights: NDArray[np.float64],
    stamp: NDArray[np.float64],
) -> None:
    """Plain-numpy twin of :func:`_stamp_cells`."""
    radius = stamp.shape[0] // 2
    padded = np.zeros((field.shape[0] + 2 * radius, field.shape[1] + 2 * radius))
    for r, c, w in zip(rows, cols, weights, strict=True):
        padded[r : r + 2 * radius + 1, c : c + 2 * radius + 1] += w * stamp
    field += padded[radius : radius + field.shape[0], radius : radius + field.shape[1]]


@numba.njit(cache=True)
def _category(h: int, m: int, l_occ: float, l_free: float) -> int:
    """0 free, 1 occupied, 2 unexplored: what hit and miss counts say of a cell."""
    if h == 0 and m == 0:
        return 2
    return 1 if h > 0 and h * l_occ + m * l_free > 0 else 0


@numba.njit(cache=True)
def _apply_counts(
    hits: np.ndarray,
    misses: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    d_hits: np.ndarray,
    d_misses: np.ndarray,
    l_occ: float,
    l_free: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Add count changes cell by cell; the category of each cell before and after its change."""
    n = rows.shape[0]
    before = np.empty(n, np.int8)
    after = np.empty(n, np.int8)
    for i in range(n):
        r = rows[i]
        c = cols[i]
        before[i] = _category(hits[r, c], misses[r, c], l_occ, l_free)
        hits[r, c] += d_hits[i]
        misses[r, c] += d_misses[i]
        after[i] = _category(hits[r, c], misses[r, c], l_occ, l_free)
    return before, after


def _apply_counts_reference(
    hits: NDArray[np.int32],
    misses: NDArray[np.int32],
    rows: NDArray[np.int64],
    cols: NDArray[np.int64],
    d_hits: NDArray[np.int32],
    d_misses: NDArray[np.int32],
    l_occ: float,
    l_free: float,
) -> tuple[NDArray[np.int8], NDArray[np.int8]]:
    """Plain-numpy twin of :func:`_apply_counts` (cells given once each)."""

    def category() -> NDArray[np.int8]:
        h = hits[rows, cols]
        m = misses[rows, cols]
        occupied = (h > 0) & (h * l_occ + m * l_free > 0)
        return np.where((h == 0) & (m == 0), 2, occupied.astype(np.int8)).astype(np.int8)

    before = category()
    hits[rows, cols] += d_hits
    misses[rows, cols] += d_misses
    return before, category()


@numba.njit(cache=True)
def _counted_cells(
    hits: np.ndarray, misses: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The cells with a hit or a miss (row-major order) and their counts, in one pass."""
    rows_n, cols_n = hits.shape
    n = 0
    for r in range(rows_n):
        for c in range(cols_n):
            if hits[r, c] != 0 or misses[r, c] != 0:
                n += 1
    rr = np.empty(n, np.int64)
    cc = np.empty(n, np.int64)
    hh = np.empty(n, np.int32)
    mm = np.empty(n, np.int32)
    k = 0
    for r in range(rows_n):
        for c in range(cols_n):
            if hits[r, c] != 0 or misses[r, c] != 0:
                rr[k] = r
                cc[k] = c
                hh[k] = hits[r, c]
                mm[k] = misses[r, c]
                k += 1
    return rr, cc, hh, mm


def _counted_cells_reference(
    hits: NDArray[np.int32], misses: NDArray[np.int32]
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int32], NDArray[np.int32]]:
    """Plain-numpy twin of :func:`_counted_cells`."""
    rr, cc = np.nonzero((hits != 0) | (misses != 0))
    return rr, cc, hits[rr, cc], misses[rr, cc]


@dataclass(frozen=True)
class _Footprint:
    """What one scan added to the map: sparse hit and miss counts in a box anchored in the world."""

    x0: float
    y0: float
    shape: tuple[int, int]
    rows: NDArray[np.int64]
    cols: NDArray[np.int64]
    hits: NDArray[np.int32]
    misses: NDArray[np.int32]
