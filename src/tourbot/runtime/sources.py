"""Sources that replay recordings: a :class:`~tourbot.records.RobotLog` (CARMEN log, ROS bag).

The simulator source is :class:`tourbot.sim.simulator.Simulator` (a ``DrivableSource``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from tourbot.records import Odometry, Record, RobotLog, Scan

__all__ = ["LogSource"]


class LogSource:
    """Replays a log's raw odometry and scans in time order, one scan (and the odometry before it) per step.

    The scans' ``reference`` poses stay on the records (metrics may read them); the localizer only
    uses ``odom`` and the ranges.
    """

    def __init__(self, log: RobotLog, name: str | None = None) -> None:
        self.name = name or log.source
        self._log = log
        self._scan_i = 0
        self._odom_i = 0
        self._time = log.scans[0].timestamp if log.scans else 0.0

    @classmethod
    def from_path(cls, path: str | Path, *, lenient: bool = False, odometry: str = "rebuilt") -> LogSource:
        """A source over any log ``tourbot.io.load_log`` reads: CARMEN logs, ROS 1 and ROS 2 bags."""
        from tourbot.io import load_log

        return cls(load_log(path, lenient=lenient, odometry=odometry), name=str(path))

    @property
    def time(self) -> float:
        return self._time

    def __len__(self) -> int:
        return len(self._log.scans)

    def poll(self) -> Sequence[Record] | None:
        if self._scan_i >= len(self._log.scans):
            return None
        scan: Scan = self._log.scans[self._scan_i]
        self._scan_i += 1
        out: list[Record] = []
        odometry: list[Odometry] = self._log.odometry
        while self._odom_i < len(odometry) and odometry[self._odom_i].timestamp <= scan.timestamp:
            out.append(odometry[self._odom_i])
            self._odom_i += 1
        out.append(scan)
        self._time = scan.timestamp
        return out
