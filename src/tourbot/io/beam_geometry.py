"""Which way a laser's beams point, checked against the data: consecutive scans must agree.

A laser line gives its ranges and, in old CARMEN formats, nothing else: the field of view, the
first beam's angle and the direction of the sweep come from ``PARAM`` lines (degrees in one log,
radians in another) or from CARMEN's conventions. A wrong guess rotates or mirrors every scan, and
nothing downstream notices. Two scans taken from nearby known poses (the reference trajectory of a
corrected log, else the odometry, which is good over a few scans) see the same walls: laid out
with the right geometry their end points coincide, with a wrong one they do not. Each candidate
layout is scored by the median, over pairs of such scans, of the median distance from the end
points of one scan to the nearest end point of the other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from tourbot.geometry import relative, transform_points
from tourbot.records import LaserGeometry, Scan

__all__ = ["GeometryCheck", "candidate_layouts", "check_layouts", "layout_disagreement"]

#: A pair of scans is compared once the robot moved this far (m) or turned this much (rad) ...
PAIR_MOTION = (0.3, math.radians(15.0))
#: ... within this many scans.
PAIR_WINDOW = 30
#: At most this many pairs, spread over the log.
MAX_PAIRS = 60
#: Ranges beyond this (m) are left out: far end points are sparse and noisy.
FAR = 30.0
#: The best layout must make the scans agree to this median distance (m), else the log is refused.
AGREEMENT = 0.15
#: Another layout replaces the stated one only when it scores below this fraction of the stated's.
CLEARLY_BETTER = 0.5


@dataclass(frozen=True)
class GeometryCheck:
    """The outcome: every candidate's score (median distance, m; NaN if unscored) and the one taken."""

    scores: dict[str, float]
    chosen: str
    pairs: int

    @property
    def agrees(self) -> bool:
        return bool(self.scores[self.chosen] <= AGREEMENT)


def candidate_layouts(
    stated: LaserGeometry, alternatives: dict[str, LaserGeometry]
) -> dict[str, LaserGeometry]:
    """The stated layout first, its mirror image (beams left to right), then the alternatives given."""
    n = stated.num_beams
    mirrored = LaserGeometry(
        n,
        stated.angle_min + stated.angle_increment * (n - 1),
        -stated.angle_increment,
        stated.max_range,
        stated.min_range,
        stated.offset,
    )
    return {"stated": stated, "mirrored (beams left to right)": mirrored, **alternatives}


def _pairs(poses: NDArray[np.float64]) -> list[tuple[int, int]]:
    """Pairs of scans a little apart (see PAIR_MOTION), spread evenly over the log."""
    n = len(poses)
    if n < 2:
        return []
    out: list[tuple[int, int]] = []
    for i in np.unique(np.linspace(0, n - 2, 4 * MAX_PAIRS).astype(int)):
        if np.isnan(poses[i]).any():
            continue
        for j in range(i + 1, min(i + PAIR_WINDOW, n)):
            if np.isnan(poses[j]).any():
                continue
            d = relative(poses[i], poses[j])
            if math.hypot(d[0], d[1]) > PAIR_MOTION[0] or abs(d[2]) > PAIR_MOTION[1]:
                out.append((int(i), j))
                break
    step = max(1, len(out) // MAX_PAIRS)
    return out[::step][:MAX_PAIRS]


def _end_points(scan: Scan, layout: LaserGeometry, pose: NDArray[np.float64]) -> NDArray[np.float64]:
    r = scan.ranges
    ok = (r > max(layout.min_range, 0.05)) & (r < min(layout.max_range, FAR))
    a = layout.angles[ok]
    local = np.stack([r[ok] * np.cos(a), r[ok] * np.sin(a)], axis=-1)
    return transform_points(pose, transform_points(layout.offset, local))


def layout_disagreement(
    scans: list[Scan], poses: NDArray[np.float64], layout: LaserGeometry, pairs: list[tuple[int, int]]
) -> float:
    """Median over ``pairs`` of the median end-point distance (m) between the two scans; NaN if none."""
    scores = []
    for i, j in pairs:
        a, b = _end_points(scans[i], layout, poses[i]), _end_points(scans[j], layout, poses[j])
        if len(a) < 10 or len(b) < 10:
            continue
        d, _ = cKDTree(a).query(b)
        scores.append(float(np.median(d)))
    return float(np.median(scores)) if scores else math.nan


def check_layouts(
    scans: list[Scan], poses: NDArray[np.float64], layouts: dict[str, LaserGeometry]
) -> GeometryCheck | None:
    """Score each layout on ``scans`` seen from ``poses`` ``(S, 3)``; None when no pair can be compared.

    The stated layout (the first) is kept unless another scores below ``CLEARLY_BETTER`` of it.
    """
    pairs = _pairs(poses)
    if not pairs:
        return None
    scores = {name: layout_disagreement(scans, poses, g, pairs) for name, g in layouts.items()}
    if all(math.isnan(v) for v in scores.values()):
        return None
    stated = next(iter(layouts))
    scored = {k: v for k, v in scores.items() if not math.isnan(v)}
    best = min(scored, key=scored.__getitem__)
    keep = stated in scored and not scored[best] < CLEARLY_BETTER * scored[stated]
    return GeometryCheck(scores, stated if keep else best, len(pairs))
