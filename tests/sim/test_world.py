"""The museum's world: the one crowd of several robots, stepped from the fleet's shared poses."""

from __future__ import annotations

import numpy as np
import pytest

from tourbot.errors import TourbotError
from tourbot.sim.crowd import CrowdConfig, CrowdError
from tourbot.sim.fleet import FleetPoses
from tourbot.sim.world import MuseumWorld
from tourbot.site.default import default_site


def test_the_world_waits_for_every_robot() -> None:
    fleet = FleetPoses(2)
    try:
        fleet.write(0, (1.0, 2.0, 0.0))
        with pytest.raises(TourbotError, match=r"robots \[1\] wrote no pose"):
            MuseumWorld(default_site(), CrowdConfig(num_people=5), fleet, wait=0.2)
    finally:
        fleet.close()


def test_a_world_started_again_carries_the_crowd_on() -> None:
    """A second world on the same fleet (the first one's process died) takes the visitors where and
    as they were, at the crowd's time, and they walk on from there without a jump."""
    site = default_site()
    config = CrowdConfig(num_people=60, robot_interest=0.5)
    fleet = FleetPoses(2)
    try:
        for k in range(2):
            fleet.write(k, site.exhibits[k].viewing_pose)
        first = MuseumWorld(site, config, fleet, seed=0)
        assert not first.resumed
        for _ in range(100):
            first.step()
        where, when = first.crowd.positions, first.time
        second = MuseumWorld(site, config, fleet, seed=1)
        assert second.resumed
        assert second.time == pytest.approx(when)
        np.testing.assert_allclose(second.crowd.positions, where, atol=1e-9)
        np.testing.assert_allclose(second.crowd.velocities, first.crowd.velocities, atol=1e-9)
        last = where
        for _ in range(50):
            second.step()
            now = second.crowd.positions
            assert np.linalg.norm(now - last, axis=1).max() <= config.speed_max * 0.1 + 0.1
            last = now
        shared = fleet.read_crowd()
        assert shared is not None
        assert shared.time == pytest.approx(when + 5.0)
        # another number of visitors is another crowd: drawn afresh
        assert not MuseumWorld(site, CrowdConfig(num_people=30), fleet).resumed
    finally:
        fleet.close()
    with pytest.raises(CrowdError, match="a crowd of 60 placed at 2 positions"):
        second.crowd.place(np.zeros((2, 2)), np.zeros((2, 2)))
