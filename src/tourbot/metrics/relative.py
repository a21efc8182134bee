"""How good a mapping run is: relative pose errors against a reference path (Kummerle et al. 2009).

Kummerle et al. ("On measuring the accuracy of SLAM algorithms", Auton. Robots 2009) compare
the *relative* motions between pose pairs, ``delta_est = est_i (-) est_j`` against ``delta_ref =
ref_i (-) ref_j``, so that a map's global frame and slow drift far from the pair do not matter.
Here the pairs are consecutive scans (or scans ``step`` apart).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from tourbot.geometry import relative

__all__ = ["RelativeError", "relative_pose_error"]


@dataclass(frozen=True)
class RelativeError:
    """Mean and spread of the relative translational (m) and rotational (rad) errors."""

    trans_mean: float
    trans_std: float
    rot_mean: float
    rot_std: float
    pairs: int


def relative_pose_error(estimate: ArrayLike, reference: ArrayLike, step: int = 1) -> RelativeError:
    """Relative pose error over pose pairs ``(i, i + step)``; rows with NaN are skipped."""
    est = np.asarray(estimate, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    if est.shape != ref.shape or est.ndim != 2 or est.shape[1] != 3:
        raise ValueError(f"need two (N, 3) paths of the same length, got {est.shape} and {ref.shape}")
    d_est = relative(est[:-step], est[step:])
    d_ref = relative(ref[:-step], ref[step:])
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
