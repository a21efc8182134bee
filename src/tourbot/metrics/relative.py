"""How good an estimated trajectory is: relation errors and the aligned trajectory error.

Relation error (Kummerle et al., "On measuring the accuracy of SLAM algorithms", Auton. Robots
2009, Eq. 2): for a set of pose pairs ``(i, j)`` the estimated relative motion ``delta_ij = est_i
(-) est_j`` is compared with the reference one ``delta*_ij = ref_i (-) ref_j``,

    eps = 1/N sum_(i,j) trans(delta_ij (-) delta*_ij)  and  rot(delta_ij (-) delta*_ij),

so that a map's global frame does not matter and only the relations chosen are judged. Which pairs
are chosen decides what the figure sees: consecutive scans only (``step=1``) hide the drift of a
whole building; :func:`sample_pairs` adds pairs drawn from the reference path at separations of
1-50 m of travelled distance, and *revisits* (pairs that the reference puts within a metre of
each other after the robot travelled at least 10 m in between), where a mapper without loop
closure is wrong by all its accumulated drift. The draw is seeded: the same log and
:class:`PairSampling` always give the same pairs.

Aligned trajectory error (ATE): the root-mean-square position error after the rigid SE(2)
transform that best aligns the estimate onto the reference (least squares, Umeyama 1991 without
scale).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from tourbot.geometry import compose, relative

__all__ = [
    "AlignedError",
    "PairSampling",
    "RelativeError",
    "align_se2",
    "aligned_trajectory_error",
    "path_length",
    "relation_error",
    "relative_pose_error",
    "sample_pairs",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class RelativeError:
    """Mean and spread of the relative translational (m) and rotational (rad) errors."""

    trans_mean: float
    trans_std: float
    rot_mean: float
    rot_std: float
    pairs: int


@dataclass(frozen=True)
class PairSampling:
    """How pose pairs are drawn from a reference path (see the module docstring).

    ``pairs`` separation pairs: a start scan drawn uniformly and a separation uniformly in
    ``[min_separation, max_separation]`` m of travelled path; the partner is the first scan at least
    that far along. Revisits: all pairs within ``revisit_radius`` m of each other and at least
    ``revisit_path`` m apart along the path, of which ``revisit_pairs`` are drawn (all when fewer).
    """

    min_separation: float = 1.0
    max_separation: float = 50.0
    pairs: int = 2000
    revisit_radius: float = 1.0
    revisit_path: float = 10.0
    revisit_pairs: int = 2000
    seed: int = 0


def _check(estimate: ArrayLike, reference: ArrayLike) -> tuple[FloatArray, FloatArray]:
    est = np.asarray(estimate, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    if est.shape != ref.shape or est.ndim != 2 or est.shape[1] != 3:
        raise ValueError(f"need two (N, 3) paths of the same length, got {est.shape} and {ref.shape}")
    return est, ref


def relation_error(estimate: ArrayLike, reference: ArrayLike, pairs: ArrayLike) -> RelativeError:
    """Kummerle et al. (2009) Eq. 2 over the pose pairs ``(P, 2)``: mean absolute errors of the
    relative motions (rows with NaN skipped)."""
    est, ref = _check(estimate, reference)
    ij = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    d_est = relative(est[ij[:, 0]], est[ij[:, 1]])
    d_ref = relative(ref[ij[:, 0]], ref[ij[:, 1]])
    err = relative(d_ref, d_est)
    ok = np.all(np.isfinite(err), axis=1)
    trans = np.hypot(err[ok, 0], err[ok, 1])
    rot = np.abs(err[ok, 2])
    return RelativeError(
        trans_mean=float(trans.mean()) if trans.size else float("nan"),
        trans_std=float(trans.std()) if trans.size else float("nan"),
        rot_mean=float(rot.mean()) if rot.size else float("nan"),
        rot_std=float(rot.std()) if rot.size else float("nan"),
        pairs=int(ok.sum()),
    )


def relative_pose_error(estimate: ArrayLike, reference: ArrayLike, step: int = 1) -> RelativeError:
    """Relation error over the pose pairs ``(i, i + step)``; rows with NaN are skipped."""
    est, ref = _check(estimate, reference)
    i = np.arange(max(len(est) - step, 0))
    return relation_error(est, ref, np.stack([i, i + step], axis=1))


def path_length(reference: ArrayLike) -> FloatArray:
    """Distance travelled along ``reference`` ``(N, 3)`` up to each pose, ``(N,)``."""
    ref = np.asarray(reference, dtype=np.float64)
    steps = np.hypot(np.diff(ref[:, 0]), np.diff(ref[:, 1]))
    return np.concatenate([[0.0], np.cumsum(steps)])


def sample_pairs(reference: ArrayLike, sampling: PairSampling | None = None) -> dict[str, IntArray]:
    """Pose pairs ``(P, 2)`` drawn from the reference path: ``"separation"`` (1-50 m apart along
    the path), ``"revisit"`` (near in space, far along the path) and ``"consecutive"``."""
    s = sampling or PairSampling()
    ref = np.asarray(reference, dtype=np.float64)
    n = len(ref)
    rng = np.random.default_rng(s.seed)
    along = path_length(ref)
    consecutive = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1).astype(np.int64)
    starts = rng.integers(0, max(n, 1), size=s.pairs)
    gaps = rng.uniform(s.min_separation, s.max_separation, size=s.pairs)
    ends = np.searchsorted(along, along[starts] + gaps, side="left")
    ok = ends < n
    separation = np.stack([starts[ok], ends[ok]], axis=1).astype(np.int64)
    # revisits: within the radius in space, far along the path (every such pair, then a draw)
    tree = cKDTree(ref[:, :2])
    near = np.asarray(sorted(tree.query_pairs(s.revisit_radius)), dtype=np.int64).reshape(-1, 2)
    far = np.abs(along[near[:, 1]] - along[near[:, 0]]) >= s.revisit_path
    revisit = near[far]
    if len(revisit) > s.revisit_pairs:
        revisit = revisit[np.sort(rng.choice(len(revisit), s.revisit_pairs, replace=False))]
    return {"separation": separation, "revisit": revisit, "consecutive": consecutive}


def align_se2(estimate: ArrayLike, reference: ArrayLike) -> FloatArray:
    """The rigid transform ``T`` (a pose) minimising ``sum |T (+) est_i - ref_i|^2`` over positions
    (Umeyama 1991, rotation and translation only); rows with NaN are skipped."""
    est, ref = _check(estimate, reference)
    ok = np.all(np.isfinite(est), axis=1) & np.all(np.isfinite(ref), axis=1)
    a, b = est[ok, :2], ref[ok, :2]
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    h = (a - ca).T @ (b - cb)
    angle = float(np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
    c, sn = np.cos(angle), np.sin(angle)
    t = cb - np.array([[c, -sn], [sn, c]]) @ ca
    return np.array([t[0], t[1], angle])


@dataclass(frozen=True)
class AlignedError:
    """Position errors (m) after SE(2) alignment: root mean square, mean and maximum."""

    rmse: float
    mean: float
    max: float
    transform: tuple[float, float, float]


def aligned_trajectory_error(estimate: ArrayLike, reference: ArrayLike) -> AlignedError:
    """Absolute trajectory error of ``estimate`` after aligning it onto ``reference`` (SE(2))."""
    est, ref = _check(estimate, reference)
    t = align_se2(est, ref)
    moved = compose(t, est)
    d = np.hypot(moved[:, 0] - ref[:, 0], moved[:, 1] - ref[:, 1])
    d = d[np.isfinite(d)]
    return AlignedError(
        rmse=float(np.sqrt(np.mean(d**2))),
        mean=float(d.mean()),
        max=float(d.max()),
        transform=(float(t[0]), float(t[1]), float(t[2])),
    )
