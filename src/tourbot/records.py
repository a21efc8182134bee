"""The in-memory records every source produces: laser scans, odometry readings and camera images.

Sources (CARMEN logs, ROS bags, the simulator, a live robot) only produce these; estimators only
consume them. A :class:`RobotLog` is a whole recording held in memory, with array views for the
batched kernels.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["Image", "LaserGeometry", "Odometry", "Record", "RobotLog", "Scan"]

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


@dataclass(frozen=True, slots=True, eq=False)
class Image:
    """One camera image: ``pixels`` ``(height, width)`` 8-bit grey (or ``(height, width, 3)`` colour).

    ``camera`` names the camera that took it (``"ceiling"`` for the upward camera of Gamallo et
    al., ``"forward"`` for the obstacle camera), so that a robot with several cameras can be read.
    ``odom`` is the odometry pose at the image's time; ``reference`` the reference pose where the
    source has one, for metrics only: estimators never read it.
    """

    timestamp: float
    pixels: NDArray[np.uint8]
    camera: str = "camera"
    odom: tuple[float, float, float] | None = None
    reference: tuple[float, float, float] | None = None


Record = Scan | Odometry | Image


@dataclass
class RobotLog:
    """A whole recording held in memory: its scans and raw odometry, in record order.

    ``odometry_kind`` says what the odometry is: ``"raw"`` (the source's stream, no re-anchoring
    found), ``"rebuilt"`` (raw odometry rebuilt from the increments of a stream re-anchored to the
    reference at every scan) or ``"re-anchored"`` (such a stream kept as recorded: it holds the
    reference's corrections, so no localization or mapping figure may stand on it).
    ``notes``: what the reader inferred and why (units, beam layout, maximum range, odometry).
    """

    source: str
    scans: list[Scan] = field(default_factory=list)
    odometry: list[Odometry] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    odometry_kind: str = "raw"
    notes: list[str] = field(default_factory=list)

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

    def duration(self) -> tuple[float | None, str]:
        """The time the scans span (s), or None with the reason when their timestamps cannot tell.

        Unknown when the timestamps are all zero, not finite, repeat or go backwards, or when one
        gap holds most of the log (a garbage timestamp): a duration printed from such stamps is
        wrong however precisely it is printed.
        """
        t = self.times
        if t.size < 2:
            return None, "fewer than two scans"
        if not np.isfinite(t).all():
            return None, "some scan timestamps are not numbers"
        if not (t != 0.0).any():
            return None, "the scan timestamps are all zero"
        steps = np.diff(t)
        if (steps <= 0.0).any():
            k = int(np.argmax(steps <= 0.0))
            what = "repeat" if steps[k] == 0.0 else "go backwards"
            return None, f"the scan timestamps {what} (scan {k + 1}: {t[k]!r} then {t[k + 1]!r})"
        span = float(t[-1] - t[0])
        k = int(np.argmax(steps))
        if t.size > 10 and steps[k] > 0.5 * span:
            return None, f"one gap of {steps[k]:.6g} s (scan {k + 1}) holds most of the log"
        return span, ""

    @property
    def has_reference(self) -> bool:
        return bool(self.scans) and all(s.reference is not None for s in self.scans)


def _pose_array(poses: list[tuple[float, float, float] | None]) -> FloatArray:
    out = np.full((len(poses), 3), np.nan, dtype=np.float64)
    for i, p in enumerate(poses):
        if p is not None:
            out[i] = p
    return out
