"""The people tracker as a runtime estimator: scans and the robot's pose belief in, tracks out.

It satisfies :class:`tourbot.interfaces.Estimator`: the runtime hands it every scan with
the localizer's belief, and reads its tracks (confirmed ones, in the world frame) into the state
snapshot, from where the web view draws them as avatars and the navigator avoids them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tourbot.interfaces import EstimatorOutput, PoseBelief, ScanShare
from tourbot.maps.grid import OccupancyGrid
from tourbot.people.sjpdaf import PeopleTracker, SJPDAFConfig, Track
from tourbot.records import Odometry, Scan
from tourbot.snapshot import PersonState

__all__ = ["PeopleEstimator"]


class PeopleEstimator:
    """:class:`PeopleTracker` behind the runtime's ``Estimator`` protocol.

    The robot's pose is the belief's estimate (Burgard et al. Sec. 4: the tracker runs on the
    moving robot, its tracks in the map frame through the robot's position estimate).
    """

    name = "people"
    scan_share = ScanShare.ALL

    def __init__(
        self,
        config: SJPDAFConfig | None = None,
        *,
        grid_map: OccupancyGrid | None = None,
        rng: np.random.Generator | None = None,
        include_tentative: bool = False,
    ) -> None:
        self.tracker = PeopleTracker(config, grid_map=grid_map, rng=rng)
        self.include_tentative = include_tentative
        self._tracks: list[Track] = []
        self._time: float | None = None

    def on_odometry(self, odom: Odometry) -> None:
        """Odometry is not used: the pose comes with each scan's belief."""
        del odom

    def on_scan(self, scan: Scan, belief: PoseBelief) -> None:
        self._tracks = self.tracker.update(scan, np.asarray(belief.estimate.pose, dtype=np.float64))
        self._time = float(scan.timestamp)

    def positions(self, time: float | None = None) -> NDArray[np.float64]:
        """The confirmed visitors' positions ``(N, 2)`` (world), moved on with their estimated
        velocities from the last scan to ``time`` (the constant-velocity model of the tracker's
        prediction, Burgard et al. Sec. 4); as of the last scan when ``time`` is None."""
        tracks = [t for t in self._tracks if t.confirmed]
        if not tracks:
            return np.zeros((0, 2))
        pos = np.array([t.position for t in tracks], dtype=np.float64)
        if time is not None and self._time is not None:
            vel = np.array([t.velocity for t in tracks], dtype=np.float64)
            pos += vel * max(0.0, float(time) - self._time)
        return pos

    def state(self) -> EstimatorOutput:
        people = tuple(
            PersonState(
                id=t.id,
                x=t.position[0],
                y=t.position[1],
                vx=t.velocity[0],
                vy=t.velocity[1],
                confirmed=t.confirmed,
            )
            for t in self._tracks
            if t.confirmed or self.include_tentative
        )
        return EstimatorOutput(people=people)
