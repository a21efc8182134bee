"""Sample-based joint probabilistic data association: Eq. 6-9 of Burgard et al. (Sec. 4).

The kernels here are the sample-level and event-level hot loops of the SJPDAF (Schulz et al. 2001),
each a numba kernel with a plain-numpy reference beside it:

- :func:`pair_likelihoods`: ``p(z_j(t) | x_{i,n}^t)`` for each gated (person i, feature j) pair and
  each of person i's samples n; its mean over n is Eq. 8, ``p(z_j(t) | x_i^t)``.
- :func:`joint_betas`: the association probabilities ``beta_ji`` of Eq. 6-7, summed over all valid
  joint events of one cluster of people and features.
- :func:`sample_weights`: the sample weights of Eq. 9.

Eq. 7 is used in its detection-aware form: a joint event ``theta`` weighs
``gamma^(m - |theta|) * prod_{(j,i) in theta} P_D p(z_j | x_i) * prod_{i missed} (1 - P_D)``, where
``gamma`` is the density of false alarms; the ``(1 - P_D)`` factors reduce to Eq. 7's plain form
when ``P_D`` is the same for all persons, and let an occluded person (``P_D`` ~ 0) be missed freely.
Dividing by ``gamma^m`` (a constant of the normaliser alpha) gives the per-pair ratio
``P_D p(z_j | x_i) / gamma`` that :func:`joint_betas` takes.
"""

from __future__ import annotations

import itertools
import math

import numba
import numpy as np
from numpy.typing import NDArray

from tourbot.union_find import _components_kernel, find, union

