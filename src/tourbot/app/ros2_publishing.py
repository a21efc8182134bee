"""A running robot published as ROS 2 messages while it runs: a runtime sink over
:class:`tourbot.io.ros2_messages.Ros2Channels`, into an MCAP file (:class:`McapRecorder`) or to a
live Foxglove server (:class:`tourbot.io.foxglove_live.FoxgloveLive`).

``tourbot simulate --mcap`` and ``tourbot demo --record --mcap`` record through it, ``demo
--foxglove`` and ``serve --foxglove`` publish through it. At each runtime step it takes the
records the source produced (each scan with the odometry pose it was taken at, the odometry, the
camera images) and, from the snapshot, any new estimate of the robot's MCL with its samples, and
the people the robot tracks. The map is published first.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from types import TracebackType

from tourbot.errors import InputError
from tourbot.io.mcap_out import McapRun
from tourbot.io.ros2_messages import TOPICS, Ros2Channels
from tourbot.records import Image, Odometry, Record, Scan
from tourbot.runtime.localizers import MCLLocalizer
from tourbot.runtime.loop import Runtime
from tourbot.snapshot import StateSnapshot

__all__ = ["McapRecorder", "RunPublisher"]


class RunPublisher:
    """Publishes a runtime's run on ``channels`` (a :class:`~tourbot.interfaces.RecordSink`).

    An estimate is published at the time of the scan it integrated, with that scan's odometry pose
    (for the map -> odom transform) and the localizer's samples. The beams are not published: the
    runtime localizer integrates a decimated scan and does not hand out which beams it used.
    """

    def __init__(self, channels: Ros2Channels, runtime: Runtime) -> None:
        localizer = runtime.localizer
        if not isinstance(localizer, MCLLocalizer):
            raise InputError(
                f"needs the robot's MCL localizer, the robot runs {type(localizer).__name__}", field="--mcap"
            )
        self.channels = channels
        self.localizer = localizer
        self._updates = 0
        self._people = False
        channels.write_map(localizer.mcl.grid, runtime.source.time)  # the map MCL localizes on

    def on_records(self, records: Sequence[Record]) -> None:
        """The sensor stream of one step: scans (with their odometry), odometry, images."""
        ch = self.channels
        for r in records:
            if isinstance(r, Scan) and r.odom is not None:
                ch.write_scan(r)
                ch.write_odometry(r.odom, r.timestamp)
            elif isinstance(r, Image) and f"/{r.camera}/image" in TOPICS and r.pixels.ndim == 2:
                ch.write_image(r)
            elif isinstance(r, Odometry):
                pass  # the odometry is published with each scan, at the scan's pose

    def on_snapshot(self, snapshot: StateSnapshot) -> None:
        """The estimate when MCL made a new one; the tracked people when there are (or were) any."""
        localizer = self.localizer
        last = localizer.last_update
        est = localizer.mcl.last_estimate
        if localizer.updates != self._updates and last is not None and est is not None:
            self._updates = localizer.updates
            stamp, odom = last
            self.channels.write_estimate(est.pose, est.covariance, odom, stamp)
            self.channels.write_particles(localizer.mcl.samples, stamp)
        if snapshot.people or self._people:
            self.channels.write_people(snapshot.people, snapshot.time)
            self._people = bool(snapshot.people)

    def close(self) -> None:
        """Nothing: the channels are closed by their owner."""


class McapRecorder:
    """Records ``runtime``'s run to ``path`` as MCAP: a context manager giving the sink to add.

    The file is written whole on a normal exit, and nothing is left when the run fails.
    """

    def __init__(self, path: Path, runtime: Runtime) -> None:
        self.path = path
        self.runtime = runtime
        self.run: McapRun | None = None

    def __enter__(self) -> RunPublisher:
        self.run = McapRun(self.path).__enter__()
        try:
            return RunPublisher(self.run, self.runtime)
        except BaseException as exc:
            self.run.__exit__(type(exc), exc, exc.__traceback__)
            self.run = None
            raise

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self.run is not None:
            self.run.__exit__(kind, value, tb)
            self.run = None
