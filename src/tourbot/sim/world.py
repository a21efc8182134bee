"""The world the robots of one museum share: its one crowd, stepped apart from every robot.

A :class:`MuseumWorld` owns the museum's crowd (:class:`tourbot.sim.crowd.Crowd`, the one crowd
model) and steps it with every robot's true pose and velocity read from the fleet's shared memory
(:class:`tourbot.sim.fleet.FleetPoses`), then writes the visitors back there for the robots'
simulators (their lasers, their bases, their debug truth). The visitors gather at, follow and
step aside for each robot as for one (the crowd's robot inputs are the list of robots).

Under ``tourbot serve`` the world runs in a process of its own (:mod:`tourbot.web.world_process`),
so that a robot's process that dies and is restarted takes nothing of the crowd with it: the
visitors walk on, around the dead robot's body where it stopped (its last written pose; a robot
that no longer steps is taken to stand), and the restarted robot writes its pose again. The world's
own process, restarted, carries the crowd on from the shared memory (where each visitor is and how
it moves; their plans are drawn afresh).

Truth, as the rest of the simulator: the robots' estimators never read it.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from tourbot.errors import TourbotError
from tourbot.sim.crowd import Crowd, CrowdConfig
from tourbot.sim.fleet import FleetPoses
from tourbot.site.model import Site

__all__ = ["MuseumWorld", "site_crowd"]

#: A robot whose pose has not been written for this long (world seconds) is taken to stand.
STALE_AFTER = 0.5


def site_crowd(site: Site, config: CrowdConfig) -> CrowdConfig:
    """The crowd of ``site``: its exhibits are where visitors go, unless ``config`` names places."""
    if not config.points_of_interest and site.exhibits:
        return replace(config, points_of_interest=tuple(e.position for e in site.exhibits))
    return config


class MuseumWorld:
    """The crowd of ``site`` for the robots of ``fleet`` (all of them: the world waits, up to
    ``wait`` seconds, until each has written its pose, then spawns the visitors clear of them).

    :meth:`step` advances the crowd by ``dt`` seconds with the robots where they are now. A world
    built on a fleet that already holds a crowd of as many visitors (the world's process died and
    was started again) carries it on: ``resumed``, the visitors where and as they were, at the
    crowd's time, with fresh plans.
    """

    def __init__(
        self,
        site: Site,
        config: CrowdConfig,
        fleet: FleetPoses,
        *,
        seed: int = 0,
        dt: float = 0.1,
        wait: float = 600.0,
    ) -> None:
        self.fleet = fleet
        self.dt = dt
        deadline = time.monotonic() + wait
        while not fleet.present().all():
            if time.monotonic() > deadline:
                missing = np.flatnonzero(~fleet.present()).tolist()
                raise TourbotError(f"the museum's world: robots {missing} wrote no pose within {wait:.0f} s")
            time.sleep(0.05)
        poses, _, self._writes = fleet.poses()
        self._rng = np.random.default_rng(seed)
        self.crowd = Crowd(site_crowd(site, config), site.grid, self._rng, robot_pose=poses)
        # a world started again (its process died): the visitors go on from where the last one left them
        before = fleet.read_crowd()
        self.resumed = before is not None and len(before.positions) == self.crowd.num_people
        if before is not None and self.resumed:
            self.crowd.place(before.positions, before.velocities, time=before.time)
        self._since = np.zeros(len(poses))  # world seconds since each robot's last write
        self._publish()

    @property
    def time(self) -> float:
        return float(self.crowd.time)

    def step(self) -> None:
        """One step of the crowd with every robot's latest pose; the visitors written to the fleet."""
        poses, velocities, writes = self.fleet.poses()
        fresh = writes != self._writes
        self._since = np.where(fresh, 0.0, self._since + self.dt)
        self._writes = writes
        still: NDArray[np.bool_] = self._since > STALE_AFTER
        velocities[still] = 0.0  # a robot that no longer steps (its process died) stands
        self.crowd.step(self.dt, poses, self._rng, velocities=velocities)
        self._publish()

    def _publish(self) -> None:
        crowd = self.crowd
        self.fleet.write_crowd(crowd.time, crowd.positions, crowd.velocities, *crowd.circles())
