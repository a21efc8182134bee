"""The odometry motion model p(l | l', a) of Markov localization (Fox et al. 1998, Eq. 1).

Fox et al. only say that "the errors of the odometry [are] normally distributed". We use the
standard odometry model of Thrun, Burgard and Fox, *Probabilistic Robotics* (2005), Sec. 5.4: the
motion ``a`` between two odometry readings is decomposed into a first rotation ``rot1``, a
translation ``trans`` and a second rotation ``rot2``; each is perturbed by zero-mean Gaussian noise
whose variance grows with the size of the motion (Table 5.6)::

    var(rot1)  = alpha1 * rot1**2 + alpha2 * trans**2
    var(trans) = alpha3 * trans**2 + alpha4 * (rot1**2 + rot2**2)
    var(rot2)  = alpha1 * rot2**2 + alpha2 * trans**2

Two forms are provided, one per representation of the belief:

- the *sampling form* for particles (:meth:`OdometryMotionModel.sample`): a numba kernel with a
  plain-numpy reference (:func:`sample_reference`) fed the same standard-normal draws;
- the *convolution form* for grids (:meth:`OdometryMotionModel.kernel`): the Gaussian displacement
  kernel, on the grid's cells, that Eq. 1 convolves the belief with, for one heading layer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.geometry import relative, wrap_angle

__all__ = [
    "MotionKernel",
    "OdometryMotionModel",
    "decompose",
    "sample_reference",
    "sample_with_noise",
]

FloatArray = NDArray[np.float64]

# Below this translation (metres) the direction of travel is meaningless: the motion is a turn in place.
_MIN_TRANSLATION = 1e-6


def decompose(odom_prev: ArrayLike, odom_now: ArrayLike) -> tuple[float, float, float]:
    """The motion between two odometry poses as ``(rot1, trans, rot2)`` (Probabilistic Robotics, Table 5.6).

    Backward motion is kept backward: when the direction of travel is more than 90 degrees from
    the heading, ``trans`` is negative and ``rot1`` is the (small) turn before reversing, so a
    robot that backs up is not modelled as turning around twice.
    """
    d = relative(np.asarray(odom_prev, np.float64), np.asarray(odom_now, np.float64))
    dx, dy, dth = float(d[0]), float(d[1]), float(d[2])
    trans = math.hypot(dx, dy)
    if trans < _MIN_TRANSLATION:
        return 0.0, 0.0, float(wrap_angle(dth))
    rot1 = math.atan2(dy, dx)
    if abs(rot1) > math.pi / 2:
        rot1 = float(wrap_angle(rot1 - math.pi))
        trans = -trans
    rot2 = float(wrap_angle(dth - rot1))
    return rot1, trans, rot2


@dataclass(frozen=True)
class MotionKernel:
    """A discretized displacement kernel for one heading layer of a grid belief (Eq. 1).

    Belief mass in cell ``(t, r, c)`` (heading index, row, column) moves to cell
    ``(t + offset[0] + i, r + offset[1] + j, c + offset[2] + k)`` with probability
    ``weights[i, j, k]``; ``weights`` sums to one. Heading indices wrap around; rows follow the
    grid's y axis and columns its x axis.
    """

    weights: FloatArray
    offset: tuple[int, int, int]
    mean_cells: tuple[float, float, float]


@dataclass(frozen=True)
class OdometryMotionModel:
    """Odometry motion model with Gaussian noise growing with rotation and translation.

    ``alpha1`` (rad^2/rad^2): rotation noise from rotation; ``alpha2`` (rad^2/m^2): rotation noise
    from translation; ``alpha3`` (m^2/m^2): translation noise from translation; ``alpha4``
    (m^2/rad^2): translation noise from rotation (Probabilistic Robotics, Table 5.6). The paper
    gives no numbers; the defaults are set for the museum logs here (FHW: a few cm and about 1-2
    degrees of odometry error per metre, see ``../shared/data/README.md``) with margin so that a
    filter with few samples does not become overconfident: 1-sigma of about 10 % of the
    translation and 0.12 rad per rad of rotation, plus 0.07 rad of heading per metre.
    ``min_trans_std`` and ``min_rot_std`` keep a floor of noise so that a standing robot's belief
    does not collapse.
    """

    alpha1: float = 0.015
    alpha2: float = 0.005
    alpha3: float = 0.01
    alpha4: float = 0.002
    min_trans_std: float = 0.005
    min_rot_std: float = 0.005

    def stds(self, rot1: float, trans: float, rot2: float) -> tuple[float, float, float]:
        """The standard deviations of the noise on ``(rot1, trans, rot2)``."""
        return _stds(
            rot1,
            trans,
            rot2,
            self.alpha1,
            self.alpha2,
            self.alpha3,
            self.alpha4,
            self.min_trans_std,
            self.min_rot_std,
        )

    def sample(
        self,
        poses: ArrayLike,
        odom_prev: ArrayLike,
        odom_now: ArrayLike,
        rng: np.random.Generator,
    ) -> FloatArray:
        """Move every pose ``(N, 3)`` by the odometry motion, with sampled noise: ``(N, 3)``.

        The sampling form of the motion model (Probabilistic Robotics, Table 5.6), run by a numba
        kernel; the noise is drawn from ``rng`` so runs are reproducible for a seed.
        """
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        return sample_with_noise(self, p, odom_prev, odom_now, rng.standard_normal((p.shape[0], 3)))

    def covariance(self, odom_prev: ArrayLike, odom_now: ArrayLike, heading: float = 0.0) -> FloatArray:
        """Covariance ``(3, 3)`` of the end pose (x, y, theta) of a robot starting at ``heading``.

        First-order propagation of the ``(rot1, trans, rot2)`` noise through the motion equations.
        """
        rot1, trans, rot2 = decompose(odom_prev, odom_now)
        s = np.array(self.stds(rot1, trans, rot2))
        a = heading + rot1
        J = np.array(
            [
                [-trans * math.sin(a), math.cos(a), 0.0],
                [trans * math.cos(a), math.sin(a), 0.0],
                [1.0, 0.0, 1.0],
            ]
        )
        return np.asarray(J @ np.diag(s**2) @ J.T, dtype=np.float64)

    def kernel(
        self,
        odom_prev: ArrayLike,
        odom_now: ArrayLike,
        resolution: float,
        angular_resolution: float,
        heading: float = 0.0,
        n_sigma: float = 3.0,
    ) -> MotionKernel:
        """The convolution form of the motion model for one heading layer of a grid (Eq. 1).

        ``heading`` is the heading of the layer in the grid's frame (the frame the cells are laid
        out in: subtract the map origin's yaw from a world heading); ``resolution`` is the cell
        size in metres and ``angular_resolution`` the heading step in radians (the paper: 15 cm and
        2 degrees). The Gaussian of :meth:`covariance`, centred on the mean displacement, is
        integrated over each destination cell (approximated by its value at the cell centre, with
        the spread floored at half a cell so a sub-cell shift still spreads over the neighbours),
        over a window of ``n_sigma`` standard deviations, and normalized.
        """
        rot1, trans, rot2 = decompose(odom_prev, odom_now)
        a = heading + rot1
        mean = np.array(
            [
                (rot1 + rot2) / angular_resolution,
                trans * math.sin(a) / resolution,
                trans * math.cos(a) / resolution,
            ]
        )
        cov_xyt = self.covariance(odom_prev, odom_now, heading)
        # Reorder (x, y, theta) -> (theta, row=y, col=x) and express in cells.
        order = [2, 1, 0]
        scale = np.array([angular_resolution, resolution, resolution])
        cov = cov_xyt[np.ix_(order, order)] / np.outer(scale, scale)
        cov = cov + np.diag(np.full(3, 0.25**2))  # floor: half a cell of spread (std 0.5 cells)
        std = np.sqrt(np.diag(cov))
        lo = np.floor(mean - n_sigma * std).astype(np.int64)
        hi = np.ceil(mean + n_sigma * std).astype(np.int64)
        axes = [np.arange(lo[i], hi[i] + 1, dtype=np.float64) - mean[i] for i in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
        inv = np.linalg.inv(cov)
        q = np.einsum("...i,ij,...j->...", grid, inv, grid)
        w = np.exp(-0.5 * q)
        w /= w.sum()
        return MotionKernel(
            weights=w,
            offset=(int(lo[0]), int(lo[1]), int(lo[2])),
            mean_cells=(float(mean[0]), float(mean[1]), float(mean[2])),
        )


@numba.njit(cache=True)
def _stds(
    rot1: float,
    trans: float,
    rot2: float,
    a1: float,
    a2: float,
    a3: float,
    a4: float,
    min_trans: float,
    min_rot: float,
) -> tuple[float, float, float]:
    s_rot1 = math.sqrt(a1 * rot1 * rot1 + a2 * trans * trans + min_rot * min_rot)
    s_trans = math.sqrt(a3 * trans * trans + a4 * (rot1 * rot1 + rot2 * rot2) + min_trans * min_trans)
    s_rot2 = math.sqrt(a1 * rot2 * rot2 + a2 * trans * trans + min_rot * min_rot)
    return s_rot1, s_trans, s_rot2


@numba.njit(cache=True)
def _sample_kernel(
    poses: FloatArray,
    rot1: float,
    trans: float,
    rot2: float,
    stds: FloatArray,
    noise: FloatArray,
    out: FloatArray,
) -> None:
    for i in range(poses.shape[0]):
        r1 = rot1 + stds[0] * noise[i, 0]
        t = trans + stds[1] * noise[i, 1]
        r2 = rot2 + stds[2] * noise[i, 2]
        a = poses[i, 2] + r1
        out[i, 0] = poses[i, 0] + t * math.cos(a)
        out[i, 1] = poses[i, 1] + t * math.sin(a)
        out[i, 2] = a + r2  # wrapped by the caller


def sample_reference(
    model: OdometryMotionModel,
    poses: ArrayLike,
    odom_prev: ArrayLike,
    odom_now: ArrayLike,
    noise: ArrayLike,
) -> FloatArray:
    """Plain-numpy reference of the sampling form, given the standard-normal draws ``noise (N, 3)``."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    z = np.asarray(noise, dtype=np.float64).reshape(-1, 3)
    rot1, trans, rot2 = decompose(odom_prev, odom_now)
    s = np.array(model.stds(rot1, trans, rot2))
    r1 = rot1 + s[0] * z[:, 0]
    t = trans + s[1] * z[:, 1]
    r2 = rot2 + s[2] * z[:, 2]
    a = p[:, 2] + r1
    return np.stack([p[:, 0] + t * np.cos(a), p[:, 1] + t * np.sin(a), wrap_angle(a + r2)], axis=-1)


def sample_with_noise(
    model: OdometryMotionModel,
    poses: ArrayLike,
    odom_prev: ArrayLike,
    odom_now: ArrayLike,
    noise: ArrayLike,
) -> FloatArray:
    """The numba sampling kernel with given standard-normal draws (for comparison with the reference)."""
    p = np.ascontiguousarray(poses, dtype=np.float64).reshape(-1, 3)
    z = np.ascontiguousarray(noise, dtype=np.float64).reshape(-1, 3)
    rot1, trans, rot2 = decompose(odom_prev, odom_now)
    stds = np.array(model.stds(rot1, trans, rot2), dtype=np.float64)
    out = np.empty_like(p)
    _sample_kernel(p, rot1, trans, rot2, stds, z, out)
    out[:, 2] = wrap_angle(out[:, 2])
    return out
