"""Clusters of samples and the estimate: the weighted mean of the heaviest cluster.

Samples are binned on a grid of ``cell x cell x cell_theta`` (KLD-sampling's bins, Fox 2003);
occupied bins that touch (26-neighbourhood, heading wrapping) form one cluster, as Nav2 AMCL's
``pf_cluster_stats`` does. The estimate is the heaviest cluster's weighted mean pose (circular mean
of the headings) with its covariance (Probabilistic Robotics Sec. 4.3.4 on extracting a pose from
a multi-modal sample set).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.geometry import wrap_angle
from tourbot.localization.mcl.kld import bin_keys
from tourbot.union_find import find, union

__all__ = [
    "best_cluster_estimate",
    "best_cluster_estimate_reference",
    "cell_keys",
    "cluster_bins",
    "cluster_bins_reference",
    "weighted_mean_cov",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def cell_keys(samples: FloatArray, cell: float, cell_theta: float) -> IntArray:
    """An integer label per sample: the cell of a ``cell x cell x cell_theta`` grid holding it."""
    ix = np.floor(samples[:, 0] / cell).astype(np.int64)
    iy = np.floor(samples[:, 1] / cell).astype(np.int64)
    n_th = max(1, round(2 * math.pi / cell_theta))
    it = np.floor((samples[:, 2] + math.pi) / (2 * math.pi) * n_th).astype(np.int64) % n_th
    ix -= ix.min()
    iy -= iy.min()
    return (ix * (int(iy.max()) + 1) + iy) * n_th + it


def weighted_mean_cov(samples: FloatArray, weights: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The weighted mean pose (circular mean of headings) and covariance (heading differences wrapped)."""
    w = weights / weights.sum()
    mx = float(w @ samples[:, 0])
    my = float(w @ samples[:, 1])
    mth = math.atan2(float(w @ np.sin(samples[:, 2])), float(w @ np.cos(samples[:, 2])))
    d = np.column_stack([samples[:, 0] - mx, samples[:, 1] - my, wrap_angle(samples[:, 2] - mth)])
    cov = (d * w[:, None]).T @ d
    return np.array([mx, my, mth]), np.asarray(cov, dtype=np.float64)


def best_cluster_estimate(
    samples: FloatArray, weights: FloatArray, labels: IntArray
) -> tuple[FloatArray, FloatArray, float]:
    """The heaviest cluster's weighted mean pose (circular mean of headings), covariance and weight.

    The cluster weights and the mean are a numba kernel; :func:`best_cluster_estimate_reference`
    is its plain-numpy reference.
    """
    n_labels = int(labels.max()) + 1 if labels.size else 0
    s = np.ascontiguousarray(samples, dtype=np.float64)
    w = np.ascontiguousarray(weights, dtype=np.float64)
    lab = np.ascontiguousarray(labels, dtype=np.int64)
    pose = np.zeros(3)
    best, total = _best_cluster_mean_kernel(s, w, lab, n_labels, pose)
    sel = lab == best
    ws = w[sel] / total
    d = np.column_stack([s[sel, 0] - pose[0], s[sel, 1] - pose[1], wrap_angle(s[sel, 2] - pose[2])])
    cov = np.asarray((d * ws[:, None]).T @ d, dtype=np.float64)
    return pose, cov, total


@numba.njit(cache=True)
def _best_cluster_mean_kernel(
    samples: FloatArray, weights: FloatArray, labels: IntArray, n_labels: int, pose: FloatArray
) -> tuple[int, float]:
    cw = np.zeros(n_labels)
    for i in range(labels.shape[0]):
        cw[labels[i]] += weights[i]
    best = 0
    for k in range(n_labels):
        if cw[k] > cw[best]:
            best = k
    total = cw[best]
    mx = 0.0
    my = 0.0
    sn = 0.0
    cs = 0.0
    for i in range(labels.shape[0]):
        if labels[i] == best:
            w = weights[i] / total
            mx += w * samples[i, 0]
            my += w * samples[i, 1]
            sn += w * math.sin(samples[i, 2])
            cs += w * math.cos(samples[i, 2])
    pose[0] = mx
    pose[1] = my
    pose[2] = math.atan2(sn, cs)
    return best, total


