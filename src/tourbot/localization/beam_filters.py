"""The entropy and novelty filters of Fox, Burgard, Thrun and Cremers (1998), Eq. 3-6.

Both decide, beam by beam, which range readings of a scan are integrated into the belief, so that
readings corrupted by people (or anything else not in the map) do not mislead the localizer. They
operate on any weighted set of hypotheses ``l`` with belief ``Bel(l)``: the samples of Monte Carlo
localization or the cells of a position probability grid. One implementation, used by both
estimators.

- Entropy filter (Eq. 3-4): ``H(l) = -sum_l Bel(l) log Bel(l)``; a beam ``s`` is used only if
  ``Delta H(l | s) = H(l) - H(l | s) >= 0``, i.e. only if integrating it alone into the current
  belief does not make the robot less certain. Each beam is judged against the same current belief
  (before any beam of this scan is integrated), so the result does not depend on beam order.
- Novelty filter (Eq. 5-6): ``p_n(d | l)`` is the probability that reading ``d`` is shorter than
  expected at ``l`` (from the sensor model, ``tourbot.maps.beam_model``); averaged over the belief,
  ``p_n(d) = sum_l p_n(d | l) Bel(l)``; a beam is dropped when ``p_n(d) > theta`` with
  ``theta = 0.99`` ("set to 0.99 in all experiments").
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.maps.beam_model import FAR_SIGMAS, shorter_than_expected_one
from tourbot.maps.raycast import RayCaster, beam_angles, rays_in_cells

# numba inlines the traversal into this file's cached kernels: it recompiles them only when
# this file changes (clear __pycache__/*.nbi after a change of traversal.py)
from tourbot.maps.traversal import cast_ray

__all__ = [
    "BeamFilter",
    "BeamFilterConfig",
    "belief_entropy",
    "entropy_change",
    "entropy_change_reference",
    "entropy_filter",
    "novelty_filter",
    "novelty_filter_cast",
    "novelty_probability",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]


class BeamFilter(enum.StrEnum):
    """Which beams a localizer integrates: all valid ones, or those passing a filter of the paper."""

    NONE = "none"
    ENTROPY = "entropy"
    NOVELTY = "novelty"


@dataclass(frozen=True)
class BeamFilterConfig:
    """Parameters of the filters.

    ``theta``: the novelty threshold, 0.99 in all experiments of Fox et al. 1998 (Sec. "Novelty
    filter"). ``entropy_tolerance``: a beam whose entropy change is within this many nats of zero
    counts as not increasing the entropy (Eq. 4 asks ``Delta H >= 0``; a beam that is equally
    likely everywhere changes nothing and rounding must not decide its fate).
    """

    theta: float = 0.99
    entropy_tolerance: float = 1e-9


def _normalized(weights: ArrayLike) -> FloatArray:
    w = np.asarray(weights, dtype=np.float64).ravel()
    total = w.sum()
    if not total > 0:
        raise ValueError("the belief's weights must have a positive sum")
    return w / total


def _group_ids(groups: ArrayLike | None, n: int) -> tuple[NDArray[np.int64], int]:
    if groups is None:
        return np.arange(n, dtype=np.int64), n
    g = np.asarray(groups).ravel()
    if g.shape[0] != n:
        raise ValueError(f"groups has {g.shape[0]} entries for {n} hypotheses")
    _, inverse = np.unique(g, return_inverse=True)
    ids = inverse.astype(np.int64).ravel()
    return ids, int(ids.max()) + 1 if n else 0


def belief_entropy(weights: ArrayLike, groups: ArrayLike | None = None) -> float:
    """Eq. 3: ``H = -sum Bel log Bel`` (nats) of a weighted set of hypotheses.

    With ``groups`` (one label per hypothesis), hypotheses with the same label are one location
    ``l`` whose belief is the sum of their weights: this is how a sample set is given the entropy of
    the belief it represents over a grid of locations (see :func:`entropy_filter`).
    """
    w = _normalized(weights)
    ids, n_groups = _group_ids(groups, w.shape[0])
    p = np.bincount(ids, weights=w, minlength=n_groups)
    p = p[p > 0]
    return float(-(p * np.log(p)).sum())


def entropy_change_reference(
    beam_lik: ArrayLike, weights: ArrayLike, groups: ArrayLike | None = None
) -> FloatArray:
    """Plain-numpy reference of :func:`entropy_change`: ``Delta H(l | s_b)`` for every beam, ``(B,)``.

    Beams with zero likelihood everywhere get ``-inf`` (they cannot be integrated).
    """
    lik = np.asarray(beam_lik, dtype=np.float64)
    w = _normalized(weights)
    ids, n_groups = _group_ids(groups, w.shape[0])
    prior = np.bincount(ids, weights=w, minlength=n_groups)
    h0 = -np.sum(prior[prior > 0] * np.log(prior[prior > 0]))
    out = np.empty(lik.shape[1])
    for b in range(lik.shape[1]):
        post = np.bincount(ids, weights=w * lik[:, b], minlength=n_groups)
        z = post.sum()
        if not z > 0:
            out[b] = -np.inf
            continue
        post = post / z
        post = post[post > 0]  # after dividing: a subnormal share can round to zero
        out[b] = h0 + np.sum(post * np.log(post))
    return out


def entropy_change(beam_lik: ArrayLike, weights: ArrayLike, groups: ArrayLike | None = None) -> FloatArray:
    """Eq. 4: ``Delta H(l | s_b) = H(l) - H(l | s_b)`` for every beam ``b``, ``(B,)`` (numba kernel).

    ``beam_lik[i, b]`` is ``p(s_b | l_i)`` (any positive scale per beam: it is normalized away),
    ``weights[i]`` is ``Bel(l_i)`` (normalized here). ``H(l | s_b)`` is the entropy of the belief
    after integrating beam ``b`` alone by Bayes' rule (Eq. 2). ``groups`` as in
    :func:`belief_entropy`. Beams with zero likelihood everywhere get ``-inf``.
    """
    lik = np.ascontiguousarray(beam_lik, dtype=np.float64)
    w = _normalized(weights)
    if lik.ndim != 2 or lik.shape[0] != w.shape[0]:
        raise ValueError(f"beam_lik must be (N, B) with N = {w.shape[0]}, got {lik.shape}")
    ids, n_groups = _group_ids(groups, w.shape[0])
    out = np.empty(lik.shape[1])
    _entropy_change_kernel(lik, w, ids, n_groups, out)
    return out


@numba.njit(cache=True)
def _entropy_change_kernel(
    lik: FloatArray, w: FloatArray, ids: NDArray[np.int64], n_groups: int, out: FloatArray
) -> None:
    n, n_beams = lik.shape
    prior = np.zeros(n_groups)
    for i in range(n):
        prior[ids[i]] += w[i]
    h0 = 0.0
    for g in range(n_groups):
        if prior[g] > 0.0:
            h0 -= prior[g] * math.log(prior[g])
    identity = n_groups == n
    if identity:
        for i in range(n):
            if ids[i] != i:
                identity = False
                break
    acc = np.zeros(n_groups)
    for b in range(n_beams):
        # H' = log Z - (1/Z) sum q log q with q = w * lik scaled by its largest value (the scale
        # cancels; scaling keeps q log q exact when the likelihoods are tiny or subnormal).
        if identity:
            top = 0.0
            for i in range(n):
                top = max(top, w[i] * lik[i, b])
            z = 0.0
            s = 0.0
            if top > 0.0:
                for i in range(n):
                    q = w[i] * lik[i, b] / top
                    if q > 0.0:
                        z += q
                        s += q * math.log(q)
        else:
            acc[:] = 0.0
            for i in range(n):
                acc[ids[i]] += w[i] * lik[i, b]
            top = 0.0
            for g in range(n_groups):
                top = max(top, acc[g])
            z = 0.0
            s = 0.0
            if top > 0.0:
                for g in range(n_groups):
                    q = acc[g] / top
                    if q > 0.0:
                        z += q
                        s += q * math.log(q)
        if z > 0.0:
            out[b] = h0 - (math.log(z) - s / z)
        else:
            out[b] = -math.inf


def entropy_filter(
    beam_lik: ArrayLike,
    weights: ArrayLike,
    groups: ArrayLike | None = None,
    tolerance: float = BeamFilterConfig.entropy_tolerance,
    informative_only: bool = False,
) -> BoolArray:
    """The entropy filter (Fox et al. 1998, Eq. 3-4): the beams whose integration does not raise the entropy.

    ``beam_lik (N, B)``: ``p(s_b | l_i)``; ``weights (N,)``: ``Bel(l_i)``. Returns the mask
    ``(B,)`` of beams with ``Delta H(l | s_b) >= -tolerance``.

    For a grid, each cell is a hypothesis. For a sample set, pass ``groups`` (e.g. the index of
    the cell of the paper's 15 cm x 2 deg grid holding each sample): with equal weights right after
    resampling, the entropy of the weights alone is at its maximum and *every* informative beam
    would lower it, whereas the entropy of the belief the samples represent is what Eq. 3 means.

    ``informative_only``: a beam whose likelihood is the same at every hypothesis of non-zero
    belief leaves the belief exactly as it is (``Delta H = 0``); Eq. 4 lets it through, but
    integrating it is a no-op, so with this flag it is reported as not integrated. This matters
    to a localizer that reads the integrated beams for more than the Bayes update: with a
    likelihood field, whose value is flat beyond a few ``sigma_hit`` of any obstacle, most beams
    that a visitor cut short are such no-ops, and MCL's recovery (how well the best sample
    explains the integrated beams) would otherwise take them for evidence of a kidnap.
    """
    keep = entropy_change(beam_lik, weights, groups) >= -tolerance
    if informative_only:
        keep &= ~_uninformative(beam_lik, weights)
    return keep


def _uninformative(beam_lik: ArrayLike, weights: ArrayLike) -> BoolArray:
    """``(B,)``: beams whose likelihood is equal at every hypothesis with non-zero weight."""
    lik = np.asarray(beam_lik, dtype=np.float64)
    held = lik[_normalized(weights) > 0]
    return np.asarray(held.max(axis=0) == held.min(axis=0), dtype=np.bool_)


def novelty_probability(p_shorter: ArrayLike, weights: ArrayLike) -> FloatArray:
    """Eq. 6: ``p_n(d_b) = sum_l p_n(d_b | l) Bel(l)`` for every beam, ``(B,)``."""
    p = np.asarray(p_shorter, dtype=np.float64)
    w = _normalized(weights)
    if p.ndim != 2 or p.shape[0] != w.shape[0]:
        raise ValueError(f"p_shorter must be (N, B) with N = {w.shape[0]}, got {p.shape}")
    return np.asarray(w @ p, dtype=np.float64)


def novelty_filter(
    p_shorter: ArrayLike, weights: ArrayLike, theta: float = BeamFilterConfig.theta
) -> BoolArray:
    """The novelty filter (Fox et al. 1998, Eq. 5-6): drop beams likely shorter than expected.

    ``p_shorter (N, B)``: ``p_n(d_b | l_i)`` of Eq. 5, the probability that reading ``b`` is
    shorter than expected at hypothesis ``i`` (``tourbot.maps.beam_model``); ``weights (N,)``:
    ``Bel(l_i)``. Returns the mask ``(B,)`` of kept beams, ``p_n(d_b) <= theta``.
    """
    return novelty_probability(p_shorter, weights) <= theta


def novelty_filter_cast(
    caster: RayCaster,
    laser_poses: ArrayLike,
    weights: ArrayLike,
    angles: ArrayLike,
    measured: ArrayLike,
    sigma_hit: float,
    max_range: float,
    theta: float = BeamFilterConfig.theta,
) -> BoolArray:
    """The novelty filter (Eq. 5-6) with its expected ranges ray cast on the way (one numba kernel).

    ``laser_poses (N, 3)``: the laser's world pose at each hypothesis, heaviest first;
    ``weights (N,)``: their ``Bel(l_i)``; ``angles (B,)`` and ``measured (B,)``: the beams (laser
    frame) and their readings. ``p_n(d_b | l_i)`` of Eq. 5 is
    :func:`tourbot.maps.beam_model.p_shorter_than_expected` at the range ``caster`` casts from
    ``l_i`` (float32 metres, as :meth:`RayCaster.cast`), with ``sigma_hit`` and ``max_range``.

    The same mask as :func:`novelty_filter` of those probabilities (which is its reference, see the
    tests), evaluated beam by beam in hypothesis order with an exit as soon as the beam is decided:
    kept once its partial sum plus the weight not yet seen is ``<= theta`` (each ``p_n <= 1``),
    dropped once the partial sum alone exceeds ``theta`` (each ``p_n >= 0``). A beam that the
    heaviest hypotheses explain costs one or two ray casts. A beam that is shorter than expected
    everywhere (a person) needs every hypothesis, but its rays stop early: once a ray has gone
    9 ``sigma_hit`` (plus two cells) beyond the reading without a hit, Eq. 5 is 1 to double
    precision whatever lies further.
    """
    w = _normalized(weights)
    n = w.shape[0]
    ox, oy, oth = rays_in_cells(caster.grid, np.asarray(laser_poses, dtype=np.float64).reshape(-1, 3))
    if ox.shape[0] != n:
        raise ValueError(f"{ox.shape[0]} laser poses for {n} weights")
    a = beam_angles(angles)
    z = np.ascontiguousarray(np.asarray(measured, dtype=np.float64))
    if z.shape != a.shape:
        raise ValueError(f"{z.shape[0]} readings for {a.shape[0]} beam angles")
    left = np.concatenate([np.cumsum(w[::-1])[::-1], [0.0]])  # weight of hypotheses i..n-1
    keep = np.empty(a.shape[0], dtype=np.bool_)
    rows, cols = caster.grid.shape
    _novelty_cast_kernel(
        caster.table,
        cols + 2,
        rows,
        cols,
        ox,
        oy,
        oth,
        w,
        left,
        a,
        z,
        caster.max_cells,
        float(caster.grid.resolution),
        caster.unknown_blocks,
        float(sigma_hit),
        float(max_range),
        float(theta),
        keep,
    )
    return keep


@numba.njit(cache=True)
def _novelty_cast_kernel(
    table: NDArray[np.uint8],
    width: int,
    rows: int,
    cols: int,
    ox: FloatArray,
    oy: FloatArray,
    oth: FloatArray,
    w: FloatArray,
    left: FloatArray,
    angles: FloatArray,
    measured: FloatArray,
    max_cells: float,
    scale: float,
    outside_blocks: bool,
    sigma_hit: float,
    max_range: float,
    theta: float,
    keep: BoolArray,
) -> None:
    n = ox.shape[0]
    ct = np.cos(oth)
    st = np.sin(oth)
    ca = np.cos(angles)
    sa = np.sin(angles)
    for b in range(angles.shape[0]):
        z = measured[b]
        if z >= max_range:  # no return: never shorter than expected
            keep[b] = theta >= 0.0
            continue
        # Beyond this many cells the expected range e exceeds z + FAR_SIGMAS sigma (and FAR_SIGMAS
        # sigma), where Eq. 5 is 1 to double precision: a ray that gets that far need not be cast
        # further.
        reach = min(max_cells, (max(z, 0.0) + FAR_SIGMAS * sigma_hit) / scale + 2.0)
        total = 0.0
        for i in range(n):
            # the ray of tourbot.maps.raycast.cast_rays_kernel, rounded to float32 metres as it is
            dx = ct[i] * ca[b] - st[i] * sa[b]
            dy = st[i] * ca[b] + ct[i] * sa[b]
            r = cast_ray(table, width, rows, cols, ox[i], oy[i], dx, dy, reach, outside_blocks)
            if r >= reach and reach < max_cells:
                p = 1.0
            else:
                p = shorter_than_expected_one(float(np.float32(scale * r)), z, sigma_hit, max_range)
            total += w[i] * p
            if total > theta or total + left[i + 1] <= theta:
                break
        keep[b] = total <= theta
