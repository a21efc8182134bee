"""Honest odometry for the corrected CARMEN logs: the wheel increments chained, the re-anchoring dropped.

The corrected logs of ../shared/data/carmen re-anchor their ``ODOM`` stream to the corrected pose
after every scan (an ``ODOM ... 0 pippo 0`` line, timestamp zero); the timestamped readings that
follow continue from it. Read as it is, that stream carries the answer. Here the motion between
consecutive readings is chained, and the jump onto each re-anchoring line is skipped: the reading
after a re-anchoring line moves on from where the previous reading ended, by its own increment
from the re-anchoring pose (see ../shared/data/README.md).

This is a bench-side stand-in until the CARMEN reader does the rebuild itself (the ``odometry``
branch); it is swapped for that then.
"""

from __future__ import annotations

import gzip
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, relative
from tourbot.records import RobotLog

__all__ = ["rebuild_odometry", "with_rebuilt_odometry"]

FloatArray = NDArray[np.float64]


def rebuild_odometry(path: str | Path) -> tuple[FloatArray, FloatArray]:
    """Times ``(R,)`` and rebuilt poses ``(R, 3)`` of the timestamped ``ODOM`` readings of a log."""
    p = Path(path)
    opener = gzip.open if p.suffix == ".gz" else open
    times: list[float] = []
    poses: list[FloatArray] = []
    anchor: FloatArray | None = None  # where the raw increments of the next reading start from
    current: FloatArray | None = None
    with opener(p, "rt") as fh:
        for line in fh:
            if not line.startswith("ODOM "):
                continue
            tok = line.split()
            raw = np.array([float(tok[1]), float(tok[2]), float(tok[3])])
            if float(tok[7]) == 0.0:  # a re-anchoring line: the next increment starts here
                anchor = raw
                continue
            if current is None:
                current = raw.copy()
            elif anchor is not None:
                current = compose(current, relative(anchor, raw))
            times.append(float(tok[7]))
            poses.append(current)
            anchor = raw
    return np.asarray(times, dtype=np.float64), np.asarray(poses, dtype=np.float64).reshape(-1, 3)


def with_rebuilt_odometry(log: RobotLog, path: str | Path) -> RobotLog:
    """``log`` with each scan's odometry replaced by the rebuilt odometry at the scan's time."""
    times, poses = rebuild_odometry(path)
    if len(times) < 2:
        raise ValueError(f"{path}: fewer than two timestamped ODOM readings: no odometry to rebuild")
    order = np.argsort(times, kind="stable")
    times, poses = times[order], poses[order]
    theta = np.unwrap(poses[:, 2])
    t = log.times
    x = np.interp(t, times, poses[:, 0])
    y = np.interp(t, times, poses[:, 1])
    th = np.interp(t, times, theta)
    th = (th + np.pi) % (2 * np.pi) - np.pi
    scans = [
        replace(s, odom=(float(a), float(b), float(c)))
        for s, a, b, c in zip(log.scans, x, y, th, strict=True)
    ]
    return RobotLog(source=log.source, scans=scans, odometry=log.odometry, warnings=list(log.warnings))