def best_cluster_estimate_reference(
    samples: FloatArray, weights: FloatArray, labels: IntArray
) -> tuple[FloatArray, FloatArray, float]:
    """Plain-numpy reference of :func:`best_cluster_estimate`."""
    cw = np.bincount(labels, weights=weights)
    best = int(np.argmax(cw))
    sel = labels == best
    pose, cov = weighted_mean_cov(samples[sel], weights[sel])
    return pose, cov, float(cw[best])


_EMPTY = -1  # an empty slot of the bin hash table (bin keys are >= 0, see kld.bin_keys)


@numba.njit(cache=True, inline="always")
def _slot(table: IntArray, key: int, mask: int) -> np.int64:
    """The slot of ``key`` in the open-addressing hash table ``table`` (linear probing): where it
    is, or the empty slot where it would go."""
    h = (np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(32)
    j = np.int64(h) & mask
    while table[j] != _EMPTY and table[j] != key:
        j = (j + 1) & mask
    return j


@numba.njit(cache=True)
def _cluster_kernel(keys: IntArray, ny: int, n_th: int) -> IntArray:
    """Union-find over the occupied bins, found through a hash table of their keys (no sort):
    each bin is joined with its 26 neighbours that hold samples."""
    n = keys.shape[0]
    cap = 16
    while cap < 2 * n:
        cap *= 2
    mask = cap - 1
    table = np.full(cap, _EMPTY, np.int64)
    bin_at = np.empty(cap, np.int64)  # bin index of the key in each occupied slot
    bin_of = np.empty(n, np.int64)
    uniq = np.empty(n, np.int64)
    m = 0
    for i in range(n):
        j = _slot(table, keys[i], mask)
        if table[j] == _EMPTY:
            table[j] = keys[i]
            bin_at[j] = m
            uniq[m] = keys[i]
            m += 1
        bin_of[i] = bin_at[j]
    parent = np.arange(m)
    for b in range(m):
        key = uniq[b]
        it = key % n_th
        rest = key // n_th
        iy = rest % ny
        ix = rest // ny
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                for dt in range(-1, 2):
                    t = (it + dt) % n_th
                    nk = ((ix + dx) * ny + (iy + dy)) * n_th + t
                    j = _slot(table, nk, mask)
                    if table[j] != _EMPTY:
                        union(parent, b, bin_at[j])
    # compact labels, numbered in order of first appearance
    label_of_root = np.full(m, -1, np.int64)
    labels = np.empty(n, np.int64)
    nl = 0
    for i in range(n):
        r = find(parent, bin_of[i])
        if label_of_root[r] < 0:
            label_of_root[r] = nl
            nl += 1
        labels[i] = label_of_root[r]
    return labels


def cluster_bins(samples: ArrayLike, cell: float, cell_theta: float) -> IntArray:
    """Cluster labels ``(N,)``: samples in bins that touch (26-neighbourhood, heading wraps) share one.

    Labels are numbered in order of first appearance.
    """
    s = np.ascontiguousarray(samples, dtype=np.float64).reshape(-1, 3)
    if s.shape[0] == 0:
        return np.zeros(0, np.int64)
    keys, ny, n_th = bin_keys(s, cell, cell_theta)
    return np.asarray(_cluster_kernel(keys, ny, n_th), dtype=np.int64)


def cluster_bins_reference(samples: ArrayLike, cell: float, cell_theta: float) -> IntArray:
    """Plain-Python reference of :func:`cluster_bins` (breadth-first search over occupied bins)."""
    s = np.asarray(samples, dtype=np.float64).reshape(-1, 3)
    n_th = max(1, round(2 * math.pi / cell_theta))
    bins = [
        (
            math.floor(x / cell),
            math.floor(y / cell),
            math.floor((t + math.pi) / (2 * math.pi) * n_th) % n_th,
        )
        for x, y, t in s
    ]
    occupied = set(bins)
    comp: dict[tuple[int, int, int], int] = {}
    for start in dict.fromkeys(bins):
        if start in comp:
            continue
        root = len(set(comp.values()))
        comp[start] = root
        stack = [start]
        while stack:
            bx, by, bt = stack.pop()
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    for dt in (-1, 0, 1):
                        nb = (bx + dx, by + dy, (bt + dt) % n_th)
                        if nb in occupied and nb not in comp:
                            comp[nb] = root
                            stack.append(nb)
    return np.array([comp[b] for b in bins], dtype=np.int64)
