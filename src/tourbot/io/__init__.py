"""Reading and writing robot data: CARMEN logs, ROS bags, ROS map_server maps, TUM trajectories.

:func:`load_log` opens any robot log by its kind; every reader produces the same records
(:mod:`tourbot.records`).
"""

from __future__ import annotations

from pathlib import Path

from tourbot.io.carmen import iter_carmen, read_carmen, write_carmen
from tourbot.io.errors import BagError, LogFormatError, MapFormatError, TrajectoryFormatError
from tourbot.records import RobotLog

__all__ = [
    "BagError",
    "LogFormatError",
    "MapFormatError",
    "TrajectoryFormatError",
    "iter_carmen",
    "load_log",
    "log_kind",
    "read_carmen",
    "write_carmen",
]

_ROS_SUFFIXES = (".bag", ".db3", ".mcap")


def log_kind(path: str | Path) -> str:
    """``"rosbag"`` for ROS 1 (``.bag``) and ROS 2 bags (folder, ``.db3``, ``.mcap``), else ``"carmen"``."""
    p = Path(path)
    if p.is_dir() or p.suffix.lower() in _ROS_SUFFIXES:
        return "rosbag"
    return "carmen"


def load_log(path: str | Path, *, lenient: bool = False, odometry: str = "rebuilt") -> RobotLog:
    """Read a robot log of any supported kind: CARMEN (``.log``, ``.log.gz``, ``.clf``...) or ROS bag.

    ``odometry``: ``"rebuilt"`` rebuilds raw odometry from the increments of a stream re-anchored to
    the reference at every scan (corrected CARMEN logs); ``"as-recorded"`` keeps the stream.
    """
    p = Path(path)
    if not p.exists():
        raise LogFormatError("no such file", path=p)
    if log_kind(p) == "rosbag":
        from tourbot.io.rosbag import read_bag

        return read_bag(p, lenient=lenient)
    return read_carmen(p, lenient=lenient, odometry=odometry)