__all__ = [
    "cluster_betas",
    "cluster_betas_reference",
    "joint_betas",
    "joint_betas_reference",
    "pair_likelihoods",
    "pair_likelihoods_reference",
    "sample_weights",
    "sample_weights_reference",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


# --- Eq. 8: per-sample feature likelihoods --------------------------------------------------------


def pair_likelihoods_reference(
    samples: FloatArray,
    detect: FloatArray,
    features: FloatArray,
    pair_track: IntArray,
    pair_feature: IntArray,
    sigma: FloatArray,
) -> FloatArray:
    """``P_D(x_{i,n}) N(z_j; x_{i,n}, sigma_j^2 I)`` for pairs ``(P,)`` and samples: ``(P, N)``.

    ``samples`` ``(K, N, 4)``, ``detect`` ``(K, N)`` the detection probability of each sample (zero
    where occluded), ``features`` ``(M, 2)`` with their position noise ``sigma`` ``(M,)``.
    """
    diff = samples[pair_track, :, 0:2] - features[pair_feature][:, None, :]
    sq = np.sum(diff * diff, axis=-1)
    s2 = (sigma[pair_feature] ** 2)[:, None]
    return detect[pair_track] / (2.0 * math.pi * s2) * np.exp(-0.5 * sq / s2)


@numba.njit(cache=True)
def _pair_likelihoods_kernel(
    samples: FloatArray,
    detect: FloatArray,
    features: FloatArray,
    pair_track: IntArray,
    pair_feature: IntArray,
    sigma: FloatArray,
) -> FloatArray:
    P = pair_track.shape[0]
    N = samples.shape[1]
    out = np.empty((P, N))
    for p in range(P):
        s2 = sigma[pair_feature[p]] ** 2
        norm = 1.0 / (2.0 * math.pi * s2)
        inv = 0.5 / s2
        k = pair_track[p]
        zx = features[pair_feature[p], 0]
        zy = features[pair_feature[p], 1]
        for n in range(N):
            dx = samples[k, n, 0] - zx
            dy = samples[k, n, 1] - zy
            out[p, n] = detect[k, n] * norm * math.exp(-(dx * dx + dy * dy) * inv)
    return out


def pair_likelihoods(
    samples: FloatArray,
    detect: FloatArray,
    features: FloatArray,
    pair_track: IntArray,
    pair_feature: IntArray,
    sigma: FloatArray,
) -> FloatArray:
    """Numba kernel of :func:`pair_likelihoods_reference`."""
    if pair_track.shape[0] == 0:
        return np.zeros((0, samples.shape[1]))
    return _pair_likelihoods_kernel(
        np.ascontiguousarray(samples, dtype=np.float64),
        np.ascontiguousarray(detect, dtype=np.float64),
        np.ascontiguousarray(features, dtype=np.float64),
        np.ascontiguousarray(pair_track, dtype=np.int64),
        np.ascontiguousarray(pair_feature, dtype=np.int64),
        np.ascontiguousarray(sigma, dtype=np.float64),
    )


# --- Eq. 6-7: association probabilities over joint events -----------------------------------------


def joint_betas_reference(ratio: FloatArray, miss: FloatArray) -> FloatArray:
    """``beta`` ``(T, F + 1)`` by enumerating every joint event with :mod:`itertools` (reference).

    ``ratio[t, f] = P_D p(z_f | x_t) / gamma`` (0 outside the gate) and ``miss[t]`` the weight of
    person t going undetected. Column 0 of the result is ``beta_0t`` (no feature), column ``f + 1``
    is ``beta_ft``. A joint event gives each person one feature or none, no feature to two persons.
    """
    T, F = ratio.shape
    options = [[-1, *[f for f in range(F) if ratio[t, f] > 0.0]] for t in range(T)]
    beta = np.zeros((T, F + 1))
    total = 0.0
    for event in itertools.product(*options):
        chosen = [f for f in event if f >= 0]
        if len(chosen) != len(set(chosen)):
            continue
        w = 1.0
        for t, f in enumerate(event):
            w *= miss[t] if f < 0 else ratio[t, f]
        total += w
        for t, f in enumerate(event):
            beta[t, f + 1] += w
    return beta / total if total > 0.0 else beta


@numba.njit(cache=True)
def _joint_betas_kernel(ratio: FloatArray, miss: FloatArray) -> FloatArray:
    T, F = ratio.shape
    beta = np.zeros((T, F + 1))
    choice = np.full(T, -2, dtype=np.int64)
    used = np.zeros(F, dtype=np.bool_)
    weight = np.ones(T + 1)
    total = 0.0
    t = 0
    # Depth-first walk over joint events; choice -1 is "person t not detected".
    while t >= 0:
        if choice[t] >= 0:
            used[choice[t]] = False
        c = choice[t] + 1
        while 0 <= c < F and (ratio[t, c] <= 0.0 or used[c]):
            c += 1
        if c >= F:
            choice[t] = -2
            t -= 1
            continue
        choice[t] = c
        if c < 0:
            weight[t + 1] = weight[t] * miss[t]
        else:
            used[c] = True
            weight[t + 1] = weight[t] * ratio[t, c]
        if t == T - 1:
            w_event = float(weight[T])
            total += w_event
            for s in range(T):
                beta[s, choice[s] + 1] += w_event
        else:
            t += 1
    if total > 0.0:
        for s in range(T):
            for f in range(F + 1):
                beta[s, f] /= total
    return beta


def joint_betas(ratio: FloatArray, miss: FloatArray) -> FloatArray:
    """Eq. 6-7 over one cluster: numba kernel of :func:`joint_betas_reference`."""
    if ratio.shape[0] == 0:
        return np.zeros((0, ratio.shape[1] + 1))
    return _joint_betas_kernel(
        np.ascontiguousarray(ratio, dtype=np.float64), np.ascontiguousarray(miss, dtype=np.float64)
    )


@numba.njit(cache=True)
def _pieces(ratio: FloatArray, piece: IntArray) -> int:
    """Label the persons (rows) of ``ratio`` by the connected piece they belong to, persons linked
    through a feature they both gate; returns the number of pieces."""
    nt, nf = ratio.shape
    edges = np.empty((nt * nf, 2), dtype=np.int64)
    e = 0
    for i in range(nt):
        for j in range(nf):
            if ratio[i, j] > 0.0:
                edges[e, 0] = i
                edges[e, 1] = nt + j
                e += 1
    # persons come first, so their labels are the first ones given: 0 .. pieces - 1
    labels = _components_kernel(nt + nf, edges[:e])
    n = 0
    for i in range(nt):
        piece[i] = labels[i]
        n = max(n, labels[i] + 1)
    return n


@numba.njit(cache=True)
def _largest_events(ratio: FloatArray, piece: IntArray, n_pieces: int) -> float:
    """An upper bound of the joint events of the largest piece: the product over its persons of
    their options plus one (not detected)."""
    events = np.ones(n_pieces)
    for i in range(ratio.shape[0]):
        c = 0
        for j in range(ratio.shape[1]):
            if ratio[i, j] > 0.0:
                c += 1
        events[piece[i]] *= c + 1
    return events.max() if n_pieces else 0.0


@numba.njit(cache=True)
def _cluster_betas_kernel(
    pair_track: IntArray, pair_feature: IntArray, ratio: FloatArray, miss: FloatArray, M: int, max_events: int
) -> tuple[FloatArray, FloatArray]:
    K = miss.shape[0]
    P = pair_track.shape[0]
    parent = np.arange(K + M)
    for p in range(P):
        union(parent, pair_track[p], K + pair_feature[p])
    root = np.empty(K + M, dtype=np.int64)
    for v in range(K + M):
        root[v] = find(parent, v)
    beta0 = np.ones(K)
    pair_beta = np.zeros(P)
    local = np.full(K + M, -1, dtype=np.int64)
    done = np.zeros(K + M, dtype=np.bool_)
    for t0 in range(K):
        r = root[t0]
        if done[r]:
            continue
        done[r] = True
        # The persons and features of this cluster, numbered locally.
        nt = 0
        nf = 0
        for v in range(K + M):
            if root[v] == r:
                if v < K:
                    local[v] = nt
                    nt += 1
                else:
                    local[v] = nf
                    nf += 1
        tracks = np.empty(nt, dtype=np.int64)
        for v in range(K):
            if root[v] == r:
                tracks[local[v]] = v
        sub = np.zeros((nt, nf))
        for p in range(P):
            if root[pair_track[p]] == r:
                sub[local[pair_track[p]], local[K + pair_feature[p]]] = ratio[p]
        # Prune the weakest options until the joint events are few enough. Pruning cuts the
        # cluster into smaller ones, enumerated each on its own: the events to count are those of
        # the largest piece, not their product (30 visitors around the robot with one option each
        # are 30 independent choices, not 2^30 joint events).
        keep = nf
        pruned = sub.copy()
        piece = np.zeros(nt, dtype=np.int64)
        n_pieces = _pieces(pruned, piece)
        while keep > 1 and _largest_events(pruned, piece, n_pieces) > max_events:
            keep -= 1
            pruned = sub.copy()
            for i in range(nt):
                order = np.argsort(-sub[i])
                for j in range(keep, nf):
                    pruned[i, order[j]] = 0.0
            n_pieces = _pieces(pruned, piece)
        for g in range(n_pieces):
            rows = np.flatnonzero(piece == g)
            cols_used = np.zeros(nf, dtype=np.bool_)
            for a in range(rows.shape[0]):
                for j in range(nf):
                    if pruned[rows[a], j] > 0.0:
                        cols_used[j] = True
            cols = np.flatnonzero(cols_used)
            part = np.zeros((rows.shape[0], cols.shape[0]))
            q = np.empty(rows.shape[0])
            for a in range(rows.shape[0]):
                q[a] = miss[tracks[rows[a]]]
                for b in range(cols.shape[0]):
                    part[a, b] = pruned[rows[a], cols[b]]
            beta = _joint_betas_kernel(part, q)
            column = np.full(nf, -1, dtype=np.int64)
            for b in range(cols.shape[0]):
                column[cols[b]] = b
            row = np.full(nt, -1, dtype=np.int64)
            for a in range(rows.shape[0]):
                row[rows[a]] = a
                beta0[tracks[rows[a]]] = beta[a, 0]
            for p in range(P):
                if root[pair_track[p]] == r:
                    a = row[local[pair_track[p]]]
                    b = column[local[K + pair_feature[p]]]
                    if a >= 0:
                        pair_beta[p] = beta[a, b + 1] if b >= 0 else 0.0
    return pair_beta, beta0


def cluster_betas(
    pair_track: IntArray,
    pair_feature: IntArray,
    ratio: FloatArray,
    miss: FloatArray,
    num_features: int,
    max_events: int = 5000,
) -> tuple[FloatArray, FloatArray]:
    """Eq. 6-7 for all persons at once, cluster by cluster (numba).

    Persons and features linked by gated pairs ``(pair_track, pair_feature)`` with ``ratio``
    ``P_D p(z_j | x_i) / gamma`` form independent clusters; the joint events of different clusters
    factorise, so each cluster is enumerated on its own, which keeps 20-50 people fast. A cluster
    with more than ``max_events`` joint events loses its persons' weakest options first, until
    the largest of the pieces it falls into has at most ``max_events`` (or each person keeps its
    best option only); the pieces are enumerated each on its own. Returns
    the betas of the pairs ``(P,)`` and each person's ``beta_0`` ``(K,)`` (``miss`` ``(K,)`` is
    the weight of a person going undetected).
    """
    return _cluster_betas_kernel(
        np.ascontiguousarray(pair_track, dtype=np.int64),
        np.ascontiguousarray(pair_feature, dtype=np.int64),
        np.ascontiguousarray(ratio, dtype=np.float64),
        np.ascontiguousarray(miss, dtype=np.float64),
        int(num_features),
        int(max_events),
    )


def cluster_betas_reference(
    pair_track: IntArray, pair_feature: IntArray, ratio: FloatArray, miss: FloatArray, num_features: int
) -> tuple[FloatArray, FloatArray]:
    """:func:`cluster_betas` without clusters or pruning: all joint events of all persons at once."""
    dense = np.zeros((miss.shape[0], num_features))
    dense[pair_track, pair_feature] = ratio
    beta = joint_betas_reference(dense, miss)
    return beta[pair_track, pair_feature + 1], beta[:, 0]


# --- Eq. 9: sample weights ------------------------------------------------------------------------


def sample_weights_reference(
    likelihood: FloatArray,
    pair_track: IntArray,
    pair_beta: FloatArray,
    miss: FloatArray,
    beta0: FloatArray,
) -> FloatArray:
    """Eq. 9: ``w_{i,n} = alpha sum_j beta_ji p(z_j | x_{i,n})``, weights ``(K, N)`` summing to 1.

    Each hypothesis' likelihood is normalised over the person's samples first, so that the mixture
    is ``sum_j beta_ji p(x_i | z_j)``: ``likelihood`` ``(P, N)`` of the gated pairs, their ``beta``
    ``(P,)``; ``miss`` ``(K, N)`` is ``p(z_0 | x_{i,n}) = 1 - P_D(x_{i,n})`` with ``beta0`` ``(K,)``.
    """
    K, N = miss.shape
    w = np.zeros((K, N))
    ms = miss.sum(axis=1)
    w += np.where(ms[:, None] > 0.0, beta0[:, None] * miss / np.where(ms > 0.0, ms, 1.0)[:, None], 0.0)
    ls = likelihood.sum(axis=1)
    terms = np.where(
        ls[:, None] > 0.0, pair_beta[:, None] * likelihood / np.where(ls > 0.0, ls, 1.0)[:, None], 0.0
    )
    np.add.at(w, pair_track, terms)
    tot = w.sum(axis=1, keepdims=True)
    return np.where(tot > 0.0, w / np.where(tot > 0.0, tot, 1.0), 1.0 / N)


@numba.njit(cache=True)
def _sample_weights_kernel(
    likelihood: FloatArray, pair_track: IntArray, pair_beta: FloatArray, miss: FloatArray, beta0: FloatArray
) -> FloatArray:
    K, N = miss.shape
    w = np.zeros((K, N))
    for k in range(K):
        s = 0.0
        for n in range(N):
            s += miss[k, n]
        if s > 0.0:
            c = beta0[k] / s
            for n in range(N):
                w[k, n] += c * miss[k, n]
    for p in range(pair_track.shape[0]):
        s = 0.0
        for n in range(N):
            s += likelihood[p, n]
        if s > 0.0:
            c = pair_beta[p] / s
            k = pair_track[p]
            for n in range(N):
                w[k, n] += c * likelihood[p, n]
    for k in range(K):
        s = 0.0
        for n in range(N):
            s += w[k, n]
        for n in range(N):
            w[k, n] = w[k, n] / s if s > 0.0 else 1.0 / N
    return w


def sample_weights(
    likelihood: FloatArray, pair_track: IntArray, pair_beta: FloatArray, miss: FloatArray, beta0: FloatArray
) -> FloatArray:
    """Eq. 9: numba kernel of :func:`sample_weights_reference`."""
    return _sample_weights_kernel(
        np.ascontiguousarray(likelihood, dtype=np.float64).reshape(-1, miss.shape[1]),
        np.ascontiguousarray(pair_track, dtype=np.int64),
        np.ascontiguousarray(pair_beta, dtype=np.float64),
        np.ascontiguousarray(miss, dtype=np.float64),
        np.ascontiguousarray(beta0, dtype=np.float64),
    )
