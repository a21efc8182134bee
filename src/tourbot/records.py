"""The in-memory records every source produces: laser scans and odometry readings.

Sources (CARMEN logs, ROS bags, the simulator, a live robot) only produce these; estimators only
consume them. A :class:`RobotLog` is a whole recording held in memory, with array views for the
batched kernels.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["LaserGeometry", "Odometry", "Record", "RobotLog", "Scan"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class LaserGeometry:
    """How a laser's beams are laid out and where the laser sits on the robot.

    Beam ``i`` points at ``angle_min + i * angle_increment`` radians in the laser frame; the laser
    frame is ``offset = (x, y, theta)`` in the robot frame. Readings ``>= max_range`` (or below
    ``min_range``) mean "no return".
    """

    num_beams: int
    angle_min: float
    angle_increment: float
    max_range: float
    min_range: float = 0.0
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def angles(self) -> FloatArray:
        """The beam angles in the laser frame, ``(num_beams,)``."""
        return self.angle_min + self.angle_increment * np.arange(self.num_beams, dtype=np.float64)

    @property
    def fov(self) -> float:
        """The field of view from the first to the last beam, in radians."""
        return self.angle_increment * (self.num_beams - 1)


@dataclass(frozen=True, slots=True)
class Odometry:
    """A raw wheel-odometry reading: the robot's pose in the odometry frame, and its velocities."""

    timestamp: float
    pose: tuple[float, float, float]
    tv: float = 0.0
    rv: float = 0.0


@dataclass(frozen=True, slots=True)
class Scan:
    """One laser scan.

    ``odom`` is the odometry pose at the scan's time (interpolated from the odometry stream by
    the reader); ``reference`` is the reference ("ground truth") pose where the source has one, for
    metrics only: estimators never read it. ``sensor`` names the laser that took the scan (the
    CARMEN record type such as ``FLASER``, or the ROS topic) so that logs with several lasers can
    be told apart.
    """

    timestamp: float
    ranges: FloatArray
    geometry: LaserGeometry
    odom: tuple[float, float, float] | None = None
    reference: tuple[float, float, float] | None = None
    sensor: str = "laser"


Record = Scan | Odometry


@dataclass
class RobotLog:
    """A whole recording held in memory: its scans and raw odometry, in record order.

    ``odometry_kind`` says what the odometry is: ``"raw"`` (the source's stream, no re-anchoring
    found), ``"rebuilt"`` (raw odometry rebuilt from the increments of a stream re-anchored to the
    reference at every scan) or ``"re-anchored"`` (such a stream kept as recorded: it holds the
    reference's corrections, so no localization or mapping figure may stand on it).
    """

    source: str
    scans: list[Scan] = field(default_factory=list)
    odometry: list[Odometry] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    odometry_kind: str = "raw"

    def __len__(self) -> int:
        return len(self.scans)

    @property
    def times(self) -> FloatArray:
        """Scan timestamps, ``(S,)``."""
        return np.array([s.timestamp for s in self.scans], dtype=np.float64)

    @property
    def ranges(self) -> FloatArray:
        """All ranges, ``(S, B)``; needs every scan to have the same beam count."""
        return np.stack([s.ranges for s in self.scans]).astype(np.float64, copy=False)

    @property
    def odom_poses(self) -> FloatArray:
        """Odometry pose at each scan, ``(S, 3)``; NaN where a scan has none."""
        return _pose_array([s.odom for s in self.scans])

    @property
    def reference_poses(self) -> FloatArray:
        """Reference pose of each scan, ``(S, 3)``; NaN where a scan has none."""
        return _pose_array([s.reference for s in self.scans])

    @property
    def has_reference(self) -> bool:
        return bool(self.scans) and all(s.reference is not None for s in self.scans)


def _pose_array(poses: list[tuple[float, float, float] | None]) -> FloatArray:
    out = np.full((len(poses), 3), np.nan, dtype=np.float64)
    for i, p in enumerate(poses):
        if p is not None:
            out[i] = p
    return out
