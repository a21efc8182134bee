"""Loop closures judged against a reference path, and the judge judged against the scans.

A loop closure ``(i, j, delta)`` says that scan ``j`` was taken at ``delta`` in the frame of scan
``i``. It is *off the reference* when the reference's own relative pose ``ref_i (-) ref_j``
differs from ``delta`` by more than 0.3 m or 3 degrees (the count a mapping benchmark reports as
false closures). A reference is itself an estimate (the corrected CARMEN logs' poses come from an
offline scan matcher), so a closure off the reference may be the reference's error: the scans
decide. :func:`overlap` is the share of scan ``j``'s returns that land within 5 cm of a return of
scan ``i`` when ``j`` is placed at a given relative pose; :func:`audit_closures` counts the closures
off the reference whose scans overlap clearly better at the closure's pose than at the
reference's (the reference contradicted by its own scans there).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from tourbot.geometry import relative, transform_points

__all__ = ["ClosureAudit", "audit_closures", "off_reference", "overlap"]

FloatArray = NDArray[np.float64]

#: A closure further than this from the reference's relative pose is off it (m, rad).
MAX_TRANSLATION = 0.3
MAX_ROTATION = float(np.radians(3.0))
#: A return within this distance of the other scan's nearest return overlaps it (m).
OVERLAP_TOLERANCE = 0.05
#: The scans side with the closure when its overlap exceeds the reference's by more than this.
OVERLAP_MARGIN = 0.02

Closure = tuple[int, int, ArrayLike]


@dataclass(frozen=True, slots=True)
class ClosureAudit:
    """``off_reference`` of the ``accepted`` closures disagree with the reference; of those,
    ``scans_side_with_closure`` overlap clearly better at the closure's relative pose."""

    accepted: int
    off_reference: int
    scans_side_with_closure: int


def off_reference(
    closures: Sequence[Closure],
    reference: ArrayLike,
    max_translation: float = MAX_TRANSLATION,
    max_rotation: float = MAX_ROTATION,
) -> NDArray[np.bool_]:
    """For each closure, whether the reference's relative pose of its two scans is more than
    ``max_translation`` or ``max_rotation`` from the closure's."""
    ref = np.asarray(reference, dtype=np.float64)
    out = np.zeros(len(closures), dtype=bool)
    for k, (i, j, delta) in enumerate(closures):
        err = relative(relative(ref[i], ref[j]), np.asarray(delta, dtype=np.float64))
        out[k] = bool(np.hypot(err[0], err[1]) > max_translation or abs(err[2]) > max_rotation)
    return out


def overlap(
    points_i: ArrayLike, points_j: ArrayLike, delta: ArrayLike, tolerance: float = OVERLAP_TOLERANCE
) -> float:
    """The share of ``points_j`` (scan ``j``'s returns in its robot frame, ``(M, 2)``), placed at
    ``delta`` in scan ``i``'s frame, that lie within ``tolerance`` of one of ``points_i``; 0 when
    either scan has no return."""
    a = np.asarray(points_i, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(points_j, dtype=np.float64).reshape(-1, 2)
    if len(a) == 0 or len(b) == 0:
        return 0.0
    dist, _ = cKDTree(a).query(transform_points(np.asarray(delta, dtype=np.float64), b))
    return float(np.mean(dist < tolerance))


def audit_closures(
    closures: Sequence[Closure],
    reference: ArrayLike,
    points: Sequence[ArrayLike],
    margin: float = OVERLAP_MARGIN,
) -> ClosureAudit:
    """Count the closures off the reference, and of those the ones whose scans (``points[k]``:
    scan ``k``'s returns in its robot frame) overlap better by more than ``margin`` at the
    closure's relative pose than at the reference's."""
    ref = np.asarray(reference, dtype=np.float64)
    off = off_reference(closures, ref)
    side = 0
    for (i, j, delta), bad in zip(closures, off, strict=True):
        if not bad:
            continue
        at_closure = overlap(points[i], points[j], delta)
        at_reference = overlap(points[i], points[j], relative(ref[i], ref[j]))
        side += int(at_closure > at_reference + margin)
    return ClosureAudit(len(closures), int(off.sum()), side)
