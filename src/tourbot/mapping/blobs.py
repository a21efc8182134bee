"""Person-sized blobs far from the laser, where legs are no longer resolved.

At 1 deg a 12 cm leg returns at most one beam beyond about 7 m, and a person's two legs often
merge into one short segment: the leg detector (:mod:`tourbot.people.legs`) cannot see them. What
remains is the shape of the scan: a short run of beams, at most a person wide, that stands out in
front of what lies behind it on both sides (a local minimum, Burgard et al. Sec. 4). A wall or a
large exhibit is a long continuous run; the same run seen from afar breaks only where the range
jumps. Consecutive points belong to one run when they are closer than ``gap_factor`` times the
spacing of two beams at that range (or ``cluster_distance``, whichever is larger), so that a
surface seen at a distance is not cut into beam-sized pieces.

The rules are vectorised numpy over the beams of one scan.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tourbot.records import Scan

__all__ = ["BlobParams", "person_blobs"]


@dataclass(frozen=True)
class BlobParams:
    """A blob is ``min_range`` or farther, at most ``max_width`` wide and ``contrast`` nearer than
    the beams on both sides of it (no return counts as far)."""

    min_range: float = 4.0
    max_width: float = 0.6
    contrast: float = 0.3
    cluster_distance: float = 0.13
    gap_factor: float = 2.5


def _runs(
    scan: Scan, p: BlobParams
) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """The runs of ``scan``: which beams returned, their points ``(B, 2)`` in the laser frame, and
    each run's first and last beam and each beam's run (every beam is in one, a beam without a
    return alone)."""
    g = scan.geometry
    r = np.asarray(scan.ranges, dtype=np.float64)
    n = len(r)
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(r) & (r > g.min_range) & (r < g.max_range)
    rv = np.where(valid, r, 0.0)
    ang = g.angles
    xy = np.stack([rv * np.cos(ang), rv * np.sin(ang)], axis=1)
    gap = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    near_enough = gap <= np.maximum(p.cluster_distance, p.gap_factor * rv[:-1] * abs(g.angle_increment))
    joined = valid[1:] & valid[:-1] & near_enough
    start = np.r_[True, ~joined]  # a run starts at every beam not joined to the one before
    seg = np.cumsum(start) - 1
    first = np.flatnonzero(start)
    last = np.r_[first[1:] - 1, n - 1]
    return valid, xy, first, last, seg


def person_blobs(scan: Scan, params: BlobParams | None = None) -> NDArray[np.bool_]:
    """Which beams of ``scan`` end on a person-sized blob standing out on both sides ``(B,)``."""
    p = params or BlobParams()
    r = np.asarray(scan.ranges, dtype=np.float64)
    n = len(r)
    if n < 3:
        return np.zeros(n, dtype=bool)
    valid, xy, first, last, seg = _runs(scan, p)
    if not valid.any():
        return np.zeros(n, dtype=bool)
    far = np.where(valid, r, np.inf)
    nearest = np.minimum.reduceat(far, first)
    farthest = np.maximum.reduceat(np.where(valid, r, -np.inf), first)
    width = np.linalg.norm(xy[last] - xy[first], axis=1)
    inner = (first > 0) & (last < n - 1)  # both sides seen
    left = far[np.maximum(first - 1, 0)]
    right = far[np.minimum(last + 1, n - 1)]
    blob = (
        valid[first]
        & inner
        & (nearest >= p.min_range)
        & (width <= p.max_width)
        & (left - farthest >= p.contrast)
        & (right - farthest >= p.contrast)
    )
    return np.asarray(blob[seg] & valid)
