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


_LASERS = ("FLASER", "RLASER")


def rebuild_odometry(path: str | Path) -> tuple[list[str], FloatArray]:
    """For each ``FLASER``/``RLASER`` line of a log, in file order: its kind, and the rebuilt
    odometry pose of the latest reading before it ``(S, 3)`` (record order: these logs'
    timestamps go backwards in places, and re-anchoring lines carry zero or garbage ones).

    A re-anchoring line is an ``ODOM`` line with timestamp zero, or one that repeats the corrected
    pose of the laser line just before it."""
    p = Path(path)
    opener = gzip.open if p.suffix == ".gz" else open
    kinds: list[str] = []
    at_scan: list[FloatArray] = []
    anchor: FloatArray | None = None  # where the raw increment of the next reading starts from
    current: FloatArray | None = None
    laser_pose: tuple[str, str, str] | None = None  # the corrected pose of the laser line just read
    with opener(p, "rt") as fh:
        for line in fh:
            tok = line.split()
            if not tok:
                continue
            if tok[0] in _LASERS:
                n = int(tok[1])
                laser_pose = (tok[2 + n], tok[3 + n], tok[4 + n])
                kinds.append(tok[0])
                at_scan.append(np.full(3, np.nan) if current is None else current.copy())
                continue
            if tok[0] != "ODOM":
                continue
            raw = np.array([float(tok[1]), float(tok[2]), float(tok[3])])
            repeat = laser_pose is not None and tuple(tok[1:4]) == laser_pose
            laser_pose = None
            if float(tok[7]) == 0.0 or repeat:  # re-anchoring: the next increment starts here
                anchor = raw
                continue
            if current is None:
                current = raw.copy()
            elif anchor is not None:
                current = compose(current, relative(anchor, raw))
            anchor = raw
    return kinds, np.asarray(at_scan, dtype=np.float64).reshape(-1, 3)


def with_rebuilt_odometry(log: RobotLog, path: str | Path) -> RobotLog:
    """``log`` (read from the CARMEN file ``path``) with each scan's odometry replaced by the
    rebuilt odometry at that scan."""
    kinds, poses = rebuild_odometry(path)
    if len(kinds) != len(log.scans) or any(k != s.sensor for k, s in zip(kinds, log.scans, strict=False)):
        raise ValueError(f"{path}: the laser lines do not match the log's {len(log.scans)} scans")
    if len(poses) and np.isnan(poses).all():
        raise ValueError(f"{path}: no timestamped ODOM readings before the scans: no odometry to rebuild")
    first = int(np.argmax(np.isfinite(poses[:, 0]))) if len(poses) else 0
    poses[:first] = poses[first]  # scans before the first reading: the first reading's pose
    scans = [
        replace(s, odom=(float(q[0]), float(q[1]), float(q[2])))
        for s, q in zip(log.scans, poses, strict=True)
    ]
    return RobotLog(source=log.source, scans=scans, odometry=log.odometry, warnings=list(log.warnings))
