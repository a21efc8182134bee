"""Union-find (disjoint sets with path halving), the one of the project.

Tarjan 1975, "Efficiency of a good but not linear set union algorithm". ``parent`` is an int64
array with ``parent[i] == i`` for a root; :func:`find` and :func:`union` are numba functions to be
called from other kernels (clustering of MCL samples, :mod:`tourbot.localization.mcl.clustering`;
the clusters of the people tracker's joint association, :mod:`tourbot.people.association`).
:func:`components` labels the connected components of a graph given by its edges and
:func:`components_reference` is its plain-Python reference.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["components", "components_reference", "find", "union"]

IntArray = NDArray[np.int64]


@numba.njit(cache=True)
def find(parent: IntArray, a: int) -> int:
    """The root of ``a``'s set (halving the path on the way)."""
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@numba.njit(cache=True)
def union(parent: IntArray, a: int, b: int) -> None:
    """Join the sets of ``a`` and ``b`` (the smaller root becomes the root)."""
    ra = find(parent, a)
    rb = find(parent, b)
    if ra != rb:
        parent[max(ra, rb)] = min(ra, rb)


@numba.njit(cache=True)
def _components_kernel(n: int, edges: IntArray) -> IntArray:
    parent = np.arange(n)
    for e in range(edges.shape[0]):
        union(parent, edges[e, 0], edges[e, 1])
    label_of_root = np.full(n, -1, np.int64)
    labels = np.empty(n, np.int64)
    nl = 0
    for i in range(n):
        r = find(parent, i)
        if label_of_root[r] < 0:
            label_of_root[r] = nl
            nl += 1
        labels[i] = label_of_root[r]
    return labels


def components(n: int, edges: ArrayLike) -> IntArray:
    """Component labels ``(n,)`` of the graph on ``n`` nodes with ``edges`` ``(E, 2)``, numbered
    in order of first appearance. A numba kernel; :func:`components_reference` is its reference."""
    e = np.ascontiguousarray(np.asarray(edges, dtype=np.int64).reshape(-1, 2))
    return np.asarray(_components_kernel(int(n), e), dtype=np.int64)


def components_reference(n: int, edges: ArrayLike) -> IntArray:
    """Plain-Python reference of :func:`components` (breadth-first search)."""
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    nbrs: list[list[int]] = [[] for _ in range(n)]
    for a, b in e.tolist():
        nbrs[a].append(b)
        nbrs[b].append(a)
    labels = np.full(n, -1, dtype=np.int64)
    nl = 0
    for s in range(n):
        if labels[s] >= 0:
            continue
        labels[s] = nl
        queue = [s]
        while queue:
            v = queue.pop()
            for w in nbrs[v]:
                if labels[w] < 0:
                    labels[w] = nl
                    queue.append(w)
        nl += 1
    return labels
