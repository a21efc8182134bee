"""The beam model of range finders, on ranges cast in the map.

Probabilistic Robotics (Thrun, Burgard & Fox 2005), Section 6.3, Eq. 6.4-6.12 and Table 6.1: a
measured range ``z`` given the range ``z*`` expected from the map (cast by
:mod:`tourbot.maps.raycast`) is a mixture of four densities,

    p(z | z*) = z_hit p_hit + z_short p_short + z_max p_max + z_rand p_rand,

- ``p_hit``   (Eq. 6.4-6.6): ``N(z; z*, sigma_hit^2)`` truncated to ``[0, z_max]`` and renormalised;
- ``p_short`` (Eq. 6.7-6.9): ``lambda_short exp(-lambda_short z)`` on ``[0, z*]``, renormalised;
- ``p_max``   (Eq. 6.10): a point mass at ``z_max`` (a reading ``>= z_max``: no return);
- ``p_rand``  (Eq. 6.11): uniform ``1 / z_max`` on ``[0, z_max)``.

The weights are divided by their sum, so the mixture integrates to one as Eq. 6.12 requires.

Fox, Burgard, Thrun & Cremers 1998 ("Position estimation for mobile robots in dynamic
environments"), Eq. 5: the novelty filter needs ``p_n(d | l) = 1 - sum_{j<i} p(d_j | l)``, the
probability that a reading ``d`` is *shorter than expected* when the sensor detects the next
obstacle of the map, ``p(. | l)`` being the hit distribution around the expected range. Its
continuous form is the survival function of ``p_hit``: :func:`p_shorter_than_expected`. Eq. 6
(averaging over the belief) is the localization part's job.

Each function has a numpy form (the reference) and the batched mixture runs as a numba kernel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr

from tourbot.errors import TourbotError

__all__ = [
    "FAR_SIGMAS",
    "BeamModel",
    "BeamModelError",
    "beam_probabilities_kernel",
    "beam_probability_one",
    "p_hit",
    "p_max",
    "p_rand",
    "p_short",
    "p_shorter_than_expected",
    "shorter_than_expected_kernel",
    "shorter_than_expected_one",
]

FloatArray = NDArray[np.float64]


class BeamModelError(TourbotError):
    """Beam-model parameters or inputs that make no sense."""


def _arrays(expected: ArrayLike, measured: ArrayLike) -> tuple[FloatArray, FloatArray]:
    e = np.asarray(expected, dtype=np.float64)
    z = np.asarray(measured, dtype=np.float64)
    return e, np.broadcast_to(z, np.broadcast_shapes(e.shape, z.shape))


def p_hit(expected: ArrayLike, measured: ArrayLike, sigma_hit: float, max_range: float) -> FloatArray:
    """Eq. 6.4-6.6: Gaussian around the expected range, truncated to ``[0, max_range]``."""
    e, z = _arrays(expected, measured)
    mass = ndtr((max_range - e) / sigma_hit) - ndtr(-e / sigma_hit)
    dens = np.exp(-0.5 * ((z - e) / sigma_hit) ** 2) / (sigma_hit * math.sqrt(2.0 * math.pi))
    ok = (z >= 0.0) & (z <= max_range) & (mass > 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.asarray(np.where(ok, dens / mass, 0.0), dtype=np.float64)


def p_short(expected: ArrayLike, measured: ArrayLike, lambda_short: float) -> FloatArray:
    """Eq. 6.7-6.9: exponential on ``[0, expected]`` (unexpected objects in front), renormalised."""
    e, z = _arrays(expected, measured)
    norm = -np.expm1(-lambda_short * e)
    ok = (z >= 0.0) & (z <= e) & (norm > 0.0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return np.asarray(
            np.where(ok, lambda_short * np.exp(-lambda_short * z) / norm, 0.0), dtype=np.float64
        )


def p_max(measured: ArrayLike, max_range: float) -> FloatArray:
    """Eq. 6.10: 1 for a reading at (or beyond) the maximum range, 0 otherwise."""
    z = np.asarray(measured, dtype=np.float64)
    return np.asarray(z >= max_range, dtype=np.float64)


def p_rand(measured: ArrayLike, max_range: float) -> FloatArray:
    """Eq. 6.11: uniform ``1 / max_range`` on ``[0, max_range)``."""
    z = np.asarray(measured, dtype=np.float64)
    return np.asarray(np.where((z >= 0.0) & (z < max_range), 1.0 / max_range, 0.0), dtype=np.float64)


def p_shorter_than_expected(
    expected: ArrayLike, measured: ArrayLike, sigma_hit: float, max_range: float
) -> FloatArray:
    """Fox et al. 1998 Eq. 5: probability that ``measured`` is shorter than the map explains.

    ``1 - P(hit reading < measured)`` for the truncated hit distribution around ``expected``,
    i.e. ``P(hit reading >= measured)``; 0 for readings at or beyond ``max_range``, 1 for
    readings ``<= 0``. The novelty filter drops a beam when the belief-weighted average of this
    (Eq. 6) exceeds its threshold (0.99 in the paper).
    """
    e, z = _arrays(expected, measured)
    lo = ndtr(-e / sigma_hit)
    hi = ndtr((max_range - e) / sigma_hit)
    with np.errstate(divide="ignore", invalid="ignore"):
        cdf = (ndtr((np.clip(z, 0.0, max_range) - e) / sigma_hit) - lo) / (hi - lo)
    sf = np.clip(1.0 - np.nan_to_num(cdf, nan=0.0), 0.0, 1.0)
    return np.asarray(np.where(z >= max_range, 0.0, sf), dtype=np.float64)


FAR_SIGMAS = 9.0  # standard deviations beyond which the normal CDF is 0 or 1 to double precision (~1e-19)


@numba.njit(cache=True, inline="always")
def _ndtr(x: float) -> float:
    if x > FAR_SIGMAS:
        return 1.0
    if x < -FAR_SIGMAS:
        return 0.0
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


@numba.njit(cache=True, inline="always")
def beam_probability_one(
    e: float,
    z: float,
    short_z: float,
    w_hit: float,
    w_max: float,
    w_rand: float,
    sigma_hit: float,
    lambda_short: float,
    max_range: float,
) -> float:
    """``p(z | e)`` of one reading, the Eq. 6.12 mixture (weights pre-normalised); ``short_z`` is
    the reading's own factor of ``p_short``, ``w_short lambda_short exp(-lambda_short z)``."""
    if z < 0.0:
        return 0.0
    p = w_max if z >= max_range else w_rand * (1.0 / max_range)
    if z <= max_range:
        inv_s = 1.0 / sigma_hit
        c_gauss = 1.0 / (sigma_hit * math.sqrt(2.0 * math.pi))
        u = (z - e) * inv_s
        if abs(u) < 40.0:  # beyond, exp(-u^2 / 2) is 0 in double precision
            mass = _ndtr((max_range - e) * inv_s) - _ndtr(-e * inv_s)
            if mass > 0.0:
                p += w_hit * c_gauss * math.exp(-0.5 * u * u) / mass
    if z <= e:
        norm = -math.expm1(-lambda_short * e)
        if norm > 0.0:
            p += short_z / norm
    return p


