"""A simulated run recorded as MCAP while it runs: a runtime sink over :class:`tourbot.io.mcap_out.McapRun`.

``tourbot simulate --mcap`` and ``tourbot demo --record --mcap`` both record through it: after each
runtime step, the scans the simulator produced (each with the odometry pose it was taken at) and
any new estimate of the robot's MCL, with its samples. The map is written once, first.
"""

from __future__ import annotations

from pathlib import Path
from types import TracebackType

from tourbot.app.simulated import SimulatedRobot
from tourbot.errors import InputError, TourbotError
from tourbot.io.mcap_out import McapRun
from tourbot.records import Scan
from tourbot.runtime.localizers import MCLLocalizer
from tourbot.snapshot import StateSnapshot

__all__ = ["McapRecorder"]


class McapRecorder:
    """Records ``robot``'s run to ``path`` (a :class:`~tourbot.interfaces.Sink` of its runtime).

    An estimate is written at the time of the scan it integrated, with that scan's odometry pose
    (for the map -> odom transform) and the localizer's samples. The beams are not written: the
    runtime localizer integrates a decimated scan and does not hand out which beams it used.
    Use it as a context manager: the file is written whole on a normal exit, and nothing is left
    when the run fails.
    """

    def __init__(self, path: Path, robot: SimulatedRobot) -> None:
        localizer = robot.runtime.localizer
        if not isinstance(localizer, MCLLocalizer):
            raise InputError(
                f"needs the robot's MCL localizer, the robot runs {type(localizer).__name__}", field="--mcap"
            )
        if not robot.simulator.config.record:
            raise TourbotError(
                "an MCAP recording needs the simulator's sensor stream (SimConfig(record=True))"
            )
        self.path = path
        self.robot = robot
        self.localizer = localizer
        self.run: McapRun | None = None
        self._seen = 0
        self._updates = 0

    def __enter__(self) -> McapRecorder:
        self.run = McapRun(self.path).__enter__()
        self.run.write_map(self.localizer.mcl.grid, self.robot.simulator.time)
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self.run is not None:
            self.run.__exit__(kind, value, tb)
            self.run = None

    def on_snapshot(self, snapshot: StateSnapshot) -> None:  # noqa: ARG002 (the records are the simulator's)
        """The scans and the estimate that are new since the last step."""
        run, localizer = self.run, self.localizer
        if run is None:
            return
        records = self.robot.simulator.records
        for r in records[self._seen :]:
            if isinstance(r, Scan) and r.odom is not None:
                run.write_scan(r)
                run.write_odometry(r.odom, r.timestamp)
        self._seen = len(records)
        last = localizer.last_update
        est = localizer.mcl.last_estimate
        if localizer.updates != self._updates and last is not None and est is not None:
            self._updates = localizer.updates
            stamp, odom = last
            run.write_estimate(est.pose, est.covariance, odom, stamp)
            run.write_particles(localizer.mcl.samples, stamp)

    def close(self) -> None:
        """Nothing: the file is finished when the ``with`` block ends."""
