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

A component that passes both is cleared (its cells take the mean probability of the free cells
of its ring). The pass is plain numpy over the small components and the beams ending in them.
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


@dataclass(frozen=True)
class SpeckEvidence:
    """What the map says around each small occupied component (index ``k`` is label ``k + 1``)."""

    labels: NDArray[np.int32]  # (rows, cols): component label of each occupied cell, 0 elsewhere
    cells: IntArray  # (K,) cells of each component
    ring_free: FloatArray  # (K,) share of the ring seen free
    ring_occupied: FloatArray  # (K,) share of the ring occupied
    behind_free: FloatArray  # (K,) share of the cells behind seen free (0 when no beam ended in it)
    behind_cells: IntArray  # (K,) how many cells behind were looked at

    def contradicted(self, params: ConsistencyParams) -> NDArray[np.bool_]:
        """Which components the map contradicts ``(K,)``."""
        p = params
        return np.asarray(
            (self.cells <= p.max_cells)
            & (self.ring_free >= p.ring_free)
            & (self.ring_occupied <= p.ring_occupied)
            & (self.behind_cells > 0)
            & (self.behind_free >= p.behind_free)
        )


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


def speck_evidence(
    grid: OccupancyGrid,
    origins: FloatArray,
    ends: FloatArray,
    params: ConsistencyParams | None = None,
) -> SpeckEvidence:
    """The ring and behind evidence of each occupied component of ``grid`` with at most
    ``max_cells`` cells (larger ones get zeros), from the kept beams that returned: laser positions
    ``origins`` ``(B, 2)`` and world endpoints ``ends`` ``(B, 2)``."""
    p = params or ConsistencyParams()
    cat = _categories(grid)
    labels, count = ndimage.label(cat == 1, structure=np.ones((3, 3), dtype=bool))
    labels = labels.astype(np.int32)
    sizes = np.bincount(labels.ravel(), minlength=count + 1)
    small = np.zeros(count + 1, dtype=bool)
    small[1:] = sizes[1:] <= p.max_cells
    zeros = np.zeros(count)
    if not small.any():
        return SpeckEvidence(labels, sizes[1:].astype(np.int64), zeros, zeros, zeros, zeros.astype(np.int64))
    # the ring: every cell within ``ring`` cells of a small component's cells, outside the component
    members = np.argwhere(small[labels])
    member_label = labels[members[:, 0], members[:, 1]].astype(np.int64)
    k = np.arange(-p.ring, p.ring + 1)
    offsets = np.stack(np.meshgrid(k, k, indexing="ij"), axis=-1).reshape(-1, 2)
    around = (members[:, None, :] + offsets[None, :, :]).reshape(-1, 2)
    around_label = np.repeat(member_label, len(offsets))
    own = _own(labels, around, around_label)
    ring_free, ring_occ, _ = _shares(around_label[~own], around[~own], cat, count)
    # behind: cells past the ends of the beams that ended in a small component, along the beam
    behind_free, behind_n = zeros.copy(), np.zeros(count, np.int64)
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    e = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
    end_cells = grid.world_to_cell(e)
    ok = grid.inside(end_cells)
    ok[ok] = small[labels[end_cells[ok, 0], end_cells[ok, 1]]]
    if ok.any():
        o, e, end_label = o[ok], e[ok], labels[end_cells[ok, 0], end_cells[ok, 1]].astype(np.int64)
        direction = e - o
        direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-12)
        steps = np.arange(p.behind[0], p.behind[1] + 1e-9, grid.resolution / 2.0)
        pts = e[:, None, :] + steps[None, :, None] * direction[:, None, :]
        cells = grid.world_to_cell(pts.reshape(-1, 2))
        cell_label = np.repeat(end_label, len(steps))
        own = _own(labels, cells, cell_label)
        free, _, n = _shares(cell_label[~own], cells[~own], cat, count)
        behind_free, behind_n = free, n
    return SpeckEvidence(labels, sizes[1:].astype(np.int64), ring_free, ring_occ, behind_free, behind_n)


def _own(labels: NDArray[np.int32], cells: IntArray, label: IntArray) -> NDArray[np.bool_]:
    """Which ``cells`` ``(N, 2)`` belong to the component ``label`` ``(N,)`` itself."""
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
) -> tuple[OccupancyGrid, int]:
    """``grid`` with the occupied specks its own free space contradicts cleared, and how many
    cells were cleared (see :func:`speck_evidence` for ``origins`` and ``ends``)."""
    p = params or ConsistencyParams()
    ev = speck_evidence(grid, origins, ends, p)
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
