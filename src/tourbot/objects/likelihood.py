"""``log p(o | s, l)`` of Eq. 10 (Schulz and Burgard 2001) for every pose sample x state sample.

For each laser pose ``l`` (``P``), object state ``s`` (``S``) and beam ``i`` of the window
(``W``): the expected range ``\\hat d_i(s, l)`` is the static map's range lowered to the object's
edges in state ``s`` (:func:`tourbot.maps.objects.segment_ranges`), and
``log p(o | s, l) = sum_i log p(d_i | \\hat d_i(s, l))`` with the project's beam-model mixture
(:func:`tourbot.maps.beam_model.beam_probability_one`). The numba kernel fuses both so that no
``(P, S, W)`` array is built; :func:`log_likelihoods_reference` is the same from the numpy
references.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.maps.beam_model import BeamModel, beam_probability_one
from tourbot.maps.objects import nearest_edge, segment_ranges_reference

__all__ = ["log_likelihoods", "log_likelihoods_reference"]

FloatArray = NDArray[np.float64]

_FLOOR = 1e-300


def log_likelihoods_reference(
    poses: ArrayLike,
    angles: ArrayLike,
    segs: ArrayLike,
    base: ArrayLike,
    measured: ArrayLike,
    model: BeamModel,
    max_range: float,
) -> FloatArray:
    """``(P, S)`` log-likelihoods from the numpy references (the kernel's reference)."""
    expected = segment_ranges_reference(poses, angles, segs, base)
    p_, s_, w_ = expected.shape
    z = np.broadcast_to(np.asarray(measured, dtype=np.float64), (p_ * s_, w_))
    prob = model.probabilities_reference(expected.reshape(p_ * s_, w_), z, max_range)
    return np.asarray(np.log(np.maximum(prob, _FLOOR)).sum(axis=1).reshape(p_, s_), dtype=np.float64)


@numba.njit(cache=True)
def _log_likelihoods(
    x: FloatArray,
    y: FloatArray,
    theta: FloatArray,
    angles: FloatArray,
    segs: FloatArray,
    base: FloatArray,
    measured: FloatArray,
    w_hit: float,
    w_short: float,
    w_max: float,
    w_rand: float,
    sigma_hit: float,
    lambda_short: float,
    max_range: float,
    out: FloatArray,
) -> None:
    n, nb = base.shape
    ns = segs.shape[0]
    short_z = np.empty(nb)
    for b in range(nb):
        short_z[b] = w_short * lambda_short * math.exp(-lambda_short * measured[b])
    out[:, :] = 0.0
    for i in range(n):
        for b in range(nb):
            a = theta[i] + angles[b]
            dx = math.cos(a)
            dy = math.sin(a)
            z = measured[b]
            for k in range(ns):
                best = nearest_edge(segs, k, x[i], y[i], dx, dy, base[i, b])
                p = beam_probability_one(
                    float(np.float32(best)),
                    z,
                    short_z[b],
                    w_hit,
                    w_max,
                    w_rand,
                    sigma_hit,
                    lambda_short,
                    max_range,
                )
                out[i, k] += math.log(max(p, _FLOOR))


def log_likelihoods(
    poses: ArrayLike,
    angles: ArrayLike,
    segs: ArrayLike,
    base: ArrayLike,
    measured: ArrayLike,
    model: BeamModel,
    max_range: float,
) -> FloatArray:
    """``(P, S)``: ``log p(o | s, l)`` (Eq. 10) for laser ``poses`` ``(P, 3)``, beam ``angles``
    ``(W,)``, state edges ``segs`` ``(S, M, 4)``, static ranges ``base`` ``(P, W)`` and the
    window's readings ``measured`` ``(W,)``."""
    p = np.ascontiguousarray(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
    a = np.ascontiguousarray(np.asarray(angles, dtype=np.float64).ravel())
    s = np.ascontiguousarray(np.asarray(segs, dtype=np.float64))
    b = np.ascontiguousarray(np.asarray(base, dtype=np.float64))
    z = np.ascontiguousarray(np.asarray(measured, dtype=np.float64).ravel())
    out = np.zeros((p.shape[0], s.shape[0]))
    if out.size and a.size:
        wh, ws, wm, wr = model.weights
        _log_likelihoods(
            np.ascontiguousarray(p[:, 0]),
            np.ascontiguousarray(p[:, 1]),
            np.ascontiguousarray(p[:, 2]),
            a,
            s,
            b,
            z,
            wh,
            ws,
            wm,
            wr,
            model.sigma_hit,
            model.lambda_short,
            float(max_range),
            out,
        )
    return out
