"""The people tracker as a runtime estimator: scans and the robot's pose belief in, tracks out.

It satisfies :class:`tourbot.interfaces.Estimator`: the runtime hands it every scan with
the localizer's belief, and reads its tracks (confirmed ones, in the world frame) into the state
snapshot, from where the web view draws them as avatars and the navigator avoids them.
"""

from __future__ import annotations

import numpy as np

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

    def on_odometry(self, odom: Odometry) -> None:
        """Odometry is not used: the pose comes with each scan's belief."""
        del odom

    def on_scan(self, scan: Scan, belief: PoseBelief) -> None:
        self._tracks = self.tracker.update(scan, np.asarray(belief.estimate.pose, dtype=np.float64))

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
