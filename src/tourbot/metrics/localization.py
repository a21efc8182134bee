"""How well a localizer did against a reference path: errors, failures and recovery from kidnapping.

Fox, Burgard and Thrun (1998, "Markov localization for mobile robots in dynamic environments",
Sec. "Experimental results") count a scan as a *failure* when the position estimate is more than
45 cm off the reference, and a robot as *recovered* from a kidnap once the error is "smaller than
45cm for more than 10 seconds". These are the only definitions of those figures in tourbot: the
CLI and every benchmark (MCL, grid Markov, the localization comparison) call them.

Censoring (the one rule)
    A kidnap is judged over the scans from it to the next kidnap (or the end of the log). Within
    that window the robot has recovered at the first scan from which the error stays below 45 cm
    for more than 10 s, or until the end of the log (a robot localized when the log ends has
    recovered: nothing after it could show otherwise). A window shorter than 10 s in which the
    robot has not recovered is *censored*: no localizer could show the 10 s that count, so the
    kidnap is neither a success nor a failure (``None``) and is left out of the rates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.geometry import wrap_angle

__all__ = [
    "FAILURE_DISTANCE",
    "RECOVERED_FOR",
    "Recovery",
    "converged_index",
    "failure_rate",
    "mean_ci",
    "pose_errors",
    "recovery",
    "settle_index",
]

FloatArray = NDArray[np.float64]

FAILURE_DISTANCE = 0.45  # m: "a failure if the estimated location deviated ... by more than 45cm"
RECOVERED_FOR = 10.0  # s: "smaller than 45cm for more than 10 seconds"


@dataclass(frozen=True)
class Recovery:
    """One judged kidnap: whether the robot recovered, and the seconds and metres travelled until
    then (NaN when it did not)."""

    recovered: bool
    seconds: float
    metres: float


def pose_errors(estimate: ArrayLike, reference: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Position error (m) and absolute heading error (rad, wrapped) per pose, ``(S,)`` each."""
    est = np.asarray(estimate, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    if est.shape != ref.shape or est.ndim != 2 or est.shape[1] != 3:
        raise ValueError(f"need two (S, 3) paths of the same length, got {est.shape} and {ref.shape}")
    pos = np.hypot(est[:, 0] - ref[:, 0], est[:, 1] - ref[:, 1])
    head = np.abs(wrap_angle(est[:, 2] - ref[:, 2]))
    return pos, head


def failure_rate(position_errors: ArrayLike) -> float:
    """The fraction of scans whose position error exceeds ``FAILURE_DISTANCE`` (NaN for none)."""
    e = np.asarray(position_errors, dtype=np.float64)
    return float(np.mean(e > FAILURE_DISTANCE)) if e.size else math.nan


def settle_index(err: ArrayLike, times: ArrayLike, start: int, end: int) -> int | None:
    """First scan ``j`` in ``[start, end)`` from which the error stays below ``FAILURE_DISTANCE``
    for more than ``RECOVERED_FOR`` seconds, or until the end of the log (None: never)."""
    e = np.asarray(err, dtype=np.float64)
    t = np.asarray(times, dtype=np.float64)
    j = start
    while j < end:
        if e[j] >= FAILURE_DISTANCE:
            j += 1
            continue
        k = j
        while k < end and e[k] < FAILURE_DISTANCE:
            k += 1
        if t[k - 1] - t[j] > RECOVERED_FOR or k == len(e):
            return j
        j = k
    return None


def converged_index(err: ArrayLike) -> int | None:
    """First scan from which the error stays below ``FAILURE_DISTANCE`` to the end (global
    localization: when the belief has found the robot for good); None if the last scan fails."""
    bad = np.flatnonzero(np.asarray(err, dtype=np.float64) >= FAILURE_DISTANCE)
    n = int(np.asarray(err).size)
    first = 0 if bad.size == 0 else int(bad[-1]) + 1
    return first if first < n else None


def recovery(
    err: ArrayLike, times: ArrayLike, kidnap_scans: list[int], path: ArrayLike | None = None
) -> list[Recovery | None]:
    """Per kidnap (the scan index it happens at): its :class:`Recovery`, or None when censored
    (module docstring). ``path`` is the cumulative distance travelled per scan (metres until
    recovery; NaN without it)."""
    e = np.asarray(err, dtype=np.float64)
    t = np.asarray(times, dtype=np.float64)
    dist = None if path is None else np.asarray(path, dtype=np.float64)
    out: list[Recovery | None] = []
    for i, k0 in enumerate(kidnap_scans):
        end = kidnap_scans[i + 1] if i + 1 < len(kidnap_scans) else len(e)
        j = settle_index(e, t, k0, end)
        if j is None and t[min(end, len(t) - 1)] - t[k0] <= RECOVERED_FOR:
            out.append(None)
        elif j is None:
            out.append(Recovery(False, math.nan, math.nan))
        else:
            metres = math.nan if dist is None else float(dist[j] - dist[k0])
            out.append(Recovery(True, float(t[j] - t[k0]), metres))
    return out


def mean_ci(values: ArrayLike) -> tuple[float, float]:
    """Mean and half-width of its 95 % confidence interval (Student t; 0 for one value), over the
    finite values."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan
    if v.size == 1:
        return float(v[0]), 0.0
    from scipy import stats

    q = float(stats.t.ppf(0.975, v.size - 1))
    return float(v.mean()), float(q * v.std(ddof=1) / math.sqrt(v.size))
