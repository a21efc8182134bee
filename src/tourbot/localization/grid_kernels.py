"""The numba kernels of grid Markov localization, each with its plain-numpy reference.

The belief of :mod:`tourbot.localization.grid_markov` lives on a lattice of poses: heading layer
``k`` (``n_theta`` of them) times free position cell ``f`` (``n_free`` of them), flattened as
``pose = k * n_free + f``. Only the poses with non-negligible belief are held, as an index array
and a weight array (the "selective update" that makes a 15 cm x 2 deg grid tractable, Fox et al.
1998, Sec. "Markov localization").

The expected range of beam ``b`` from pose ``(k, f)`` is a table lookup,
``table[laser_cell(k, f), beam_cols[k, b]]`` (a ``uint16`` range bin); the per-scan tables
``ll[b, bin]`` and ``ps[b, bin]`` hold the log-likelihood ``log p(s_b | l)`` and the probability
``p_n(s_b | l)`` that reading ``s_b`` is shorter than expected (Eq. 5) for every expected-range
bin. So a per-beam evaluation is two lookups and no transcendental function.

Kernels (numba) and their references (numpy):

- :func:`scan_log_likelihood` / :func:`scan_log_likelihood_reference`: ``sum_b log p(s_b | l)``
  over the used beams for every held pose, the log of the product of Eq. 2.
- :func:`filter_statistics` / :func:`filter_statistics_reference`: in one pass over the belief,
  the entropy change ``Delta H(l | s_b)`` of Eq. 3-4 and the novelty probability ``p_n(s_b)`` of
  Eq. 6 for every beam, without materializing the ``(N, B)`` arrays that
  :mod:`tourbot.localization.beam_filters` takes (tests compare the two).
- :func:`motion_scatter` / :func:`motion_scatter_reference`: Eq. 1, each held pose's mass moved
  by its heading layer's displacement kernel onto a dense scratch array, listing touched poses.
- :func:`collect` / :func:`collect_reference`: read the touched poses back, drop negligible ones
  (below ``ratio`` times the largest) and clear the scratch array.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "collect",
    "collect_reference",
    "filter_statistics",
    "filter_statistics_reference",
    "laser_cells_reference",
    "motion_scatter",
    "motion_scatter_reference",
    "scan_log_likelihood",
    "scan_log_likelihood_reference",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BinArray = NDArray[np.uint16]


# ------------------------------------------------------------------------------------------------
# laser cell: the free cell the laser sits in (the robot's cell shifted by the laser offset)
# ------------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _laser_cell(k: int, f: int, free_rc: IntArray, free_index: IntArray, laser_shift: IntArray) -> int:
    r = free_rc[f, 0] + laser_shift[k, 0]
    c = free_rc[f, 1] + laser_shift[k, 1]
    if 0 <= r < free_index.shape[0] and 0 <= c < free_index.shape[1]:
        g = free_index[r, c]
        if g >= 0:
            return int(g)
    return f


def laser_cells_reference(
    pose_idx: IntArray, n_free: int, free_rc: IntArray, free_index: IntArray, laser_shift: IntArray
) -> tuple[IntArray, IntArray]:
    """Heading layer ``(N,)`` and free cell of the laser ``(N,)`` for every pose (numpy)."""
    k = pose_idx // n_free
    f = pose_idx % n_free
    r = free_rc[f, 0] + laser_shift[k, 0]
    c = free_rc[f, 1] + laser_shift[k, 1]
    inside = (r >= 0) & (r < free_index.shape[0]) & (c >= 0) & (c < free_index.shape[1])
    g = np.full(f.shape, -1, dtype=np.int64)
    g[inside] = free_index[r[inside], c[inside]]
    return k, np.where(g >= 0, g, f)


def _beam_bins_reference(
    pose_idx: IntArray,
    n_free: int,
    free_rc: IntArray,
    free_index: IntArray,
    laser_shift: IntArray,
    table: BinArray,
    beam_cols: IntArray,
) -> IntArray:
    """The expected-range bin of every beam from every pose, ``(N, B)`` (numpy)."""
    k, g = laser_cells_reference(pose_idx, n_free, free_rc, free_index, laser_shift)
    return table[g[:, None], beam_cols[k]].astype(np.int64)


# ------------------------------------------------------------------------------------------------
# sensor update: log p(s | l) = sum over used beams of log p(s_b | l)   (Eq. 2)
# ------------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _scan_log_likelihood_kernel(
    pose_idx: IntArray,
    n_free: int,
    free_rc: IntArray,
    free_index: IntArray,
    laser_shift: IntArray,
    table: BinArray,
    beam_cols: IntArray,
    beams: IntArray,
    ll: NDArray[np.float32],
    out: FloatArray,
) -> None:
    for i in range(pose_idx.shape[0]):
        p = pose_idx[i]
        k = p // n_free
        f = p - k * n_free
        g = _laser_cell(k, f, free_rc, free_index, laser_shift)
        acc = 0.0
        for j in range(beams.shape[0]):
            b = beams[j]
            acc += ll[b, table[g, beam_cols[k, b]]]
        out[i] = acc


def scan_log_likelihood(
    pose_idx: IntArray,
    n_free: int,
    free_rc: IntArray,
    free_index: IntArray,
    laser_shift: IntArray,
    table: BinArray,
    beam_cols: IntArray,
    used: NDArray[np.bool_],
    ll: FloatArray,
) -> FloatArray:
    """``log p(s | l) = sum_{b used} ll[b, bin(l, b)]`` for every pose, ``(N,)`` (numba kernel).

    The log of the product of independent beam likelihoods that Eq. 2 multiplies the belief with.
    The look-up table is read in float32 (sums are float64).
    """
    out = np.empty(pose_idx.shape[0], dtype=np.float64)
    beams = np.flatnonzero(used).astype(np.int64)
    ll32 = np.ascontiguousarray(ll, dtype=np.float32)  # half the cache footprint of the look-ups
    _scan_log_likelihood_kernel(
        pose_idx, n_free, free_rc, free_index, laser_shift, table, beam_cols, beams, ll32, out
    )
    return out


def scan_log_likelihood_reference(
    pose_idx: IntArray,
    n_free: int,
    free_rc: IntArray,
    free_index: IntArray,
    laser_shift: IntArray,
    table: BinArray,
    beam_cols: IntArray,
    used: NDArray[np.bool_],
    ll: FloatArray,
) -> FloatArray:
    """Plain-numpy reference of :func:`scan_log_likelihood`."""
    bins = _beam_bins_reference(pose_idx, n_free, free_rc, free_index, laser_shift, table, beam_cols)
    beams = np.flatnonzero(used)
    vals = ll[beams[None, :], bins[:, beams]]
    return np.asarray(vals.sum(axis=1), dtype=np.float64)


# ------------------------------------------------------------------------------------------------
# beam filters: entropy change (Eq. 3-4) and novelty probability (Eq. 6), streamed over the belief
# ------------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _filter_statistics_kernel(
    pose_idx: IntArray,
    w: FloatArray,
    mult: FloatArray,
    n_free: int,
    free_rc: IntArray,
    free_index: IntArray,
    laser_shift: IntArray,
    table: BinArray,
    beam_cols: IntArray,
    beams: IntArray,
    tab: NDArray[np.float32],
    z: FloatArray,
    s: FloatArray,
    pn: FloatArray,
) -> float:
    # tab[b, bin] = (p, p log p, p_n, 0) with p = p(s_b | l) relative to the beam's best bin: one
    # cache line per look-up.
    h0 = 0.0
    for i in range(pose_idx.shape[0]):
        wi = w[i]
        mi = mult[i]
        if wi <= 0.0 or mi <= 0.0:
            continue
        mw = mi * wi
        logw = math.log(wi)
        h0 -= mw * logw
        p = pose_idx[i]
        k = p // n_free
        f = p - k * n_free
        g = _laser_cell(k, f, free_rc, free_index, laser_shift)
        for j in range(beams.shape[0]):
            b = beams[j]
            d = table[g, beam_cols[k, b]]
            lik = tab[b, d, 0]
            z[b] += mw * lik
            s[b] += mw * (lik * logw + tab[b, d, 1])
            pn[b] += mw * tab[b, d, 2]
    return h0


def filter_statistics(
    pose_idx: IntArray,
    w: FloatArray,
    mult: FloatArray,
    n_free: int,
    free_rc: IntArray,
    free_index: IntArray,
    laser_shift: IntArray,
    table: BinArray,
    beam_cols: IntArray,
    beams: IntArray,
    ll: FloatArray,
    ps: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Entropy change ``Delta H(l | s_b)`` (Eq. 3-4) and ``p_n(s_b)`` (Eq. 6) for beams ``beams``.

    ``w`` is the belief ``Bel(l)`` of each listed pose and ``mult`` how many poses of that belief
    it stands for (1 for a held pose; more for a sample of the uniform mixture), so the belief is
    ``sum mult * w`` (normalized here). Returns two ``(B,)`` arrays
    (NaN for beams not listed). One pass: with ``q_l = Bel(l) p(s_b | l)`` and ``Z = sum q_l``,
    the entropy after integrating beam ``b`` alone is ``H(l | s_b) = log Z - (1/Z) sum q_l log q_l``
    (the scale of ``p(s_b | l)`` cancels, so it is taken relative to the beam's best bin). Beams
    whose likelihood is zero everywhere get ``-inf`` (never integrated), as in
    :func:`tourbot.localization.beam_filters.entropy_change`.
    """
    n_beams = ll.shape[0]
    m = np.ascontiguousarray(mult, dtype=np.float64)
    wn = np.ascontiguousarray(w, dtype=np.float64) / float(np.sum(m * w))
    lq = ll - np.max(ll, axis=1)[:, None]
    lik = np.exp(lq)
    tab = np.zeros((n_beams, ll.shape[1], 4), dtype=np.float32)
    tab[:, :, 0] = lik
    tab[:, :, 1] = np.where(lik > 0.0, lik * lq, 0.0)
    tab[:, :, 2] = ps
    z = np.zeros(n_beams)
    s = np.zeros(n_beams)
    pn = np.zeros(n_beams)
    h0 = _filter_statistics_kernel(
        pose_idx, wn, m, n_free, free_rc, free_index, laser_shift, table, beam_cols,
        np.ascontiguousarray(beams, dtype=np.int64), tab, z, s, pn,
    )  # fmt: skip
    dh = np.full(n_beams, np.nan)
    pnov = np.full(n_beams, np.nan)
    zb = z[beams]
    with np.errstate(divide="ignore", invalid="ignore"):
        dh[beams] = np.where(zb > 0.0, h0 - (np.log(zb) - s[beams] / zb), -np.inf)
    pnov[beams] = pn[beams]
    return dh, pnov


