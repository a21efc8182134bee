"""People's legs as features of a laser scan (Burgard et al., Sec. 4 and Fig. 5, middle).

At about 40 cm above the floor a laser sees people's legs as local minima of the scan: short
segments, narrower than about 25 cm, that stand out in front of what lies behind them. Each such
segment becomes a feature with a probability of being a leg, from how close its width is to a
leg's and how much nearer it is than its neighbours. Two legs close to each other are then grouped
into one person feature, the ``z_j(t)`` of the SJPDAF (a person produces one feature per scan, as
the JPDAF's joint events assume).

The segmentation is a numba kernel over the beams with a vectorised numpy reference beside it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numba
import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import transform_points
from tourbot.people.leg_classifier import FEATURE_NAMES, LegModel, candidate_features, default_model
from tourbot.records import Scan

__all__ = [
    "LegConfig",
    "LegFeatures",
    "PersonFeatures",
    "detect_legs",
    "group_legs",
    "leg_candidates",
    "leg_segments",
    "leg_segments_reference",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class LegConfig:
    """Parameters of the leg detector.

    A leg is about 12 cm wide (``leg_width``); segments from ``min_width`` to ``max_width`` are
    candidates (up to two legs seen as one blob; thinner ones are chair or table legs).
    Consecutive points further apart than ``cluster_distance`` start a new segment (13 cm, the
    ``leg_tracker`` project's clustering distance). A segment must be at least ``min_contrast``
    nearer than the beams beside it on one side at least to be a local minimum (Burgard et al.,
    Sec. 4: "legs ... appear as local minima in the scans"), and the range must jump by as much on
    both sides (the other side may be an occluder in front, such as the person's other leg).
    ``max_range`` ignores features too far away to be resolved as legs, ``min_range`` those so
    near the laser that they are the robot's own body (a person's leg centre cannot come nearer
    than the robot's skin around the laser).
    ``max_leg_separation`` is the largest distance between a person's two legs (a long stride).
    ``model``: the learnt P(leg) of :mod:`tourbot.people.leg_classifier` (None: the rule above);
    with a model the candidates are all segments ``model_min_width``-``model_max_width`` wide,
    local minimum or not (two legs seen as one blob near the laser are up to 0.5 m wide; a leg
    half hidden by the other has no contrast on one side), and the model decides for those of
    ``model_min_points`` points or more; fewer have no shape to speak of (a line and a circle fit
    them exactly), and the rule decides (a far leg, or a coarse laser's).
    ``depth_offset`` moves a segment's centroid away from the laser towards the leg's axis: the
    laser sees only the near side of a leg (about 2/3 of a 6 cm radius behind the visible arc).
    """

    leg_width: float = 0.12
    width_std: float = 0.07
    min_width: float = 0.05
    max_width: float = 0.35
    min_points: int = 2
    cluster_distance: float = 0.13
    min_contrast: float = 0.10
    contrast_scale: float = 0.05
    max_range: float = 8.0
    min_range: float = 0.25
    max_leg_separation: float = 0.55
    depth_offset: float = 0.04
    min_probability: float = 0.1
    model: LegModel | None = field(default_factory=default_model)
    model_min_points: int = 3
    model_min_width: float = 0.02
    model_max_width: float = 0.5


@dataclass(frozen=True, slots=True)
class LegFeatures:
    """Leg candidates of one scan, in the laser frame: centroids ``(M, 2)``, widths and P(leg)."""

    points: FloatArray
    width: FloatArray
    probability: FloatArray

    def __len__(self) -> int:
        return int(self.points.shape[0])


@dataclass(frozen=True, slots=True)
class PersonFeatures:
    """Person features ``z_j(t)``: positions ``(M, 2)``, P(person), and the legs that made each
    (``members`` ``(M, 2)``: indices into the :class:`LegFeatures`, -1 where there is no second leg)."""

    points: FloatArray
    probability: FloatArray
    members: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.points.shape[0])

    def transformed(self, pose: FloatArray | tuple[float, float, float]) -> PersonFeatures:
        """The same features with points expressed in the parent frame of ``pose``."""
        pts = transform_points(np.asarray(pose, dtype=np.float64), self.points) if len(self) else self.points
        return PersonFeatures(pts, self.probability, self.members)


def _valid_ranges(scan: Scan, max_range: float) -> NDArray[np.bool_]:
    r = scan.ranges
    g = scan.geometry
    with np.errstate(invalid="ignore"):
        return np.isfinite(r) & (r > max(g.min_range, 1e-6)) & (r < min(g.max_range, max_range))


def detect_legs(scan: Scan, config: LegConfig | None = None) -> LegFeatures:
    """Leg candidates of ``scan`` (Burgard et al. Fig. 5, middle): segments that are local minima.

    Returns features in the laser frame with ``probability >= config.min_probability``; the numba
    kernel :func:`leg_segments` finds the candidates, and with ``config.model`` (by default the
    shipped one, :func:`~tourbot.people.leg_classifier.default_model`) P(leg) is that model's
    probability from the candidate's shape and neighbours instead of the width and contrast rule.
    """
    cfg = config or LegConfig()
    legs, features = leg_candidates(scan, cfg, with_features=cfg.model is not None)
    if cfg.model is None or len(legs) == 0:
        return legs
    shaped = features[:, FEATURE_NAMES.index("points")] >= math.log(cfg.model_min_points) - 1e-9
    prob = np.where(shaped, cfg.model.probability(features), legs.probability)
    keep = prob >= cfg.min_probability
    return LegFeatures(legs.points[keep], legs.width[keep], prob[keep])


def leg_candidates(
    scan: Scan, config: LegConfig | None = None, *, with_features: bool = True
) -> tuple[LegFeatures, FloatArray]:
    """The candidates of the width and contrast rule (P(leg) from that rule) or, with
    ``with_features``, the model's wider candidates (see :class:`LegConfig`) with their classifier
    features ``(M, F)`` (:func:`~tourbot.people.leg_classifier.candidate_features`; an empty array
    otherwise)."""
    cfg = config or LegConfig()
    r = np.asarray(scan.ranges, dtype=np.float64)
    valid = _valid_ranges(scan, np.inf)
    angles = scan.geometry.angles
    seg_cfg = cfg
    if with_features:
        seg_cfg = replace(
            cfg,
            min_width=cfg.model_min_width,
            max_width=cfg.model_max_width,
            min_probability=0.0,
        )
    pts, width, prob, first, last = leg_segments(r, angles, valid, seg_cfg)
    if pts.shape[0]:
        d = np.linalg.norm(pts, axis=1, keepdims=True)
        pts = pts + cfg.depth_offset * pts / np.maximum(d, 1e-9)
        far = d[:, 0] >= cfg.min_range
        pts, width, prob, first, last = pts[far], width[far], prob[far], first[far], last[far]
    features = np.zeros((0, 0))
    if with_features:
        features = candidate_features(r, angles, valid, first, last, pts)
    return LegFeatures(pts, width, prob), features


def leg_segments_reference(
    r: FloatArray, angles: FloatArray, valid: NDArray[np.bool_], cfg: LegConfig
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray, IntArray]:
    """Vectorised numpy reference of :func:`leg_segments`: centroids ``(S, 2)``, widths, P(leg),
    and each segment's first and last beam."""
    near = valid & (r < cfg.max_range)
    B = r.shape[0]
    if B < 2 or not near.any():
        e = np.zeros(0, dtype=np.int64)
        return np.zeros((0, 2)), np.zeros(0), np.zeros(0), e, e.copy()
    rr = np.where(valid, r, np.inf)
    xy = np.stack([np.cos(angles) * np.where(valid, r, 0.0), np.sin(angles) * np.where(valid, r, 0.0)], -1)
    step = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    # A segment breaks where a point is invalid or far from the previous one.
    brk = np.ones(B, dtype=bool)
    brk[1:] = ~(valid[1:] & valid[:-1] & (step <= cfg.cluster_distance))
    seg = np.cumsum(brk) - 1
    nseg = int(seg[-1]) + 1
    starts = np.flatnonzero(brk)
    ends = np.append(starts[1:] - 1, B - 1)
    count = np.bincount(seg, weights=valid.astype(np.float64), minlength=nseg)
    sx = np.bincount(seg, weights=np.where(valid, xy[:, 0], 0.0), minlength=nseg)
    sy = np.bincount(seg, weights=np.where(valid, xy[:, 1], 0.0), minlength=nseg)
    sr = np.bincount(seg, weights=np.where(valid, r, 0.0), minlength=nseg)
    seg_near = np.bincount(seg, weights=near.astype(np.float64), minlength=nseg) == count
    keep = (count >= cfg.min_points) & seg_near & valid[starts]
    width = np.linalg.norm(xy[ends] - xy[starts], axis=1)
    keep &= (width >= cfg.min_width) & (width <= cfg.max_width)
    mean_r = sr / np.maximum(count, 1.0)
    # Contrast: the range jumps to the beams just outside the segment (no return or the edge of
    # the field of view = far). Something must lie behind on one side at least, and both sides
    # must jump (nearer there is an occluder, e.g. the other leg; no jump is a continuous surface).
    left = np.where(starts > 0, rr[np.maximum(starts - 1, 0)], np.inf) - mean_r
    right = np.where(ends < B - 1, rr[np.minimum(ends + 1, B - 1)], np.inf) - mean_r
    behind = np.maximum(left, right)
    jump = np.minimum(np.abs(left), np.abs(right))
    with np.errstate(over="ignore", invalid="ignore"):
        p_behind = 1.0 / (1.0 + np.exp(-(behind - cfg.min_contrast) / cfg.contrast_scale))
        p_jump = 1.0 / (1.0 + np.exp(-(jump - cfg.min_contrast) / cfg.contrast_scale))
    p_contrast = np.nan_to_num(p_behind, nan=1.0) * np.nan_to_num(p_jump, nan=1.0)
    excess = np.maximum(width - cfg.leg_width, 0.0)  # narrower than a leg: a leg seen edge-on
    p_width = np.exp(-0.5 * (excess / cfg.width_std) ** 2)
    prob = p_width * p_contrast
    keep &= prob >= cfg.min_probability
    idx = np.flatnonzero(keep)
    pts = np.stack([sx[idx] / count[idx], sy[idx] / count[idx]], -1)
    return pts, width[idx], prob[idx], starts[idx].astype(np.int64), ends[idx].astype(np.int64)


@numba.njit(cache=True)
def _sigmoid(x: float, centre: float, scale: float) -> float:
    if x == np.inf:
        return 1.0
    z = -(x - centre) / scale
    return 0.0 if z > 700.0 else 1.0 / (1.0 + math.exp(z))


@numba.njit(cache=True)
def _leg_segments_kernel(
    r: FloatArray,
    angles: FloatArray,
    valid: NDArray[np.bool_],
    max_range: float,
    cluster_distance: float,
    min_points: int,
    min_width: float,
    max_width: float,
    leg_width: float,
    width_std: float,
    min_contrast: float,
    contrast_scale: float,
    min_probability: float,
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray, IntArray]:
    B = r.shape[0]
    pts = np.empty((B, 2))
    width = np.empty(B)
    prob = np.empty(B)
    first = np.empty(B, dtype=np.int64)
    last = np.empty(B, dtype=np.int64)
    n = 0
    i = 0
    while i < B:
        # One segment: [i, j], all valid, consecutive points within cluster_distance.
        j = i
        if valid[i]:
            while j + 1 < B and valid[j + 1]:
                dx = math.cos(angles[j + 1]) * r[j + 1] - math.cos(angles[j]) * r[j]
                dy = math.sin(angles[j + 1]) * r[j + 1] - math.sin(angles[j]) * r[j]
                if math.sqrt(dx * dx + dy * dy) > cluster_distance:
                    break
                j += 1
        if valid[i] and j - i + 1 >= min_points:
            sx = 0.0
            sy = 0.0
            sr = 0.0
            all_near = True
            for k in range(i, j + 1):
                sx += math.cos(angles[k]) * r[k]
                sy += math.sin(angles[k]) * r[k]
                sr += r[k]
                if r[k] >= max_range:
                    all_near = False
            cnt = j - i + 1
            wx = math.cos(angles[j]) * r[j] - math.cos(angles[i]) * r[i]
            wy = math.sin(angles[j]) * r[j] - math.sin(angles[i]) * r[i]
            w = math.sqrt(wx * wx + wy * wy)
            if all_near and min_width <= w <= max_width:
                mean_r = sr / cnt
                left = (np.inf if i == 0 or not valid[i - 1] else r[i - 1]) - mean_r
                right = (np.inf if j == B - 1 or not valid[j + 1] else r[j + 1]) - mean_r
                p_contrast = _sigmoid(max(left, right), min_contrast, contrast_scale) * _sigmoid(
                    min(abs(left), abs(right)), min_contrast, contrast_scale
                )
                excess = max(w - leg_width, 0.0)
                p = math.exp(-0.5 * (excess / width_std) ** 2) * p_contrast
                if p >= min_probability:
                    pts[n, 0] = sx / cnt
                    pts[n, 1] = sy / cnt
                    width[n] = w
                    prob[n] = p
                    first[n] = i
                    last[n] = j
                    n += 1
        i = j + 1
    return pts[:n].copy(), width[:n].copy(), prob[:n].copy(), first[:n].copy(), last[:n].copy()


def leg_segments(
    r: FloatArray, angles: FloatArray, valid: NDArray[np.bool_], cfg: LegConfig
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray, IntArray]:
    """Segments of a scan that look like legs: centroids ``(S, 2)`` (laser frame), widths, P(leg),
    and the first and last beam of each.

    A segment is a run of valid beams whose consecutive points are within ``cluster_distance``;
    it is a leg candidate when it has ``min_points``, lies within ``max_range``, is
    ``min_width``-``max_width`` wide, and P(leg) = P(width) * P(local minimum) reaches
    ``min_probability`` (numba kernel of :func:`leg_segments_reference`).
    """
    return _leg_segments_kernel(
        np.ascontiguousarray(r, dtype=np.float64),
        np.ascontiguousarray(angles, dtype=np.float64),
        np.ascontiguousarray(valid, dtype=np.bool_),
        cfg.max_range,
        cfg.cluster_distance,
        cfg.min_points,
        cfg.min_width,
        cfg.max_width,
        cfg.leg_width,
        cfg.width_std,
        cfg.min_contrast,
        cfg.contrast_scale,
        cfg.min_probability,
    )


def group_legs(legs: LegFeatures, config: LegConfig | None = None) -> PersonFeatures:
    """Group legs into person features: the nearest pairs within ``max_leg_separation`` first.

    A pair becomes one feature at its midpoint with ``P = 1 - (1 - p1)(1 - p2)``; a leg with no
    partner (the other leg hidden, or both legs seen as one segment) is a feature on its own.
    """
    cfg = config or LegConfig()
    M = len(legs)
    if M == 0:
        return PersonFeatures(np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2), dtype=np.int64))
    d = np.linalg.norm(legs.points[:, None, :] - legs.points[None, :, :], axis=-1)
    iu, ju = np.triu_indices(M, k=1)
    close = d[iu, ju] <= cfg.max_leg_separation
    iu, ju = iu[close], ju[close]
    order = np.argsort(d[iu, ju], kind="stable")
    used = np.zeros(M, dtype=bool)
    pts: list[FloatArray] = []
    probs: list[float] = []
    members: list[tuple[int, int]] = []
    for a, b in zip(iu[order].tolist(), ju[order].tolist(), strict=True):
        if used[a] or used[b]:
            continue
        used[a] = used[b] = True
        pts.append(0.5 * (legs.points[a] + legs.points[b]))
        probs.append(1.0 - (1.0 - legs.probability[a]) * (1.0 - legs.probability[b]))
        members.append((a, b))
    for a in np.flatnonzero(~used).tolist():
        pts.append(legs.points[a])
        probs.append(float(legs.probability[a]))
        members.append((a, -1))
    return PersonFeatures(
        np.array(pts, dtype=np.float64).reshape(-1, 2),
        np.array(probs, dtype=np.float64),
        np.array(members, dtype=np.int64).reshape(-1, 2),
    )
