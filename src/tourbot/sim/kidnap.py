"""Kidnapping the robot on a recorded log, as in Fox, Burgard, Thrun & Cremers (1998), Sec.
"Recovery from extreme localization failures": with probability 0.005 per metre of motion the
robot's pose is changed (heading by 180 ± 90 degrees, position by 0 ± 100 cm) without the robot
knowing.

How it is done on a real log
    The scans of a recorded log cannot be re-taken from another place, so the kidnap is applied to
    what the robot *believes*: at the kidnap, the odometry reports a motion ``D`` that never
    happened (a turn of 180 ± 90 degrees and a shift of up to 1 m), and every later odometry pose
    is carried along, so all later odometry increments are unchanged in the robot's frame. The
    scans and the reference trajectory stay as recorded. A localizer that trusts its odometry then
    believes itself at ``estimate ⊕ D`` while the scans come from the true pose: exactly the
    situation after a physical kidnap by ``D⁻¹`` (the error between belief and truth has the
    paper's distribution). Formally, with ``o_t`` the odometry and ``k`` the kidnap,
    ``o'_t = o_k ⊕ D ⊕ (o_k ⊖ o_t)`` for ``t >= k``, applied in turn for each kidnap.

    A kidnap "at scan k" happens between scans ``k-1`` and ``k``: ``Scan.odom`` of scans ``>= k``
    and the raw odometry readings stamped after scan ``k-1`` are changed.

The ± of the paper are read as uniform ranges: heading change uniform in [90, 270] degrees,
shift uniform in direction and uniform in length in [0, 1] m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.errors import TourbotError
from tourbot.geometry import compose, invert
from tourbot.records import Odometry, RobotLog

__all__ = ["Kidnap", "KidnapConfig", "KidnapError", "apply_kidnaps", "plan_kidnaps"]

FloatArray = NDArray[np.float64]


class KidnapError(TourbotError):
    """Kidnaps that cannot be applied to a log (no odometry, indices outside the log)."""


@dataclass(frozen=True)
class KidnapConfig:
    """Fox et al. 1998, Sec. "Recovery from extreme localization failures"."""

    probability_per_metre: float = 0.005
    heading_change: float = math.pi  # mean, rad
    heading_spread: float = math.pi / 2.0  # ± uniform, rad
    max_shift: float = 1.0  # m, the ± of "0 ± 100 cm"

    def __post_init__(self) -> None:
        if not self.probability_per_metre >= 0.0:
            raise KidnapError("probability_per_metre must be >= 0")
        if self.max_shift < 0.0 or self.heading_spread < 0.0:
            raise KidnapError("max_shift and heading_spread must be >= 0")


@dataclass(frozen=True)
class Kidnap:
    """A kidnap just before scan ``scan`` (time ``time``): odometry gains the phantom motion
    ``delta = (dx, dy, dtheta)`` in the robot frame."""

    scan: int
    time: float
    delta: tuple[float, float, float]


def plan_kidnaps(
    reference: ArrayLike, times: ArrayLike, rng: np.random.Generator, config: KidnapConfig | None = None
) -> list[Kidnap]:
    """Draw kidnaps along a reference trajectory ``(S, 3)`` with scan ``times`` ``(S,)``.

    Each scan-to-scan segment of length ``d`` carries a kidnap with probability
    ``1 - exp(-p d)`` (``p`` per metre); none before the first scan.
    """
    cfg = config or KidnapConfig()
    ref = np.asarray(reference, dtype=np.float64)
    t = np.asarray(times, dtype=np.float64)
    if len(ref) < 2:
        return []
    seg = np.hypot(*np.diff(ref[:, :2], axis=0).T)
    seg = np.nan_to_num(seg, nan=0.0)
    p = 1.0 - np.exp(-cfg.probability_per_metre * seg)
    u = rng.random(len(seg))
    kidnaps = []
    for i in np.flatnonzero(u < p).tolist():
        k = i + 1
        turn = cfg.heading_change + rng.uniform(-cfg.heading_spread, cfg.heading_spread)
        length = rng.uniform(0.0, cfg.max_shift)
        direction = rng.uniform(-math.pi, math.pi)
        delta = (
            length * math.cos(direction),
            length * math.sin(direction),
            math.remainder(turn, 2 * math.pi),
        )
        kidnaps.append(Kidnap(scan=k, time=float(t[k]), delta=delta))
    return kidnaps


def _carry(pose: ArrayLike, at: FloatArray, delta: ArrayLike) -> FloatArray:
    """``o' = at ⊕ delta ⊕ (at ⊖ o)``: the odometry after a phantom motion ``delta`` at ``at``."""
    correction = compose(compose(at, delta), invert(at))
    return compose(correction, np.asarray(pose, dtype=np.float64))


def apply_kidnaps(log: RobotLog, kidnaps: list[Kidnap]) -> RobotLog:
    """A copy of ``log`` whose odometry carries the kidnaps (see the module docstring)."""
    scans = list(log.scans)
    odometry = list(log.odometry)
    for kid in sorted(kidnaps, key=lambda k: k.scan):
        if not 1 <= kid.scan < len(scans):
            raise KidnapError(f"kidnap at scan {kid.scan} outside the log's 1..{len(scans) - 1}")
        at_pose = scans[kid.scan].odom
        if at_pose is None:
            raise KidnapError(f"scan {kid.scan} has no odometry pose to kidnap from")
        at = np.asarray(at_pose, dtype=np.float64)
        for j in range(kid.scan, len(scans)):
            s = scans[j]
            if s.odom is not None:
                scans[j] = replace(s, odom=_as_pose(_carry(s.odom, at, kid.delta)))
        after = scans[kid.scan - 1].timestamp
        for j, o in enumerate(odometry):
            if o.timestamp > after:
                odometry[j] = Odometry(o.timestamp, _as_pose(_carry(o.pose, at, kid.delta)), o.tv, o.rv)
    return RobotLog(source=log.source, scans=scans, odometry=odometry, warnings=list(log.warnings))


def _as_pose(p: FloatArray) -> tuple[float, float, float]:
    return (float(p[0]), float(p[1]), float(p[2]))