def filter_statistics_reference(
    pose_idx: IntArray,
    w: FloatArray,
    mult: IntArray,
    n_free: int,
    free_rc: IntArray,
    free_index: IntArray,
    laser_shift: IntArray,
    table: BinArray,
    beam_cols: IntArray,
    beams: IntArray,
    ll: FloatArray,
    ps: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Plain-numpy reference of :func:`filter_statistics`, through the project's beam filters.

    Repeats each pose ``mult`` times (integer multiplicities here), materializes ``p(s_b | l)``
    and ``p_n(s_b | l)`` as ``(N, B)`` arrays and hands them to
    :func:`tourbot.localization.beam_filters.entropy_change_reference` and
    :func:`~tourbot.localization.beam_filters.novelty_probability`.
    """
    from tourbot.localization.beam_filters import entropy_change_reference, novelty_probability

    reps = np.asarray(mult, dtype=np.int64)
    pose_idx = np.repeat(pose_idx, reps)
    w = np.repeat(np.asarray(w, dtype=np.float64), reps)
    bins = _beam_bins_reference(pose_idx, n_free, free_rc, free_index, laser_shift, table, beam_cols)
    b = np.asarray(beams, dtype=np.int64)
    lik = np.exp(ll[b[None, :], bins[:, b]] - np.max(ll[b], axis=1)[None, :])
    pshort = ps[b[None, :], bins[:, b]]
    dh = np.full(ll.shape[0], np.nan)
    pnov = np.full(ll.shape[0], np.nan)
    if b.size:
        dh[b] = entropy_change_reference(lik, w)
        pnov[b] = novelty_probability(pshort, w)
    return dh, pnov


# ------------------------------------------------------------------------------------------------
# motion update: Bel(l) <- sum_l' p(l | l', a) Bel(l')   (Eq. 1)
# ------------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _motion_scatter_kernel(
    src_idx: IntArray,
    src_w: FloatArray,
    n_theta: int,
    n_free: int,
    free_rc: IntArray,
    free_index: IntArray,
    weights: FloatArray,
    offsets: IntArray,
    dense: FloatArray,
    touched: IntArray,
) -> tuple[IntArray, int]:
    rows, cols = free_index.shape
    kt, kr, kc = weights.shape[1], weights.shape[2], weights.shape[3]
    n_touched = 0
    for i in range(src_idx.shape[0]):
        m = src_w[i]
        if m <= 0.0:
            continue
        p = src_idx[i]
        k = p // n_free
        f = p - k * n_free
        r0 = free_rc[f, 0] + offsets[k, 1]
        c0 = free_rc[f, 1] + offsets[k, 2]
        for a in range(kt):
            kk = (k + offsets[k, 0] + a) % n_theta
            base = kk * n_free
            for b in range(kr):
                r = r0 + b
                if r < 0 or r >= rows:
                    continue
                for c in range(kc):
                    wt = weights[k, a, b, c]
                    if wt <= 0.0:
                        continue
                    cc = c0 + c
                    if cc < 0 or cc >= cols:
                        continue
                    g = free_index[r, cc]
                    if g < 0:
                        continue  # the robot cannot end up inside an obstacle: mass dropped
                    add = m * wt
                    if add <= 0.0:
                        continue
                    t = base + g
                    if dense[t] == 0.0:
                        if n_touched == touched.shape[0]:
                            grown = np.empty(2 * touched.shape[0] + 16, dtype=np.int64)
                            grown[:n_touched] = touched[:n_touched]
                            touched = grown
                        touched[n_touched] = t
                        n_touched += 1
                    dense[t] += add
    return touched, n_touched


def motion_scatter(
    src_idx: IntArray,
    src_w: FloatArray,
    n_theta: int,
    n_free: int,
    free_rc: IntArray,
    free_index: IntArray,
    weights: FloatArray,
    offsets: IntArray,
    dense: FloatArray,
) -> IntArray:
    """Eq. 1 on the held poses: scatter their mass into ``dense`` (numba kernel).

    ``weights (n_theta, Kt, Kr, Kc)`` is the displacement kernel of each heading layer (the
    convolution form of the motion model, zero-padded to a common shape) and ``offsets
    (n_theta, 3)`` the (heading, row, column) offset of its first entry: mass ``w`` at ``(k, r, c)``
    sends ``w * weights[k, a, b, c]`` to ``(k + offsets[k, 0] + a mod n_theta, r + offsets[k, 1] + b,
    c + offsets[k, 2] + c)``, dropped where that cell is outside the map or not free. ``dense``
    (``n_theta * n_free``, all zero on entry) receives the result; returns the touched poses, each
    once.
    """
    touched = np.empty(max(16, 4 * src_idx.shape[0]), dtype=np.int64)
    touched, n = _motion_scatter_kernel(
        src_idx, src_w, n_theta, n_free, free_rc, free_index, weights, offsets, dense, touched
    )
    return touched[:n]


def motion_scatter_reference(
    src_idx: IntArray,
    src_w: FloatArray,
    n_theta: int,
    n_free: int,
    free_rc: IntArray,
    free_index: IntArray,
    weights: FloatArray,
    offsets: IntArray,
) -> FloatArray:
    """Plain-numpy reference of :func:`motion_scatter`: the dense result ``(n_theta * n_free,)``."""
    out = np.zeros(n_theta * n_free)
    rows, cols = free_index.shape
    k = src_idx // n_free
    f = src_idx % n_free
    for a in range(weights.shape[1]):
        for b in range(weights.shape[2]):
            for c in range(weights.shape[3]):
                wt = weights[k, a, b, c]
                kk = (k + offsets[k, 0] + a) % n_theta
                r = free_rc[f, 0] + offsets[k, 1] + b
                cc = free_rc[f, 1] + offsets[k, 2] + c
                ok = (wt > 0) & (r >= 0) & (r < rows) & (cc >= 0) & (cc < cols)
                g = np.full(k.shape, -1, dtype=np.int64)
                g[ok] = free_index[r[ok], cc[ok]]
                ok &= g >= 0
                np.add.at(out, kk[ok] * n_free + g[ok], src_w[ok] * wt[ok])
    return out


# ------------------------------------------------------------------------------------------------
# selective update: keep the poses with non-negligible belief
# ------------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _collect_kernel(
    touched: IntArray, dense: FloatArray, ratio: float, out_idx: IntArray, out_w: FloatArray
) -> int:
    top = 0.0
    for i in range(touched.shape[0]):
        v = dense[touched[i]]
        top = max(top, v)
    cut = ratio * top
    n = 0
    for i in range(touched.shape[0]):
        t = touched[i]
        v = dense[t]
        dense[t] = 0.0
        if v > 0.0 and v >= cut:
            out_idx[n] = t
            out_w[n] = v
            n += 1
    return n


def collect(touched: IntArray, dense: FloatArray, ratio: float) -> tuple[IntArray, FloatArray]:
    """The touched poses whose mass is at least ``ratio`` times the largest, and their mass.

    Clears ``dense`` at every touched pose (numba kernel); the result is in ``touched`` order.
    """
    out_idx = np.empty(touched.shape[0], dtype=np.int64)
    out_w = np.empty(touched.shape[0], dtype=np.float64)
    n = _collect_kernel(touched, dense, float(ratio), out_idx, out_w)
    return out_idx[:n], out_w[:n]


def collect_reference(dense: FloatArray, ratio: float) -> tuple[IntArray, FloatArray]:
    """Plain-numpy reference of :func:`collect` on a dense array (result sorted by pose index)."""
    top = float(dense.max()) if dense.size else 0.0
    keep = np.flatnonzero((dense > 0.0) & (dense >= ratio * top))
    return keep.astype(np.int64), dense[keep].astype(np.float64)
