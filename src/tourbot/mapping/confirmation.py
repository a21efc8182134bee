"""Beams left out as people that other scans confirm: their hits given back to the finished map.

People filtering (Burgard et al. Sec. 5, Eq. 10-12) leaves a beam out of the map when it ends
on something taken for a person: in a tracked person's box, on a person feature, or on a far
blob (``blobs`` mode). In a crowd much static structure is taken so too: a wall behind a
visitor's box, an exhibit's edge or a pole that looks like a blob from afar. Leaving those
beams out costs the map static cells that, with a scan every few seconds, few other beams hit.

A visitor stands at a spot for a while and leaves; another scan's beam ends where they stood
only when that scan saw a visitor there too. A beam the filter kept, in another scan, is one the
filter judged static; when kept beams of at least ``scans`` other scans ended within ``radius``
cells of where a left-out beam ended, the spot is static structure that scans from other times
and places confirm, and the left-out beam's hit is given back to the map that is returned. The
confirmation counts distinct scans, not beams, and never the left-out beam's own scan (whose
kept beams next to a visitor are no independent evidence).

This acts on the finished map only: the scans were aligned and the per-scan filter decided with
the beams left out (Eq. 12 weights are unchanged), so mapping at known poses and the alignment
in SLAM stay as they were. The consistency check (:mod:`tourbot.mapping.consistency`) runs after
it, on the map with the hits given back, and judges the confirmed beams' ends like any other.

A wall or an exhibit's edge that the filter took for a person is often mapped from afar by one
beam per cell, so fewer than ``scans`` other scans confirm it; yet the map already holds the
structure it belongs to on both sides of it (``line_radius``, None: off). A left-out beam's end
is given back too when the finished map (before any hit is given back) holds occupied cells
within ``line_radius`` cells (Chebyshev) of its end's cell, not the cell itself, in two
directions at least ``line_angle`` degrees apart as seen from the end's cell: the end fills a
gap in, or continues, a line of structure (:func:`continues_structure`). A visitor standing in
the open has no occupied cell around it, and a beam ending 2 cells or more in front of a
straight wall has the wall on one side only (directions less than 90 degrees apart, unless the
wall runs axis-aligned exactly 2 cells away); an end 1 cell from a wall touches it and is given
back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["ConfirmationParams", "confirmed_beams", "confirming_scans", "continues_structure"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class ConfirmationParams:
    """A left-out beam's hit is given back when kept beams of at least ``scans`` other scans
    ended within ``radius`` cells (Chebyshev, cells of ``resolution`` metres) of its end; with
    ``line_radius`` also when the map holds occupied cells within that many cells of its end in
    two directions at least ``line_angle`` degrees apart (None: off)."""

    radius: int = 1
    scans: int = 4
    line_radius: int | None = None
    line_angle: float = 90.0


def confirming_scans(
    left_ends: FloatArray,
    left_scans: IntArray,
    kept_ends: FloatArray,
    kept_scans: IntArray,
    resolution: float,
    radius: int = 1,
) -> IntArray:
    """For each left-out beam (world end ``left_ends`` ``(L, 2)``, scan index ``left_scans``
    ``(L,)``): how many distinct scans other than its own had a kept beam (``kept_ends`` ``(K, 2)``,
    ``kept_scans`` ``(K,)``) end within ``radius`` cells of its end's cell."""
    left = np.floor(np.asarray(left_ends, dtype=np.float64).reshape(-1, 2) / resolution).astype(np.int64)
    kept = np.floor(np.asarray(kept_ends, dtype=np.float64).reshape(-1, 2) / resolution).astype(np.int64)
    if len(left) == 0 or len(kept) == 0:
        return np.zeros(len(left), np.int64)
    k = np.arange(-radius, radius + 1)
    offsets = np.stack(np.meshgrid(k, k, indexing="ij"), axis=-1).reshape(-1, 2)
    around = (kept[:, None, :] + offsets[None, :, :]).reshape(-1, 2)
    around_scan = np.repeat(np.asarray(kept_scans, dtype=np.int64), len(offsets))
    lo = np.minimum(around.min(axis=0), left.min(axis=0))
    height = int(max(around[:, 1].max(), left[:, 1].max()) - lo[1]) + 1
    n_scans = int(max(around_scan.max(), int(np.max(left_scans)))) + 1

    def key(cells: IntArray) -> IntArray:
        return (cells[:, 0] - lo[0]) * height + (cells[:, 1] - lo[1])

    pairs = np.unique(key(around) * n_scans + around_scan)  # each scan once per cell
    cells, count = np.unique(pairs // n_scans, return_counts=True)
    mine = key(left)
    at = np.minimum(np.searchsorted(cells, mine), len(cells) - 1)
    n = np.where(cells[at] == mine, count[at], 0)
    own = np.isin(mine * n_scans + np.asarray(left_scans, dtype=np.int64), pairs)
    return np.asarray(n - own, dtype=np.int64)


def confirmed_beams(
    left_ends: FloatArray,
    left_scans: IntArray,
    kept_ends: FloatArray,
    kept_scans: IntArray,
    resolution: float,
    params: ConfirmationParams | None = None,
) -> NDArray[np.bool_]:
    """Which left-out beams other scans' kept beams confirm ``(L,)`` (see
    :func:`confirming_scans`)."""
    p = params or ConfirmationParams()
    n = confirming_scans(left_ends, left_scans, kept_ends, kept_scans, resolution, p.radius)
    return np.asarray(n >= p.scans)


def continues_structure(
    occupied: NDArray[np.bool_], cells: IntArray, radius: int = 2, angle: float = 90.0
) -> NDArray[np.bool_]:
    """Which ends, at grid ``cells`` ``(L, 2)`` (row, col, possibly outside) of the ``occupied``
    grid ``(H, W)``, have occupied cells within ``radius`` cells (Chebyshev, the end's own cell
    left aside) in two directions at least ``angle`` degrees apart, seen from the end's cell.
    Cells outside the grid count as not occupied."""
    c = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    n = len(c)
    if n == 0 or radius < 1:
        return np.zeros(n, dtype=bool)
    k = np.arange(-radius, radius + 1)
    offsets = np.stack(np.meshgrid(k, k, indexing="ij"), axis=-1).reshape(-1, 2)
    offsets = offsets[np.any(offsets != 0, axis=1)]
    unit = offsets / np.linalg.norm(offsets, axis=1)[:, None]
    apart = (unit @ unit.T) <= np.cos(np.radians(angle)) + 1e-9  # pairs of directions far enough apart
    rows, cols = occupied.shape
    at = c[:, None, :] + offsets[None, :, :]
    inside = (at[..., 0] >= 0) & (at[..., 0] < rows) & (at[..., 1] >= 0) & (at[..., 1] < cols)
    held = np.zeros(inside.shape, dtype=bool)
    held[inside] = occupied[at[inside][:, 0], at[inside][:, 1]]
    partner = (held.astype(np.int64) @ apart.astype(np.int64)) > 0  # an occupied cell far enough apart
    return np.asarray(np.any(held & partner, axis=1))