@numba.njit(cache=True)
def beam_probabilities_kernel(
    expected: NDArray[np.float32],
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
    """``out[i, b] = p(measured[b] | expected[i, b])``, the Eq. 6.12 mixture (weights pre-normalised)."""
    n, nb = expected.shape
    # the reading's own factor of p_short, once per beam rather than per pose
    short_z = np.empty(nb)
    for b in range(nb):
        short_z[b] = w_short * lambda_short * math.exp(-lambda_short * measured[b])
    for i in range(n):
        for b in range(nb):
            out[i, b] = beam_probability_one(
                float(expected[i, b]),
                measured[b],
                short_z[b],
                w_hit,
                w_max,
                w_rand,
                sigma_hit,
                lambda_short,
                max_range,
            )


@numba.njit(cache=True, inline="always")
def shorter_than_expected_one(e: float, z: float, sigma_hit: float, max_range: float) -> float:
    """:func:`p_shorter_than_expected` of one reading ``z`` at expected range ``e`` (numba)."""
    if z >= max_range:
        return 0.0
    lo = _ndtr(-e / sigma_hit)
    hi = _ndtr((max_range - e) / sigma_hit)
    if hi - lo <= 0.0:
        return 0.0
    zc = min(max(z, 0.0), max_range)
    sf = 1.0 - (_ndtr((zc - e) / sigma_hit) - lo) / (hi - lo)
    return min(max(sf, 0.0), 1.0)


@numba.njit(cache=True)
def shorter_than_expected_kernel(
    expected: NDArray[np.float32], measured: FloatArray, sigma_hit: float, max_range: float, out: FloatArray
) -> None:
    """Batched :func:`p_shorter_than_expected`: ``out[i, b]`` for ``expected[i, b]``, ``measured[b]``."""
    n, nb = expected.shape
    for i in range(n):
        for b in range(nb):
            out[i, b] = shorter_than_expected_one(float(expected[i, b]), measured[b], sigma_hit, max_range)


@dataclass(frozen=True)
class BeamModel:
    """Parameters of the beam model (Probabilistic Robotics Table 6.1, Eq. 6.12).

    Defaults are Nav2 AMCL's beam-model defaults (``z_hit`` 0.95, ``z_short`` 0.1, ``z_max``
    0.05, ``z_rand`` 0.05, ``sigma_hit`` 0.2 m, ``lambda_short`` 0.1 /m); the book leaves them to
    be learned (Table 6.2). The weights are normalised to sum to one when used.
    """

    z_hit: float = 0.95
    z_short: float = 0.1
    z_max: float = 0.05
    z_rand: float = 0.05
    sigma_hit: float = 0.2
    lambda_short: float = 0.1

    def __post_init__(self) -> None:
        weights = (self.z_hit, self.z_short, self.z_max, self.z_rand)
        if min(weights) < 0 or sum(weights) <= 0:
            raise BeamModelError(f"beam model weights must be >= 0 with a positive sum, got {weights}")
        if not self.sigma_hit > 0 or not self.lambda_short > 0:
            raise BeamModelError("beam model: sigma_hit and lambda_short must be positive")

    @property
    def weights(self) -> tuple[float, float, float, float]:
        """``(z_hit, z_short, z_max, z_rand)`` divided by their sum (Eq. 6.12)."""
        s = self.z_hit + self.z_short + self.z_max + self.z_rand
        return (self.z_hit / s, self.z_short / s, self.z_max / s, self.z_rand / s)

    def probabilities_reference(
        self, expected: ArrayLike, measured: ArrayLike, max_range: float
    ) -> FloatArray:
        """The mixture from the numpy component functions (the kernel's reference)."""
        wh, ws, wm, wr = self.weights
        return (
            wh * p_hit(expected, measured, self.sigma_hit, max_range)
            + ws * p_short(expected, measured, self.lambda_short)
            + wm * p_max(_arrays(expected, measured)[1], max_range)
            + wr * p_rand(_arrays(expected, measured)[1], max_range)
        )

    def probabilities(self, expected: ArrayLike, measured: ArrayLike, max_range: float) -> FloatArray:
        """``p(z_b | z*_ib)`` for expected ranges ``(N, B)`` and one scan ``measured (B,)``."""
        e = np.ascontiguousarray(np.asarray(expected, dtype=np.float32))
        z = np.ascontiguousarray(np.asarray(measured, dtype=np.float64))
        if e.ndim != 2 or z.shape != (e.shape[1],):
            raise BeamModelError(f"expected must be (N, B) and measured (B,), got {e.shape} and {z.shape}")
        out = np.empty(e.shape, dtype=np.float64)
        if out.size:
            wh, ws, wm, wr = self.weights
            beam_probabilities_kernel(
                e, z, wh, ws, wm, wr, self.sigma_hit, self.lambda_short, float(max_range), out
            )
        return out

    def log_likelihood(
        self, expected: ArrayLike, measured: ArrayLike, max_range: float, beam_mask: ArrayLike | None = None
    ) -> FloatArray:
        """``sum_b log p(z_b | z*_ib)`` over the beams in ``beam_mask`` (all by default), ``(N,)``."""
        p = self.probabilities(expected, measured, max_range)
        logp = np.log(np.maximum(p, 1e-300))
        if beam_mask is not None:
            logp = logp[:, np.asarray(beam_mask, dtype=bool)]
        return np.asarray(logp.sum(axis=1), dtype=np.float64)

    def prob_shorter(self, expected: ArrayLike, measured: ArrayLike, max_range: float) -> FloatArray:
        """Fox et al. 1998 Eq. 5 per pose and beam, ``(N, B)`` (see :func:`p_shorter_than_expected`)."""
        e = np.ascontiguousarray(np.asarray(expected, dtype=np.float32))
        z = np.ascontiguousarray(np.asarray(measured, dtype=np.float64))
        if e.ndim != 2 or z.shape != (e.shape[1],):
            raise BeamModelError(f"expected must be (N, B) and measured (B,), got {e.shape} and {z.shape}")
        out = np.empty(e.shape, dtype=np.float64)
        if out.size:
            shorter_than_expected_kernel(e, z, self.sigma_hit, float(max_range), out)
        return out
