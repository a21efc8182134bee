"""Occupied specks that the finished map contradicts: people seen once, cleared after mapping.

People filtering (Burgard et al. Sec. 5) leaves out the beams it takes for people while the map is
built; a visitor it missed, seen once through a gap and never again from that side, stays as a
small occupied speck. The finished map knows more than any single scan did: a visitor stands on
floor, so the cells around the speck and those just behind it along the beams that hit it are
floor that other scans, at other times, saw free. A wall or an exhibit seen once is different:
what lies behind its face is its body or space no beam reached (unknown), and it continues into
neighbouring occupied cells.

So, over the finished map, each 8-connected component of occupied cells with at most
``max_cells`` cells is judged (a consistency check of the map against itself):

* its ring, the cells within ``ring`` cells (Chebyshev) of it, outside it: the share seen free
  (log-odds at most 0: at least as many misses as a hit outweighs) must be at least
  ``ring_free``, and the share occupied at most ``ring_occupied``;
* behind it, the cells from ``behind[0]`` to ``behind[1]`` metres past each end of a kept beam
  in the component, along the beam, outside it: the share seen free must be at least
  ``behind_free``.

A group of visitors leaves several specks a few decimetres apart, each in the ring of another, so
none passes alone. Groups are therefore also judged as a whole: the components of at most
``group_member_cells`` cells are joined into groups by dilating them ``group_radius`` cells (two
join when their cells are at most ``2 * group_radius + 1`` cells apart, Chebyshev), and a group of
at most ``group_cells`` cells is cleared when its ring (the cells within ``ring`` cells of any
member, outside the group) is at least ``ring_free`` seen free with no occupied cell in it (so no
larger structure within ``ring`` cells), and the cells behind the ends of the kept beams in any of
its members are at least ``behind_free`` seen free. A lone component is a group of one, so with
``group_member_cells`` above ``max_cells`` an isolated speck of up to that many cells can go too;
``group_radius = 0`` turns group judging off (the check of the first version).

Specks seen only from afar (``far_range``, None: off): a visitor far away is hit by one or two
beams of one scan (about 10 cm apart at 6 m), and the floor just behind it was seldom seen by
any other beam, so ``behind_free`` rarely passes. A component of at most ``far_cells`` cells
whose beams (every beam that ended in it) all ended farther than ``far_range`` metres from the
laser, from at most ``far_scans`` scans, is also cleared when its ring is at least
``far_ring_free`` seen free with no occupied cell in it and the cells behind it are at least
``far_behind_free`` seen free. A group (above) whose members were each hit from beyond
``far_range`` only, by at most ``far_group_scans`` scans each, is judged as other groups are but
with ``far_behind_free`` in place of ``behind_free`` (a few far visitors standing together).
Structure seen once from afar is what the laser sees live anyway;
a wall seen from afar continues into neighbouring occupied cells (the ring), and what lies behind
it is its body or unknown.

Visitors standing together beyond the leg detector's reach (``mutual_range``, None: off): each is
a speck a beam or two of one scan hit, and each lies in the ring of another, so that none passes
with no occupied cell in its ring, while their specks chained together (with the static specks
around) make groups too large to judge. A component of at most ``far_cells`` cells whose beams all
ended farther than ``mutual_range`` metres from the laser, from at most ``far_scans`` scans, with
a ring at least ``far_ring_free`` seen free and at least ``far_behind_free`` of the cells behind
it seen free, is a *loose* speck; a loose speck is cleared when every occupied cell in its ring
belongs to a loose speck too, or to a component another test clears. A dotted wall or an exhibit
next to the speck is larger or has nothing seen behind it, and keeps it.

A component that passes any test is cleared (its cells take the mean probability of the free
cells around them). The pass is plain numpy over the small components and the beams ending in them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from tourbot.maps.grid import OccupancyGrid

__all__ = ["ConsistencyParams", "SpeckEvidence", "clear_specks", "speck_evidence"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class ConsistencyParams:
    """Which occupied specks the finished map contradicts (see the module's docstring)."""

    max_cells: int = 2
    ring: int = 2
    ring_free: float = 0.6
    ring_occupied: float = 0.0
    behind: tuple[float, float] = (0.10, 0.50)
    behind_free: float = 0.5
    group_radius: int = 5  # 0: no group judging
    group_member_cells: int = 4
    group_cells: int = 10
    far_range: float | None = None  # metres; None: no test of specks seen only from afar
    far_scans: int = 1
    far_cells: int = 2  # at most max_cells (only those have their ring and behind evidence)
    far_ring_free: float = 0.75
    far_behind_free: float = 0.2
    far_group_scans: int = 2
    mutual_range: float | None = None  # metres; None: no test of loose specks next to each other


@dataclass(frozen=True)
class SpeckEvidence:
    """What the map says around each small occupied component (index ``k`` is label ``k + 1``) and
    around each group of them (index ``g`` is group ``g + 1``)."""

    labels: NDArray[np.int32]  # (rows, cols): component label of each occupied cell, 0 elsewhere
    cells: IntArray  # (K,) cells of each component
    ring_free: FloatArray  # (K,) share of the ring seen free
    ring_occupied: FloatArray  # (K,) share of the ring occupied
    behind_free: FloatArray  # (K,) share of the cells behind seen free (0 when no beam ended in it)
    behind_cells: IntArray  # (K,) how many cells behind were looked at
    group: IntArray  # (K,) group of each component (1-based), 0 for components in none
    group_cells: IntArray  # (G,) cells of each group
    group_ring_free: FloatArray  # (G,) share of the group's ring seen free
    group_ring_occupied: FloatArray  # (G,) share of the group's ring occupied
    group_behind_free: FloatArray  # (G,) share of the cells behind the group's ends seen free
    group_behind_cells: IntArray  # (G,) how many cells behind the group were looked at
    nearest: FloatArray  # (K,) shortest range (m) at which a beam ended in it (inf: none did)
    scans: IntArray  # (K,) distinct scans with a beam ending in it (0 without scan indices)
    neighbours: IntArray  # (M, 2) components k and j (0-based) with a cell of j in k's ring (k small)

    def contradicted(self, params: ConsistencyParams) -> NDArray[np.bool_]:
        """Which components the map contradicts ``(K,)``: alone, or as a member of a group."""
        p = params
        alone = (
            (self.cells <= p.max_cells)
            & (self.ring_free >= p.ring_free)
            & (self.ring_occupied <= p.ring_occupied)
            & (self.behind_cells > 0)
            & (self.behind_free >= p.behind_free)
        )
        together = np.zeros(len(self.group_cells) + 1, dtype=bool)
        together[1:] = (
            (self.group_cells <= p.group_cells)
            & (self.group_ring_free >= p.ring_free)
            & (self.group_ring_occupied <= 0.0)
            & (self.group_behind_cells > 0)
            & (self.group_behind_free >= p.behind_free)
        )
        far = np.zeros(len(self.cells), dtype=bool)
        if p.far_range is not None:
            far = (
                (self.cells <= min(p.far_cells, p.max_cells))
                & (self.nearest > p.far_range)
                & (self.scans <= p.far_scans)
                & (self.ring_free >= p.far_ring_free)
                & (self.ring_occupied <= 0.0)
                & (self.behind_cells > 0)
                & (self.behind_free >= p.far_behind_free)
            )
            seen_far = (self.nearest > p.far_range) & (self.scans <= p.far_group_scans)
            all_far = np.ones(len(self.group_cells) + 1, dtype=bool)
            member = self.group > 0
            np.logical_and.at(all_far, self.group[member], seen_far[member])
            far_group = np.zeros(len(self.group_cells) + 1, dtype=bool)
            far_group[1:] = (
                all_far[1:]
                & (self.group_cells <= p.group_cells)
                & (self.group_ring_free >= p.ring_free)
                & (self.group_ring_occupied <= 0.0)
                & (self.group_behind_cells > 0)
                & (self.group_behind_free >= p.far_behind_free)
            )
            far |= member & far_group[self.group]
        cleared = alone | together[self.group] | far
        if p.mutual_range is not None:
            cleared |= self._mutual(p, cleared)
        return np.asarray(cleared)

    def _mutual(self, p: ConsistencyParams, cleared: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """The loose specks whose ring holds only cells of loose specks or of ``cleared`` ones."""
        loose = (
            (self.cells <= min(p.far_cells, p.max_cells))
            & (self.nearest > (p.mutual_range or 0.0))
            & (self.scans <= p.far_scans)
            & (self.ring_free >= p.far_ring_free)
            & (self.behind_cells > 0)
            & (self.behind_free >= p.far_behind_free)
        )
        ok = loose | cleared
        spoilt = np.zeros(len(self.cells), dtype=bool)
        k, j = self.neighbours[:, 0], self.neighbours[:, 1]
        np.logical_or.at(spoilt, k, ~ok[j])
        return np.asarray(loose & ~spoilt)


def _categories(grid: OccupancyGrid) -> NDArray[np.int8]:
    """0 seen free (probability at most 0.5), 1 occupied, 2 unknown, 3 in between."""
    prob = grid.prob
    cat = np.full(prob.shape, 3, np.int8)
    cat[(prob >= 0.0) & (prob <= 0.5)] = 0
    cat[grid.occupied()] = 1
    cat[prob < 0.0] = 2
    return cat


def _shares(
    labels: IntArray, cells: IntArray, cat: NDArray[np.int8], count: int
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Per component (labels 1..count): share of its distinct ``cells`` ``(N, 2)`` seen free, share
    occupied, and how many there are. ``cells`` outside the grid count as unknown."""
    rows, cols = cat.shape
    _, first = np.unique(np.stack([labels, cells[:, 0], cells[:, 1]], axis=1), axis=0, return_index=True)
    labels, cells = labels[first], cells[first]
    inside = (cells[:, 0] >= 0) & (cells[:, 0] < rows) & (cells[:, 1] >= 0) & (cells[:, 1] < cols)
    c = np.full(len(labels), 2, np.int8)
    c[inside] = cat[cells[inside, 0], cells[inside, 1]]
    n = np.bincount(labels, minlength=count + 1)[1:]
    free = np.bincount(labels, weights=(c == 0).astype(np.float64), minlength=count + 1)[1:]
    occ = np.bincount(labels, weights=(c == 1).astype(np.float64), minlength=count + 1)[1:]
    m = np.maximum(n, 1)
    return free / m, occ / m, n.astype(np.int64)


def _evidence(
    grid: OccupancyGrid,
    cat: NDArray[np.int8],
    labels: NDArray[np.int32],
    count: int,
    origins: FloatArray,
    ends: FloatArray,
    p: ConsistencyParams,
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray]:
    """Ring and behind evidence of each labelled region (``labels`` 1..count over the grid, 0
    elsewhere): ring free and occupied shares, behind free share and how many cells behind."""
    zeros = np.zeros(count)
    if count == 0:
        return zeros, zeros, zeros, zeros.astype(np.int64)
    # the ring: every cell within ``ring`` cells of a region's cells, outside the region
    members = np.argwhere(labels > 0)
    member_label = labels[members[:, 0], members[:, 1]].astype(np.int64)
    k = np.arange(-p.ring, p.ring + 1)
    offsets = np.stack(np.meshgrid(k, k, indexing="ij"), axis=-1).reshape(-1, 2)
    around = (members[:, None, :] + offsets[None, :, :]).reshape(-1, 2)
    around_label = np.repeat(member_label, len(offsets))
    own = _own(labels, around, around_label)
    ring_free, ring_occ, _ = _shares(around_label[~own], around[~own], cat, count)
    # behind: cells past the ends of the beams that ended in a region, along the beam
    behind_free, behind_n = zeros.copy(), np.zeros(count, np.int64)
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    e = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
    end_cells = grid.world_to_cell(e)
    ok = grid.inside(end_cells)
    ok[ok] = labels[end_cells[ok, 0], end_cells[ok, 1]] > 0
    if ok.any():
        o, e, end_label = o[ok], e[ok], labels[end_cells[ok, 0], end_cells[ok, 1]].astype(np.int64)
        direction = e - o
        direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-12)
        steps = np.arange(p.behind[0], p.behind[1] + 1e-9, grid.resolution / 2.0)
        pts = e[:, None, :] + steps[None, :, None] * direction[:, None, :]
        cells = grid.world_to_cell(pts.reshape(-1, 2))
        cell_label = np.repeat(end_label, len(steps))
        own = _own(labels, cells, cell_label)
        behind_free, _, behind_n = _shares(cell_label[~own], cells[~own], cat, count)
    return ring_free, ring_occ, behind_free, behind_n


def _compact(labels: NDArray[np.int32], keep: NDArray[np.bool_]) -> tuple[NDArray[np.int32], IntArray]:
    """``labels`` with only the labels in ``keep`` ``(count + 1,)``, renumbered 1..n; and the
    old label of each new one ``(n,)``."""
    old = np.flatnonzero(keep)
    new = np.zeros(len(keep), np.int32)
    new[old] = np.arange(1, len(old) + 1, dtype=np.int32)
    return new[labels], old.astype(np.int64)


def speck_evidence(
    grid: OccupancyGrid,
    origins: FloatArray,
    ends: FloatArray,
    params: ConsistencyParams | None = None,
    scans: IntArray | None = None,
) -> SpeckEvidence:
    """The ring and behind evidence of each occupied component of ``grid`` with at most
    ``max_cells`` cells (larger ones get zeros), and of each group of components with at most
    ``group_member_cells`` cells, from the kept beams that returned: laser positions ``origins``
    ``(B, 2)`` and world endpoints ``ends`` ``(B, 2)``; with the scan index of each beam ``scans``
    ``(B,)``, also how many distinct scans ended beams in each component."""
    p = params or ConsistencyParams()
    cat = _categories(grid)
    labels, count = ndimage.label(cat == 1, structure=np.ones((3, 3), dtype=bool))
    labels = labels.astype(np.int32)
    sizes = np.bincount(labels.ravel(), minlength=count + 1)
    sizes[0] = 0
    # each small component alone
    small = np.zeros(count + 1, dtype=bool)
    small[1:] = sizes[1:] <= p.max_cells
    ring_free, ring_occ = np.zeros(count), np.zeros(count)
    behind_free, behind_n = np.zeros(count), np.zeros(count, np.int64)
    if small.any():
        compact, old = _compact(labels, small)
        rf, ro, bf, bn = _evidence(grid, cat, compact, len(old), origins, ends, p)
        ring_free[old - 1], ring_occ[old - 1], behind_free[old - 1], behind_n[old - 1] = rf, ro, bf, bn
    # groups of small components
    group = np.zeros(count, np.int64)
    empty = np.zeros(0)
    g_cells, g_rf, g_ro, g_bf, g_bn = empty.astype(np.int64), empty, empty, empty, empty.astype(np.int64)
    member = np.zeros(count + 1, dtype=bool)
    member[1:] = sizes[1:] <= p.group_member_cells
    if p.group_radius > 0 and member.any():
        mask = member[labels]
        size = 2 * p.group_radius + 1
        grown = ndimage.binary_dilation(mask, structure=np.ones((size, size), dtype=bool))
        regions, _ = ndimage.label(grown, structure=np.ones((3, 3), dtype=bool))
        keep = np.zeros(int(regions.max()) + 1, dtype=bool)
        keep[np.unique(regions[mask])] = True
        keep[0] = False
        group_labels, _ = _compact(np.where(mask, regions, 0).astype(np.int32), keep)
        n_groups = int(group_labels.max())
        g_rf, g_ro, g_bf, g_bn = _evidence(grid, cat, group_labels, n_groups, origins, ends, p)
        g_cells = np.bincount(group_labels.ravel(), minlength=n_groups + 1)[1:].astype(np.int64)
        cells = np.argwhere(mask)
        group[labels[cells[:, 0], cells[:, 1]] - 1] = group_labels[cells[:, 0], cells[:, 1]]
    nearest, n_scans = _ranges(grid, labels, count, origins, ends, scans)
    return SpeckEvidence(
        labels, sizes[1:].astype(np.int64), ring_free, ring_occ, behind_free, behind_n,
        group, g_cells, g_rf, g_ro, g_bf, g_bn, nearest, n_scans,
        _neighbours(labels, small, p.ring),
    )  # fmt: skip


def _neighbours(labels: NDArray[np.int32], small: NDArray[np.bool_], ring: int) -> IntArray:
    """Pairs ``(M, 2)`` of components (0-based): ``k`` small (``small`` ``(count + 1,)``) and ``j``
    another one with a cell within ``ring`` cells (Chebyshev) of ``k``'s cells."""
    members = np.argwhere(small[labels])
    own = labels[members[:, 0], members[:, 1]].astype(np.int64)
    k = np.arange(-ring, ring + 1)
    offsets = np.stack(np.meshgrid(k, k, indexing="ij"), axis=-1).reshape(-1, 2)
    around = (members[:, None, :] + offsets[None, :, :]).reshape(-1, 2)
    own = np.repeat(own, len(offsets))
    rows, cols = labels.shape
    inside = (around[:, 0] >= 0) & (around[:, 0] < rows) & (around[:, 1] >= 0) & (around[:, 1] < cols)
    other = np.zeros(len(around), np.int64)
    other[inside] = labels[around[inside, 0], around[inside, 1]]
    pair = (other > 0) & (other != own)
    pairs = np.unique(np.stack([own[pair], other[pair]], axis=1), axis=0)
    return np.asarray(pairs.reshape(-1, 2) - 1, dtype=np.int64)


def _ranges(
    grid: OccupancyGrid,
    labels: NDArray[np.int32],
    count: int,
    origins: FloatArray,
    ends: FloatArray,
    scans: IntArray | None,
) -> tuple[FloatArray, IntArray]:
    """Per component (labels 1..count): the shortest range of the beams that ended in it (inf when
    none did) and how many distinct scans they came from (0 without ``scans``)."""
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    e = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
    cells = grid.world_to_cell(e)
    ok = grid.inside(cells)
    label = np.zeros(len(e), np.int64)
    label[ok] = labels[cells[ok, 0], cells[ok, 1]]
    nearest = np.full(count + 1, np.inf)
    np.minimum.at(nearest, label, np.linalg.norm(e - o, axis=1))
    n_scans = np.zeros(count + 1, np.int64)
    if scans is not None:
        s = np.asarray(scans, dtype=np.int64).reshape(-1)
        inside = label > 0
        pairs = np.unique(np.stack([label[inside], s[inside]], axis=1), axis=0)
        n_scans = np.bincount(pairs[:, 0], minlength=count + 1).astype(np.int64)
    return nearest[1:], n_scans[1:]


def _own(labels: NDArray[np.int32], cells: IntArray, label: IntArray) -> NDArray[np.bool_]:
    """Which ``cells`` ``(N, 2)`` belong to the region ``label`` ``(N,)`` itself."""
    rows, cols = labels.shape
    inside = (cells[:, 0] >= 0) & (cells[:, 0] < rows) & (cells[:, 1] >= 0) & (cells[:, 1] < cols)
    own = np.zeros(len(cells), dtype=bool)
    own[inside] = labels[cells[inside, 0], cells[inside, 1]] == label[inside]
    return own


def clear_specks(
    grid: OccupancyGrid,
    origins: FloatArray,
    ends: FloatArray,
    params: ConsistencyParams | None = None,
    scans: IntArray | None = None,
) -> tuple[OccupancyGrid, int]:
    """``grid`` with the occupied specks its own free space contradicts cleared, and how many
    cells were cleared (see :func:`speck_evidence` for ``origins``, ``ends`` and ``scans``, which
    the test of specks seen only from afar needs)."""
    p = params or ConsistencyParams()
    if (p.far_range is not None or p.mutual_range is not None) and scans is None:
        raise ValueError("the test of specks seen only from afar needs the scan of each beam")
    ev = speck_evidence(grid, origins, ends, p, scans)
    gone = np.zeros(len(ev.cells) + 1, dtype=bool)
    gone[1:] = ev.contradicted(p)
    cleared = gone[ev.labels]
    n = int(cleared.sum())
    if n == 0:
        return grid, 0
    prob = grid.prob.copy()
    seen_free = (prob >= 0.0) & (prob <= 0.5)
    # the mean probability of the free cells around each cleared cell (within the ring)
    size = 2 * p.ring + 1
    total = ndimage.uniform_filter(np.where(seen_free, prob, 0.0).astype(np.float64), size, mode="constant")
    many = ndimage.uniform_filter(seen_free.astype(np.float64), size, mode="constant")
    fill = np.where(many > 0, total / np.maximum(many, 1e-12), 0.5)
    prob[cleared] = fill[cleared].astype(prob.dtype)
    out = OccupancyGrid(prob, grid.resolution, grid.origin, grid.occupied_thresh, grid.free_thresh)
    return out, n
