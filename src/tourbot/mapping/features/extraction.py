"""Line segments and corners of one laser scan (Burgard et al. Sec. 2.2, first paragraph).

The scan's end points are split into runs of neighbouring points (a jump between consecutive
returns larger than ``break_distance`` ends a run), and each run into collinear sets by the
Iterative-End-Point-Fit algorithm (Michael and Quint 1994): the chord from the run's first to its
last point is drawn, the point farthest from it splits the run when it is farther than
``split_distance``, and both halves are split again. Each set with enough points and length is
refitted by total least squares in the normal form ``x cos(alpha) + y sin(alpha) = r`` (the
orthogonal regression of Arras and Siegwart 1997), which also gives the 2 x 2 covariance of
``(alpha, r)`` from the points' range noise; neighbouring sets that the refit finds collinear are
merged (the "merge" of split-and-merge). Corners are the intersections of *directly adjacent*
segments (consecutive in the scan, their facing ends close) meeting at a clear angle (Baltzakis
and Trahanias 2002).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import wrap_angle

__all__ = [
    "Corner",
    "ExtractionParams",
    "Segment",
    "extract_corners",
    "extract_segments",
    "fit_line",
    "scan_points",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ExtractionParams:
    """Segment and corner extraction.

    The paper gives no values; these suit the 1-degree, 0.01-0.05 m SICK scanners of the logs:
    ``max_range`` (m, farther returns are too sparse for lines), ``break_distance`` (m between
    consecutive returns, and ``break_ratio`` times the range step of one beam) ends a run,
    ``split_distance`` (m) splits a set, ``min_points`` and ``min_length`` (m) keep a segment,
    ``merge_angle`` (rad) and ``merge_distance`` (m) merge neighbouring collinear ones,
    ``range_sigma`` (m) the range noise behind each segment's covariance; a segment seen more
    obliquely than ``max_incidence`` (rad between its normal and the line of sight to its middle:
    sparse points, mixed returns at depth jumps, a normal form ill-defined near the robot) is
    dropped. A corner joins two
    adjacent segments whose facing ends are within ``corner_gap`` m of the intersection and whose
    directions differ by at least ``corner_angle`` rad.
    """

    max_range: float = 15.0
    break_distance: float = 0.3
    break_ratio: float = 3.0
    split_distance: float = 0.05
    min_points: int = 6
    min_length: float = 0.4
    merge_angle: float = math.radians(4.0)
    merge_distance: float = 0.06
    range_sigma: float = 0.02
    max_incidence: float = math.radians(75.0)
    corner_gap: float = 0.25
    corner_angle: float = math.radians(45.0)


@dataclass(frozen=True)
class Segment:
    """A line segment of a scan in the robot frame.

    ``alpha``, ``r``: the line's normal form (``r >= 0``); ``cov``: the 2 x 2 covariance of
    ``(alpha, r)``; ``start``, ``end``: the end points (the first and last point projected on the
    line, in beam order); ``points``: the scan points it was fitted to ``(M, 2)``.
    """

    alpha: float
    r: float
    cov: FloatArray
    start: FloatArray
    end: FloatArray
    points: FloatArray

    @property
    def length(self) -> float:
        return float(np.hypot(*(self.end - self.start)))

    @property
    def bearing(self) -> float:
        """The bearing (rad) of the segment's middle seen from the robot: its place in the scan's
        angular order."""
        mid = 0.5 * (self.start + self.end)
        return math.atan2(mid[1], mid[0])


@dataclass(frozen=True)
class Corner:
    """The intersection of two adjacent segments (indices ``first`` < ``second``) in the robot frame.

    ``heading``: the direction (rad) of the bisector of the two segments' directions away from the
    corner; ``angle``: the angle (rad, 0-pi) between those two directions.
    """

    position: FloatArray
    heading: float
    angle: float
    first: int
    second: int


def scan_points(
    ranges: FloatArray, angles: FloatArray, max_range: float, min_range: float = 0.0
) -> FloatArray:
    """The end points ``(B, 2)`` of the beams in the sensor frame; NaN where a beam returned nothing
    (at or beyond ``max_range``, or below ``min_range``)."""
    r = np.asarray(ranges, dtype=np.float64)
    ok = (r < max_range) & (r > min_range) & np.isfinite(r)
    pts = np.stack([r * np.cos(angles), r * np.sin(angles)], axis=1)
    pts[~ok] = np.nan
    return pts


def fit_line(points: FloatArray, range_sigma: float) -> tuple[float, float, FloatArray]:
    """Total-least-squares line through ``points`` ``(M, 2)``: ``(alpha, r, cov)``, ``r >= 0``.

    The normal ``(cos alpha, sin alpha)`` is the eigenvector of the scatter matrix with the smaller
    eigenvalue; the covariance propagates an isotropic point noise ``range_sigma`` through the fit
    (for points spread along a line of length L: ``var(r) ~ s^2 / M``, ``var(alpha) ~ 12 s^2 /
    (M L^2)``, with the cross term from the centroid's offset along the line).
    """
    p = np.asarray(points, dtype=np.float64)
    m = len(p)
    c = p.mean(axis=0)
    d = p - c
    sxx, syy, sxy = float(d[:, 0] @ d[:, 0]), float(d[:, 1] @ d[:, 1]), float(d[:, 0] @ d[:, 1])
    alpha = 0.5 * math.atan2(-2.0 * sxy, syy - sxx)
    r = c[0] * math.cos(alpha) + c[1] * math.sin(alpha)
    if r < 0:
        alpha, r = alpha + math.pi, -r
    alpha = float(wrap_angle(alpha))
    tangent = np.array([-math.sin(alpha), math.cos(alpha)])
    along = d @ tangent
    spread = max(float(along @ along), 1e-9)
    u = float(c @ tangent)  # the centroid's offset along the line from the foot of the normal
    var_a = range_sigma**2 / spread
    var_r = range_sigma**2 / m + u * u * var_a
    cov_ar = u * var_a  # r = c . n(alpha): dr/dalpha = c . tangent = u
    return alpha, r, np.array([[var_a, cov_ar], [cov_ar, var_r]])


def _project(points: FloatArray, alpha: float, r: float) -> FloatArray:
    n = np.array([math.cos(alpha), math.sin(alpha)])
    off = points @ n - r
    return np.asarray(points - off[:, None] * n[None, :], dtype=np.float64)


def _split(points: FloatArray, threshold: float, out: list[tuple[int, int]], lo: int, hi: int) -> None:
    """Iterative end-point fit over ``points[lo:hi]`` (inclusive-exclusive); sets into ``out``."""
    stack = [(lo, hi)]
    found: list[tuple[int, int]] = []
    while stack:
        a, b = stack.pop()
        if b - a < 3:
            found.append((a, b))
            continue
        p0, p1 = points[a], points[b - 1]
        chord = p1 - p0
        norm = math.hypot(chord[0], chord[1])
        seg = points[a:b] - p0
        if norm < 1e-9:
            dist = np.hypot(seg[:, 0], seg[:, 1])
        else:
            dist = np.abs(seg[:, 0] * chord[1] - seg[:, 1] * chord[0]) / norm
        k = int(np.argmax(dist))
        if dist[k] > threshold and 0 < k < b - a - 1:
            stack.append((a + k, b))  # the far point starts the second half (it lies on both)
            stack.append((a, a + k + 1))
        else:
            found.append((a, b))
    out.extend(sorted(found))


def _runs(points: FloatArray, angle_step: float, params: ExtractionParams) -> list[tuple[int, int]]:
    """Index ranges of consecutive returned points without a jump between them (one missing or
    two missing returns do not break a run)."""
    idx = np.flatnonzero(~np.isnan(points[:, 0]))
    if len(idx) == 0:
        return []
    p, q = points[idx[:-1]], points[idx[1:]]
    skip = np.diff(idx)
    gap = np.hypot(q[:, 0] - p[:, 0], q[:, 1] - p[:, 1])
    limit = np.maximum(
        params.break_distance, params.break_ratio * np.hypot(p[:, 0], p[:, 1]) * angle_step * skip
    )
    cut = np.flatnonzero((skip > 2) | (gap > limit))
    starts = np.concatenate([[idx[0]], idx[cut + 1]])
    ends = np.concatenate([idx[cut] + 1, [idx[-1] + 1]])
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def _segment(points: FloatArray, params: ExtractionParams) -> Segment:
    alpha, r, cov = fit_line(points, params.range_sigma)
    ends = _project(points[[0, -1]], alpha, r)
    return Segment(alpha, r, cov, ends[0], ends[1], points)


def _collinear(a: Segment, b: Segment, params: ExtractionParams) -> bool:
    da = abs(float(wrap_angle(a.alpha - b.alpha)))
    if da > params.merge_angle:
        return False
    gap = float(np.hypot(*(b.start - a.end)))
    if gap > params.break_distance:
        return False
    both = np.concatenate([a.points, b.points])
    alpha, r, _ = fit_line(both, params.range_sigma)
    n = np.array([math.cos(alpha), math.sin(alpha)])
    return float(np.max(np.abs(both @ n - r))) < params.merge_distance + params.split_distance


def extract_segments(
    points: FloatArray, angle_step: float, params: ExtractionParams | None = None
) -> list[Segment]:
    """The line segments of one scan, in beam (angular) order.

    ``points`` ``(B, 2)``: the beams' end points in beam order (NaN where a beam returned nothing,
    see :func:`scan_points`), in the frame the segments are wanted in; ``angle_step``: the angle
    (rad) between neighbouring beams.
    """
    p = params or ExtractionParams()
    pts = np.array(points, dtype=np.float64)
    pts[np.hypot(pts[:, 0], pts[:, 1]) > p.max_range] = np.nan
    step = abs(angle_step)
    sets: list[tuple[int, int]] = []
    for lo, hi in _runs(pts, step, p):
        run = pts[lo:hi]
        keep = ~np.isnan(run[:, 0])
        idx = np.flatnonzero(keep) + lo
        local: list[tuple[int, int]] = []
        _split(pts[idx], p.split_distance, local, 0, len(idx))
        sets.extend((int(idx[a]), int(idx[b - 1]) + 1) for a, b in local)
    segments: list[Segment] = []
    for lo, hi in sets:
        run = pts[lo:hi]
        run = run[~np.isnan(run[:, 0])]
        if len(run) < max(p.min_points, 2):
            continue
        seg = _segment(run, p)
        if segments and _collinear(segments[-1], seg, p):
            seg = _segment(np.concatenate([segments[-1].points, run]), p)
            segments[-1] = seg
            continue
        segments.append(seg)
    cos_max = math.cos(p.max_incidence)
    return [
        s
        for s in segments
        if s.length >= p.min_length and s.r >= cos_max * float(np.hypot(*(0.5 * (s.start + s.end))))
    ]


def extract_corners(segments: list[Segment], params: ExtractionParams | None = None) -> list[Corner]:
    """Corners at the intersections of directly adjacent segments (consecutive in the scan)."""
    p = params or ExtractionParams()
    corners: list[Corner] = []
    for k in range(len(segments) - 1):
        a, b = segments[k], segments[k + 1]
        na = np.array([math.cos(a.alpha), math.sin(a.alpha)])
        nb = np.array([math.cos(b.alpha), math.sin(b.alpha)])
        det = na[0] * nb[1] - na[1] * nb[0]
        if abs(det) < 1e-6:
            continue
        x = (a.r * nb[1] - b.r * na[1]) / det
        y = (b.r * na[0] - a.r * nb[0]) / det
        pos = np.array([x, y])
        if np.hypot(*(a.end - pos)) > p.corner_gap or np.hypot(*(b.start - pos)) > p.corner_gap:
            continue
        da, db = a.start - pos, b.end - pos  # directions away from the corner along each segment
        ua, ub = da / max(np.hypot(*da), 1e-9), db / max(np.hypot(*db), 1e-9)
        angle = math.acos(float(np.clip(ua @ ub, -1.0, 1.0)))
        if angle < p.corner_angle or angle > math.pi - p.corner_angle:
            continue
        bis = ua + ub
        corners.append(Corner(pos, math.atan2(bis[1], bis[0]), angle, k, k + 1))
    return corners
