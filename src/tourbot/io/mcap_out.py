"""A run written as MCAP with the ROS 2 message profile, for Foxglove (or any ROS 2 tool) to show.

The file is the ``.mcap`` of a rosbag2 bag (``rosbags.rosbag2.Writer`` with MCAP storage) holding
the channels of :mod:`tourbot.io.ros2_messages` (the map latched: transient-local durability).
Times are the log's own. The file is written whole or not at all: the bag is written into a
temporary folder beside the target and its ``.mcap`` renamed onto the target when
:class:`McapRun` closes without an error. With ``storage="sqlite3"`` the target is a whole ROS 2
bag folder (``metadata.yaml`` and a ``.db3``), renamed onto the target the same way.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from types import TracebackType
from typing import Any

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer

from tourbot.errors import InputError
from tourbot.io.output import check_output, partial_name
from tourbot.io.ros2_messages import STORE, TOPICS, Ros2Channels
from tourbot.records import RobotLog

__all__ = ["McapRun", "check_mcap_output", "write_log_as_ros2"]

_ZERO = QosTime(sec=0, nsec=0)
_LATCHED = Qos(
    history=QosHistory.KEEP_LAST,
    depth=1,
    reliability=QosReliability.RELIABLE,
    durability=QosDurability.TRANSIENT_LOCAL,
    deadline=_ZERO,
    lifespan=_ZERO,
    liveliness=QosLiveliness.AUTOMATIC,
    liveliness_lease_duration=_ZERO,
    avoid_ros_namespace_conventions=False,
)


def check_mcap_output(path: str | Path, *, force: bool, option: str = "--mcap") -> Path:
    """``path`` as an MCAP file to write, checked before the work (one clear error each).

    Refused: a folder, an existing file unless ``force``, a folder that does not exist or cannot
    be written to.
    """
    p = check_output(path, option)
    if p.exists() and not force:
        raise InputError("exists; --force overwrites it", path=p, field=option)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"folder {parent} does not exist", path=p, field=option)
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"folder {parent} is not writable", path=p, field=option)
    return p


class McapRun(Ros2Channels):
    """A run being written to ``path`` as MCAP (a context manager; the file appears on close).

    >>> with McapRun(path) as run:                                      # doctest: +SKIP
    ...     run.write_map(grid, t0)
    ...     run.write_scan(scan)
    """

    def __init__(self, path: str | Path, storage: str = "mcap", option: str = "--mcap") -> None:
        super().__init__()
        if storage not in ("mcap", "sqlite3"):
            raise ValueError(f"storage must be 'mcap' or 'sqlite3', not {storage!r}")
        self.storage = storage
        self.path = check_output(path, option) if storage == "mcap" else Path(path)
        self._tmp = partial_name(self.path)
        self._writer: Writer | None = None
        self._conns: dict[str, Any] = {}

    # ------------------------------------------------------------------ life cycle

    def __enter__(self) -> McapRun:
        shutil.rmtree(self._tmp, ignore_errors=True)
        plugin = StoragePlugin.MCAP if self.storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer(self._tmp, version=9, storage_plugin=plugin)
        writer.open()
        for topic, msgtype in TOPICS.items():
            qos = [_LATCHED] if topic == "/map" else []
            self._conns[topic] = writer.add_connection(
                topic, msgtype, typestore=STORE, offered_qos_profiles=qos
            )
        self._writer = writer
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        writer, self._writer = self._writer, None
        try:
            if writer is not None:
                writer.close()
            if kind is None and self.storage == "mcap":
                os.replace(self._tmp / f"{self._tmp.name}.mcap", self.path)
            elif kind is None:
                # the bag folder's files are named after it: name them after the target
                for f in list(self._tmp.iterdir()):
                    if f.name.startswith(self._tmp.name):
                        f.rename(self._tmp / f.name.replace(self._tmp.name, self.path.name, 1))
                meta = self._tmp / "metadata.yaml"
                meta.write_text(meta.read_text().replace(self._tmp.name, self.path.name))
                shutil.rmtree(self.path, ignore_errors=True)
                os.replace(self._tmp, self.path)
        finally:
            shutil.rmtree(self._tmp, ignore_errors=True)

    def _emit(self, topic: str, stamp_ns: int, data: bytes) -> None:
        if self._writer is None:
            raise RuntimeError("McapRun is not open: use it in a with statement")
        self._writer.write(self._conns[topic], stamp_ns, data)


def write_log_as_ros2(log: RobotLog, path: str | Path) -> Path:
    """``log`` as a ROS 2 bag: an MCAP file (``.mcap``) or a bag folder (sqlite3, any other name).

    Every odometry reading on ``/odom`` (with ``odom -> base_link`` on ``/tf``) and every scan on
    ``/scan`` (with the laser's mount, ``base_link -> laser``), at their own times, so that
    :func:`tourbot.io.rosbag.read_bag` reads the same scans and odometry back. Reference poses are
    not written (a ROS bag has no place for them).
    """
    p = Path(path)
    storage = "mcap" if p.suffix == ".mcap" else "sqlite3"
    events: list[tuple[float, int, Any]] = [(o.timestamp, 0, o) for o in log.odometry]
    events += [(s.timestamp, 1, s) for s in log.scans]
    with McapRun(p, storage=storage, option="--output") as run:
        for _, kind, record in sorted(events, key=lambda e: (e[0], e[1])):
            if kind == 0:
                run.write_odometry(record.pose, record.timestamp, record.tv, record.rv)
            else:
                run.write_scan(record)
    return p
